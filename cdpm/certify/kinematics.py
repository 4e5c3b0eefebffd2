"""Enclosures of a robot's kinematics and mass matrix over boxes of poses.

A box ``Q = [lower, upper]`` of natural coordinates (nv,) holds every pose
q with ``lower <= q <= upper``. :func:`box_kinematics` returns intervals
(:class:`cdpm.certify.interval.Interval`) that hold, for every q in Q, the
values :class:`cdpm.model.robot.CableRobot` computes at q: joint placements,
cable route points and their Jacobians, cable lengths and the cable
Jacobian L(q), the outputs and their Jacobian C_q, and the mass matrix
M(q), round-off included. These are what the zero-load POC test
(``G(q) = C_q M(q)^-1 (-L(q)^T)``, docs/analysis.md) needs.

Two forms:

- ``"naive"``: interval evaluation of the forward kinematics, joint by
  joint from the base (sin and cos of each coordinate's interval, products
  of interval rotation matrices);
- ``"mean_value"``: ``f(Q) in f(q_c) + sum_k df/dq_k(Q) [-h_k, h_k]``, with
  f(q_c) the naive evaluation at the box's centre q_c (a point box: round-off
  wide) and the derivatives' enclosures over Q by the same chain rule in
  intervals (:class:`_Jet`), intersected with the naive enclosure. Tighter
  on small boxes, where the naive form's overestimation (the same
  coordinate entering many factors) dominates.

Frames and units: every vector is in the world frame; lengths in m,
angles in rad; Jacobians map the tangent velocity (nv,) [rad/s or m/s] to
the rate of the quantity, as cdpm's (a revolute or prismatic joint's
natural coordinate is its configuration entry and its tangent coordinate).

Supported joints: revolute (Pinocchio's RX, RY, RZ and RevoluteUnaligned),
prismatic (PX, PY, PZ, PrismaticUnaligned) and free-flyer (natural
coordinates x, y, z, roll, pitch, yaw with ``R = Rz(yaw) Ry(pitch)
Rx(roll)``; its six degrees of freedom move along and about the body's own
axes, Pinocchio's local velocities, so L, C_q and M are Pinocchio's); fixed
joints are frames merged into their parent link. Other joints (spherical,
planar, continuous, ...) raise :class:`cdpm.errors.InputError`.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np

from cdpm.certify.interval import Interval
from cdpm.certify.jet import Jet, jet_cos, jet_sin, jet_stack, jet_where, mean_value, variables
from cdpm.errors import InputError, float_array
from cdpm.model.coordinates import MAX_COORDINATE
from cdpm.model.outputs import anchor_in_joint, joint_support

__all__ = ["BoxKinematics", "box_kinematics", "box_jets", "check_boxes", "FORMS"]

#: the evaluation forms of :func:`box_kinematics`
FORMS = ("naive", "mean_value")

_REVOLUTE = {
    "JointModelRX": 0,
    "JointModelRY": 1,
    "JointModelRZ": 2,
    "JointModelRevoluteUnaligned": -1,
}
_PRISMATIC = {
    "JointModelPX": 0,
    "JointModelPY": 1,
    "JointModelPZ": 2,
    "JointModelPrismaticUnaligned": -1,
}


@dataclass(frozen=True)
class BoxKinematics:
    """Enclosures over a box of poses (or B boxes: a leading axis B on every
    array when ``lower`` was (B, nv)).

    Attributes:
        lower, upper: the box, natural coordinates [rad or m], (nv,) or (B, nv).
        form: ``"naive"`` or ``"mean_value"``.
        joint_rotation: world rotation of each joint frame, (..., njoints, 3, 3)
            (joint 0 is the world).
        joint_translation: world position of each joint frame [m], (..., njoints, 3).
        point_positions: the cable route points, cable by cable in route
            order (``CableRobot.route_point_slices``) [m], (..., n_route, 3).
        point_jacobians: their translational Jacobians, (..., n_route, 3, nv).
        segment_lengths: straight segment lengths [m], (..., n_segments).
        lengths: cable lengths l [m], (..., m).
        jacobian: cable Jacobian L = dl/dq, (..., m, nv) (seed paper eq 16).
        output: outputs y in their units, (..., p). A rotation component is
            only known to lie in [-pi, pi].
        output_jacobian: C_q = dy/dv, (..., p, nv).
        mass_matrix: M(q) [kg, kg m, kg m^2], (..., nv, nv) (seed paper eq 14).
        gravity: the generalised gravity G(q) [N or N m], (..., nv) (seed
            paper eq 11; Pinocchio's ``computeGeneralizedGravity``):
            ``G = -sum_bodies m J_com^T g`` with J_com the Jacobian of the
            body's centre of mass and g the model's gravity [m/s^2].
        segment_may_vanish: per box, whether some segment's length may be 0
            in it, (...,) bool. Its unit vector is then only bounded by
            [-1, 1] per component, and L's enclosure holds where L exists.
    """

    lower: np.ndarray
    upper: np.ndarray
    form: str
    joint_rotation: Interval
    joint_translation: Interval
    point_positions: Interval
    point_jacobians: Interval
    segment_lengths: Interval
    lengths: Interval
    jacobian: Interval
    output: Interval
    output_jacobian: Interval
    mass_matrix: Interval
    segment_may_vanish: np.ndarray
    gravity: Interval

    def __str__(self) -> str:
        boxes = 1 if self.lower.ndim == 1 else self.lower.shape[0]

        def widest(x: Interval) -> str:
            return f"{np.max(x.width, initial=0.0):.3g}"

        return (
            f"BoxKinematics ({self.form}, {boxes} box{'es' if boxes != 1 else ''}): widest "
            f"enclosure of L {widest(self.jacobian)}, C_q {widest(self.output_jacobian)}, "
            f"M {widest(self.mass_matrix)}"
        )


def box_kinematics(robot: Any, lower: Any, upper: Any, form: str = "naive") -> BoxKinematics:
    """Enclosures of the kinematics and the mass matrix over a box of poses.

    Args:
        robot: a :class:`cdpm.model.robot.CableRobot` with revolute and
            prismatic joints only.
        lower, upper: the box's corners in natural coordinates [rad or m],
            shape (nv,), or (B, nv) for B boxes at once (one vectorised pass).
        form: ``"naive"`` or ``"mean_value"`` (see the module docstring).

    Returns:
        :class:`BoxKinematics`; each of its intervals holds the robot's value
        at every pose of the box.

    Raises:
        InputError: a joint type other than revolute or prismatic; corners
            of the wrong shape, not finite, or lower > upper; an unknown form.
    """
    if form not in FORMS:
        raise InputError(f"form must be one of {', '.join(FORMS)}; got {form!r}")
    chain = _chain(robot)
    lo, hi, single = check_boxes(robot, lower, upper)
    if form == "naive":
        values = chain.evaluate(Interval(lo, hi))
    else:
        values = chain.mean_value(lo, hi)
    if single:
        values = {k: v[0] for k, v in values.items()}
        lo, hi = lo[0], hi[0]
    return BoxKinematics(lower=lo, upper=hi, form=form, **values)


def box_jets(robot: Any, lower: Any, upper: Any) -> tuple[dict, dict, np.ndarray]:
    """What a mean-value form of a quantity built from the kinematics needs:
    the enclosures at the boxes' centres (point boxes: round-off wide), the
    jets over the boxes (value and derivative enclosures) and the boxes'
    half-widths.

    Args:
        robot, lower, upper: as :func:`box_kinematics` (boxes (B, nv) or one (nv,)).

    Returns:
        (at_centre, over_box, radius): two dicts keyed like
        :class:`BoxKinematics`'s fields (Intervals at the centre; Jets, or
        Intervals for what is constant, over the box), each with a leading
        axis B, and the half-widths (B, nv) [rad or m].
    """
    chain = _chain(robot)
    lo, hi, _ = check_boxes(robot, lower, upper)
    centre = np.clip(0.5 * lo + 0.5 * hi, lo, hi)
    radius = np.maximum(np.nextafter(centre - lo, np.inf), np.nextafter(hi - centre, np.inf))
    return (
        chain.evaluate(Interval(centre), "root"),
        chain.evaluate(variables(lo, hi), "root"),
        radius,
    )


def check_boxes(robot: Any, lower: Any, upper: Any) -> tuple[np.ndarray, np.ndarray, bool]:
    """Box corners, (nv,) or (B, nv), checked (numbers, one per coordinate,
    finite, lower <= upper) as (B, nv) float arrays, and whether one box was
    given."""
    nv = robot.nv
    names = ", ".join(robot.coordinate_names)
    arrays = []
    for name, value in (("lower", lower), ("upper", upper)):
        try:
            arr = float_array(value, copy=True)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"{name} must be numbers, one per coordinate ({names}): {exc}"
            ) from exc
        if arr.ndim not in (1, 2) or arr.shape[-1] != nv:
            raise InputError(
                f"{name} has shape {arr.shape}, expected ({nv},) or (B, {nv}): one value per "
                f"coordinate ({names})"
            )
        if not np.all(np.abs(arr) <= MAX_COORDINATE):
            raise InputError(
                f"{name} holds values that are not finite numbers of at most "
                f"{MAX_COORDINATE:g} (rad or m)"
            )
        arrays.append(arr)
    lo, hi = arrays
    if lo.shape != hi.shape:
        raise InputError(f"lower has shape {lo.shape} and upper {hi.shape}; give them alike")
    if np.any(lo > hi):
        k = np.argwhere(lo > hi)[0]
        raise InputError(
            f"lower > upper for coordinate {robot.coordinate_names[k[-1]]!r} "
            f"({lo[tuple(k)]:g} > {hi[tuple(k)]:g}); swap them"
        )
    single = lo.ndim == 1
    return lo.reshape(-1, nv), hi.reshape(-1, nv), single


# one chain per robot, built on first use
_CHAINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _chain(robot: Any) -> _Chain:
    chain = _CHAINS.get(robot)
    if chain is None:
        chain = _Chain(robot)
        _CHAINS[robot] = chain
    return chain


def _axis_matrices(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rodrigues' rotation by q about the unit ``axis``:
    ``R(q) = a a^T + cos q (I - a a^T) + sin q [a]_x``; returns the three
    constant matrices (for an axis along x, y or z each entry has one
    nonzero term, so no coordinate enters an entry twice)."""
    a = np.asarray(axis, dtype=float)
    outer = np.outer(a, a)
    skew = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return outer, np.eye(3) - outer, skew


class _Chain:
    """The robot's kinematic tree as constants: joints (parent, placement,
    kind, axis), tracked points (joint, position in the joint frame),
    segments, output terms and bodies."""

    def __init__(self, robot: Any) -> None:
        model = robot.model
        spec = robot.spec
        self.nv, self.nj = int(model.nv), int(model.njoints)
        self.parent = [int(model.parents[j]) for j in range(self.nj)]
        self.placement_rotation = [
            np.array(model.jointPlacements[j].rotation) for j in range(self.nj)
        ]
        self.placement_translation = [
            np.array(model.jointPlacements[j].translation) for j in range(self.nj)
        ]
        self.revolute = np.zeros(self.nv, dtype=bool)
        self.dof_joint = np.zeros(self.nv, dtype=int)
        self.joint_dof = [-1] * self.nj
        self.axis = [np.zeros(3)] * self.nj
        self.free_flyer = [False] * self.nj
        for j in range(1, self.nj):
            joint = model.joints[j]
            short = joint.shortname()
            if short == "JointModelFreeFlyer":
                # x, y, z along the body's own axes, then rotations about them
                k = joint.idx_v
                self.free_flyer[j] = True
                self.revolute[k + 3 : k + 6] = True
                self.dof_joint[k : k + 6] = j
                self.joint_dof[j] = k
                continue
            code = _REVOLUTE.get(short, _PRISMATIC.get(short))
            if code is None:
                raise InputError(
                    f"joint {model.names[j]!r} ({short.removeprefix('JointModel')}) is not "
                    "supported by certified boxes yet: they handle revolute joints (about any "
                    "axis), prismatic joints, free-flyer joints and fixed joints; continuous "
                    "(unbounded), spherical and planar joints are not"
                )
            axis = np.eye(3)[code] if code >= 0 else np.array(joint.extract().axis, dtype=float)
            self.axis[j] = axis / np.linalg.norm(axis)
            self.revolute[joint.idx_v] = short in _REVOLUTE
            self.dof_joint[joint.idx_v] = j
            self.joint_dof[j] = joint.idx_v
        self.support = joint_support(model)  # (nj, nv)

        # tracked points: route points, then the points of position outputs,
        # then the bodies' centres of mass
        joints: list[int] = []
        local: list[np.ndarray] = []
        seg_a: list[int] = []
        self.segment_cable: list[int] = []
        for ci, cable in enumerate(spec.cables):
            start = len(joints)
            for point in cable.route:
                joint, p_joint = anchor_in_joint(model, point.frame, np.array(point.point_in_frame))
                joints.append(joint)
                local.append(p_joint)
            for k in range(len(cable.route) - 1):
                seg_a.append(start + k)
                self.segment_cable.append(ci)
        self.n_route = len(joints)
        self.segments = np.array([[a, a + 1] for a in seg_a], dtype=int).reshape(-1, 2)
        n_cables = len(spec.cables)
        self.to_cable = np.zeros((n_cables, len(seg_a)))
        self.to_cable[self.segment_cable, np.arange(len(seg_a))] = 1.0
        self.cable_names = [c.name for c in spec.cables]

        cable_index = {name: k for k, name in enumerate(self.cable_names)}
        self.outputs: list[list[tuple[float, str, Any]]] = []
        for out in spec.outputs:
            terms = []
            for term in out.terms:
                if term.kind == "position":
                    joint, p_joint = anchor_in_joint(
                        model, term.frame, np.array(term.point_in_frame)
                    )
                    terms.append((term.weight, "position", (term.axis, len(joints))))
                    joints.append(joint)
                    local.append(p_joint)
                elif term.kind == "rotation":
                    joint = anchor_in_joint(model, term.frame, np.zeros(3))[0]
                    terms.append((term.weight, "rotation", (term.axis, joint)))
                elif term.kind == "joint":
                    terms.append(
                        (term.weight, "joint", model.joints[model.getJointId(term.joint)].idx_v)
                    )
                else:
                    terms.append((term.weight, "cable", cable_index[term.cable]))
            self.outputs.append(terms)

        self.first_com = len(joints)
        self.body_mass = np.array([float(model.inertias[j].mass) for j in range(1, self.nj)])
        self.body_inertia = np.array(
            [np.array(model.inertias[j].inertia) for j in range(1, self.nj)]
        )
        for j in range(1, self.nj):
            joints.append(j)
            local.append(np.array(model.inertias[j].lever, dtype=float))
        self.point_joint = np.array(joints, dtype=int)
        self.point_local = np.array(local, dtype=float).reshape(-1, 3)
        self.armature = np.array(model.armature, dtype=float).reshape(-1)
        # m_b g per body [N], (nb, 3): G = -sum_b J_com_b^T (m_b g)
        self.body_weight = self.body_mass[:, None] * np.array(model.gravity.linear, dtype=float)
        # a joint that carries every body (the first of a chain from the
        # world): M does not depend on its coordinate
        self.root_dof = -1
        for j in range(1, self.nj):
            k = self.joint_dof[j]
            if (
                k >= 0
                and not self.free_flyer[j]
                and self.parent[j] == 0
                and bool(np.all(self.support[1:, k]))
            ):
                self.root_dof = int(k)
                self.root_revolute = bool(self.revolute[k])
                self.root_axis = self.placement_rotation[j] @ self.axis[j]  # world frame
                self.root_origin = self.placement_translation[j]
                break

    # ----------------------------------------------------------- evaluation

    def evaluate(self, q: Interval | Jet, frame: str = "world") -> dict[str, Any]:
        """Interval evaluation over boxes q (B, nv): naive for an Interval,
        with the derivatives' enclosures for a Jet.

        ``frame="root"``, for a robot whose bodies all ride on one joint at
        the world (its *root*), evaluates the chain with the root's
        coordinate pinned at 0 and moves the world-fixed points (and the
        output and gravity directions) by the root's inverse motion instead:
        the relative geometry is the same, so the frame-independent
        quantities (cable lengths, L, M, G, and the outputs and C_q, mapped
        back) are the same, but the root's coordinate enters once instead of
        along the whole chain, which keeps the enclosures far tighter. Its
        dict holds only those quantities."""
        if frame == "world" or self.root_dof < 0:
            return self._assemble(q, *self._placements(q))
        k = self.root_dof
        motion = _root_motion(q, k, self.root_axis, self.root_origin, self.root_revolute)
        out = self._assemble(q, *self._placements(_pin(q, k)), world=motion)
        for name in ("joint_rotation", "joint_translation", "point_positions", "point_jacobians"):
            out.pop(name)
        return out

    def _placements(self, q: Interval | Jet) -> tuple[Any, Any, Any]:
        """World rotation (B, nj, 3, 3) and origin (B, nj, 3) of every joint
        frame, and the world axis of every degree of freedom (B, nv, 3), over
        boxes q (B, nv) of natural coordinates (a free-flyer's: x, y, z,
        then roll, pitch, yaw; its degrees of freedom move along and about
        its body's own axes, as Pinocchio's local velocities)."""
        n_boxes = q.shape[0]
        s, c = jet_sin(q), jet_cos(q)
        rot: list[Any] = [Interval(np.broadcast_to(np.eye(3), (n_boxes, 3, 3)))]
        pos: list[Any] = [Interval(np.zeros((n_boxes, 3)))]
        dof_axes: list[Any] = [None] * self.nv
        for j in range(1, self.nj):
            par, k = self.parent[j], self.joint_dof[j]
            r_pre = rot[par] @ self.placement_rotation[j]
            origin = pos[par] + rot[par] @ self.placement_translation[j]
            if self.free_flyer[j]:
                turn = None  # R = Rz(yaw) Ry(pitch) Rx(roll)
                for i in (2, 1, 0):
                    outer, perp, skew = _axis_matrices(np.eye(3)[i])
                    ki = k + 3 + i
                    r_i = (c[:, ki, None, None] * perp + s[:, ki, None, None] * skew) + outer
                    turn = r_i if turn is None else turn @ r_i
                body = r_pre @ turn
                rot.append(body)
                pos.append(origin + (r_pre * q[:, None, k : k + 3]).sum(axis=-1))
                for i in range(6):
                    dof_axes[k + i] = body[:, :, i % 3]
                continue
            a = r_pre @ self.axis[j]
            if self.revolute[k]:
                outer, perp, skew = _axis_matrices(self.axis[j])
                r_joint = (c[:, k, None, None] * perp + s[:, k, None, None] * skew) + outer
                rot.append(r_pre @ r_joint)
                pos.append(origin)
            else:
                rot.append(r_pre)
                pos.append(origin + a * q[:, k, None])
            dof_axes[k] = a
        rot_all = jet_stack(rot, axis=1)  # (B, nj, 3, 3)
        pos_all = jet_stack(pos, axis=1)  # (B, nj, 3)
        axis_all = jet_stack(dof_axes, axis=1)  # (B, nv, 3)
        return rot_all, pos_all, axis_all

    def _points(
        self, rot: Any, pos: Any, axis: Any, which: slice, world: Any = None
    ) -> tuple[Any, Any]:
        """Positions (B, P, 3) and Jacobians (B, P, 3, nv) of the tracked
        points ``which``; ``world`` (rotation (B, 3, 3), translation (B, 3))
        replaces the world frame's placement for the points fixed to it."""
        pj = self.point_joint[which]
        if world is not None:
            rot = jet_where((np.arange(self.nj) == 0)[None, :, None, None], world[0][:, None], rot)
            pos = jet_where((np.arange(self.nj) == 0)[None, :, None], world[1][:, None], pos)
        points = pos[:, pj] + (rot[:, pj] * self.point_local[which][None, :, None, :]).sum(axis=-1)
        dof_axis = axis  # (B, nv, 3)
        dof_origin = pos[:, self.dof_joint]
        arm = points[:, :, None, :] - dof_origin[:, None, :, :]  # (B, P, nv, 3)
        linear = _cross(dof_axis[:, None], arm)
        linear = jet_where(self.revolute[None, :, None], linear, dof_axis[:, None])
        mask = self.support[pj][:, :, None]  # (P, nv, 1)
        return points, jet_where(mask, linear, 0.0).swapaxes(-1, -2)

    def _assemble(self, q: Any, rot: Any, pos: Any, axis: Any, world: Any = None) -> dict[str, Any]:
        """Points, Jacobians, L, outputs and M from the joint placements;
        ``world``: the root frame's view (see :meth:`evaluate`), as
        (rotation, translation, world directions (B, 3, 3), world offset
        (B, 3)) from :func:`_root_motion`."""
        points, point_jac = self._points(rot, pos, axis, slice(None), world)
        dof_axis = axis  # (B, nv, 3)

        a, b = self.segments[:, 0], self.segments[:, 1]
        diff = points[:, b] - points[:, a]  # (B, S, 3)
        squared = diff.square().sum(axis=-1)  # (B, S)
        may_vanish = _value(squared).lo <= 0
        # segments that may vanish get a stand-in length of 1 for their
        # direction, which is then only known to lie in [-1, 1]^3
        safe, units = _length_and_direction(diff, jet_where(may_vanish, 1.0, squared))
        seg_len = jet_where(may_vanish, _value(squared).sqrt(), safe)
        units = jet_where(may_vanish[..., None], Interval(-1.0, 1.0), units)
        seg_rows = (units[..., None] * (point_jac[:, b] - point_jac[:, a])).sum(axis=-2)
        lengths = (self.to_cable[:, :, None] * seg_len[:, None, :, None]).sum(axis=-2)[..., 0]
        rows = (self.to_cable[:, :, None] * seg_rows[:, None, :, :]).sum(axis=-2)

        n_boxes = q.shape[0]
        values, rates = [], []
        for terms in self.outputs:
            value = Interval(np.zeros(n_boxes))
            rate = Interval(np.zeros((n_boxes, self.nv)))
            for weight, kind, where in terms:
                if kind == "position" and world is not None:
                    axis_k, point = where
                    e = world[2][:, axis_k]  # the world axis k in the root frame (B, 3)
                    v = (e * points[:, point]).sum(axis=-1) + world[3][:, axis_k]
                    r = (e[:, :, None] * point_jac[:, point]).sum(axis=-2)
                elif kind == "position":
                    axis_k, point = where
                    v, r = points[:, point, axis_k], point_jac[:, point, axis_k]
                elif kind == "rotation":
                    axis_k, joint = where
                    v = Interval(np.full(n_boxes, -math.pi), np.full(n_boxes, math.pi))
                    v = Interval._raw(np.nextafter(v.lo, -np.inf), np.nextafter(v.hi, np.inf))
                    if world is not None:
                        e = world[2][:, axis_k]
                        angular = (e[:, None, :] * dof_axis).sum(axis=-1)  # (B, nv)
                    else:
                        angular = dof_axis[:, :, axis_k]  # (B, nv)
                    r = jet_where(self.revolute & self.support[joint], angular, 0.0)
                elif kind == "joint":
                    v = q[:, where]
                    r = Interval(np.broadcast_to(np.eye(self.nv)[where], (n_boxes, self.nv)))
                else:
                    v, r = lengths[:, where], rows[:, where]
                value = value + v * weight
                rate = rate + r * weight
            values.append(value)
            rates.append(rate)
        output = jet_stack(values, axis=1) if values else Interval(np.zeros((n_boxes, 0)))
        output_jac = (
            jet_stack(rates, axis=1) if rates else Interval(np.zeros((n_boxes, 0, self.nv)))
        )

        com_jac = point_jac[:, self.first_com :]  # (B, nb, 3, nv)
        mass = self._mass_matrix(rot, dof_axis, com_jac)
        if world is None:
            weight = self.body_weight[:, :, None]  # (nb, 3, 1) world frame
        else:  # the weights in the root frame: sum_i (m g)_i (R^T e_i)
            weight = (self.body_weight[None, :, :, None] * world[2][:, None]).sum(axis=-2)
            weight = weight[..., None]  # (B, nb, 3, 1)
        gravity = -(com_jac * weight).sum(axis=-2).sum(axis=1)
        return {
            "joint_rotation": rot,
            "joint_translation": pos,
            "point_positions": points[:, : self.n_route],
            "point_jacobians": point_jac[:, : self.n_route],
            "segment_lengths": seg_len,
            "lengths": lengths,
            "jacobian": rows,
            "output": output,
            "output_jacobian": output_jac,
            "mass_matrix": mass,
            "gravity": gravity,
            "segment_may_vanish": may_vanish.any(axis=-1),
        }

    def _mass_matrix(self, rot: Any, dof_axis: Any, com_jac: Any) -> Any:
        """``M = sum_bodies m Jv^T Jv + (R^T Jw)^T I_c (R^T Jw)``: Jv the
        Jacobian of the body's centre of mass (B, nb, 3, nv), Jw its world
        angular Jacobian, R its joint's world rotation, I_c its inertia about
        the centre of mass in the joint frame; plus the joints' armature."""
        linear = (com_jac.mT @ com_jac * self.body_mass[:, None, None]).sum(axis=1)
        if not np.any(self.body_inertia):  # point masses: no rotational term
            return linear + np.diag(self.armature)
        body_support = self.support[1:] & self.revolute[None, :]  # (nb, nv)
        angular = jet_where(body_support[:, None, :], dof_axis.mT[:, None], 0.0)  # (B, nb, 3, nv)
        in_body = rot[:, 1:].mT @ angular  # (B, nb, 3, nv)
        rotational = (in_body.mT @ (self.body_inertia @ in_body)).sum(axis=1)
        return linear + rotational + np.diag(self.armature)

    # ------------------------------------------------------- mean-value form

    def mean_value(self, lo: np.ndarray, hi: np.ndarray) -> dict[str, Any]:
        """The mean-value form over boxes (B, nv): the naive enclosure at
        each box's centre plus the derivatives' enclosures over the box times
        its half-widths, cut to the naive enclosure over the box. Boxes
        where a segment may vanish keep the naive enclosures."""
        centre = np.clip(0.5 * lo + 0.5 * hi, lo, hi)
        radius = np.maximum(np.nextafter(centre - lo, np.inf), np.nextafter(hi - centre, np.inf))
        at_centre = self.evaluate(Interval(centre))
        over_box = self.evaluate(variables(lo, hi))
        naive = over_box["segment_may_vanish"]
        out: dict[str, Any] = {"segment_may_vanish": naive}
        for name, value in over_box.items():
            if name == "segment_may_vanish":
                continue
            if not isinstance(value, Jet):  # constant over the box
                out[name] = value
                continue
            mv = mean_value(at_centre[name], value, radius)
            keep = naive.reshape(naive.shape + (1,) * (len(mv.shape) - 1))
            out[name] = jet_where(keep, value.val, mv)
        return out


def _length_and_direction(diff: Any, squared: Any) -> tuple[Any, Any]:
    """Lengths l = |d| and unit vectors u = d / l of segment vectors d
    (..., 3), given their squared lengths (bounded away from 0).

    For jets the derivatives take the forms with the least repetition of d,
    ``dl = u . dd`` and ``du = (dd - u (u . dd)) / l`` (the part of dd
    across u, over l), whose interval evaluation overestimates far less
    than the chain rule through ``d / sqrt(d . d)``."""
    length = _value(squared).sqrt()
    inv = length.reciprocal()
    u_val = (_value(diff) * inv[..., None]).intersect(-1.0, 1.0)
    if not isinstance(diff, Jet):
        return length, u_val
    along = (u_val[..., None] * diff.grad).sum(axis=-2)  # u . dd  (..., n)
    across = (diff.grad - u_val[..., None] * along[..., None, :]) * inv[..., None, None]
    return Jet(length, along), Jet(u_val, across)


def _root_motion(q: Any, k: int, axis: np.ndarray, origin: np.ndarray, revolute: bool):
    """The root frame's view of the world over boxes q (B, nv), the root
    joint moving by q_k about (revolute) or along (prismatic) the world
    ``axis`` through ``origin``: the inverse motion's rotation Rt (B, 3, 3)
    and translation (B, 3) (a world-fixed point p is at ``Rt p + t`` in
    the root frame), and back: the world axes in the root frame (rows of
    Rt^T... here the columns of R^T: ``E[:, i]`` is world axis i) and the
    offset ``o - R o`` (world value = E[:, i] . p' + offset_i)."""
    qk = q[:, k]
    n_boxes = q.shape[0]
    if revolute:
        outer, perp, skew = _axis_matrices(axis)
        c, s = jet_cos(qk), jet_sin(qk)
        # R(q) = outer + c perp + s skew; its inverse R(-q) = outer + c perp - s skew
        inverse = (c[:, None, None] * perp - s[:, None, None] * skew) + outer
        forward = (c[:, None, None] * perp + s[:, None, None] * skew) + outer
        shift = origin - inverse @ origin  # Rt p + (o - Rt o)
        offset = origin - forward @ origin
        # world value e_i . (o + R (p' - o)) = (R^T e_i) . p' + e_i . (o - R o);
        # R^T = R(-q) = inverse: world axis i in the root frame is inverse[:, :, i]
        directions = inverse.mT  # row i: R^T e_i
        return inverse, shift, directions, offset
    eye = Interval(np.broadcast_to(np.eye(3), (n_boxes, 3, 3)))
    shift = qk[:, None] * (-axis)
    return eye, shift, eye, qk[:, None] * axis


def _pin(q: Any, k: int) -> Any:
    """Boxes q (B, nv) with coordinate k pinned at the point 0 (no
    derivative along any coordinate)."""
    val = q.val if isinstance(q, Jet) else q
    lo, hi = val.lo.copy(), val.hi.copy()
    lo[:, k] = hi[:, k] = 0.0
    pinned = Interval._raw(lo, hi)
    if not isinstance(q, Jet):
        return pinned
    glo, ghi = q.grad.lo.copy(), q.grad.hi.copy()
    glo[:, k] = ghi[:, k] = 0.0
    return Jet(pinned, Interval._raw(glo, ghi))


def _value(x: Any) -> Interval:
    """The enclosure of the values of a jet or an interval."""
    return x.val if isinstance(x, Jet) else x


def _cross(a: Any, b: Any) -> Any:
    """Cross product over the last axis (length 3) of intervals or jets."""
    return jet_stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )
