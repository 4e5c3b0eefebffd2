"""Robot: the Pinocchio model plus the cable layer.

:class:`CableRobot` evaluates, at a configuration q, everything the
linearisation needs: cable lengths l(q), the cable-joint Jacobian L(q)
(``l' = L q'``, seed paper eq 16), the mass matrix M(q), gravity G(q), and
the outputs y = h(q) with their Jacobian.

Conventions (THEORY.md section 1): a straight segment from attachment point
A to B has length ``|B - A|`` and unit vector ``u = (B - A)/|B - A|``; its row
of L is ``u^T (J_B - J_A)`` with ``J_X`` the (3, nv) world-aligned
translational Jacobian of the point X. A cable with several segments sums
its segments' rows. A tension f pulls B towards A; the generalised force of
all cables is ``-L^T f``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.configuration import (
    as_configuration,
    configuration_from_natural,
    configuration_from_values,
    coordinate_names,
    natural_from_configuration,
)
from cdpm.errors import ModelError
from cdpm.spec import OUTPUT_COMPONENTS, WORLD_FRAME_NAMES, CableSpec, load_spec

__all__ = ["CableRobot", "CableKinematics", "load_robot"]

#: A segment shorter than this [m] has no direction: its L row is undefined.
MIN_SEGMENT_LENGTH = 1e-9


@dataclass(frozen=True)
class CableKinematics:
    """Cable and output kinematics at one configuration (world frame).

    Attributes:
        q: configuration vector, shape (nq,).
        lengths: cable lengths l [m], shape (m,).
        jacobian: cable-joint Jacobian L, shape (m, nv); maps joint velocity
            [rad/s or m/s] to cable length rate [m/s].
        point_positions: world positions of the route points [m], shape (n_points, 3).
        point_jacobians: their translational Jacobians, shape (n_points, 3, nv).
        segment_lengths: length of each straight segment [m], shape (n_segments,).
        segment_units: unit vectors A -> B of each segment, shape (n_segments, 3).
        segment_points: indices (A, B) of each segment's end points, shape (n_segments, 2).
        segment_cable: index of the cable each segment belongs to, shape (n_segments,).
        output: outputs y, shape (p,).
        output_jacobian: dy/dv, shape (p, nv).
    """

    q: np.ndarray
    lengths: np.ndarray
    jacobian: np.ndarray
    point_positions: np.ndarray
    point_jacobians: np.ndarray
    segment_lengths: np.ndarray
    segment_units: np.ndarray
    segment_points: np.ndarray
    segment_cable: np.ndarray
    output: np.ndarray
    output_jacobian: np.ndarray


class CableRobot:
    """A cable-driven manipulator: Pinocchio model, cables and outputs.

    Build one with :func:`load_robot`. Every method that takes ``q`` accepts
    the model's configuration vector (nq,) or, when nq != nv, natural
    coordinates (nv,) (see :mod:`cdpm.configuration`).

    Attributes:
        spec: the validated :class:`~cdpm.spec.CableSpec`.
        model: the ``pinocchio.Model`` (gravity set from the spec).
        nq, nv: sizes of the configuration vector and of the tangent space.
        cable_names: names of the m cables, in spec order.
        output_names: names of the p outputs.
        coordinate_names: names of the nv natural coordinates.
        poses: named configuration vectors from the spec, each (nq,).
        tension_min, tension_max: tension bounds [N], each shape (m,).
    """

    def __init__(self, spec: CableSpec) -> None:
        import pinocchio as pin

        self.spec = spec
        self.model = spec.model
        self._data = self.model.createData()
        self._dyn_data = self.model.createData()
        self.nq = int(self.model.nq)
        self.nv = int(self.model.nv)
        self.cable_names = tuple(c.name for c in spec.cables)
        self.output_names = tuple(o.name for o in spec.outputs)
        self.coordinate_names = tuple(coordinate_names(self.model))
        self.poses = {k: v.copy() for k, v in spec.poses.items()}
        self.tension_min = np.array([c.tension_min for c in spec.cables])
        self.tension_max = np.array([c.tension_max for c in spec.cables])
        self.gravity = np.array(spec.gravity)
        self.external_wrench = (
            np.zeros(self.nv) if spec.external_wrench is None else np.array(spec.external_wrench)
        )

        # Every tracked point (route points, then output frame origins) is
        # stored in its parent joint's frame so one forward pass places all.
        joints: list[int] = []
        local: list[np.ndarray] = []
        seg_a: list[int] = []
        seg_cable: list[int] = []
        self.route_point_slices: list[slice] = []
        for ci, cable in enumerate(spec.cables):
            start = len(joints)
            for point in cable.route:
                joint, p_joint = self._anchor(point.frame, np.array(point.point_in_frame))
                joints.append(joint)
                local.append(p_joint)
            for k in range(len(cable.route) - 1):
                seg_a.append(start + k)
                seg_cable.append(ci)
            self.route_point_slices.append(slice(start, len(joints)))
        self._n_route_points = len(joints)
        self._output_rows: list[int] = []
        for out in spec.outputs:
            joint, p_joint = self._anchor(out.frame, np.zeros(3))
            self._output_rows.append(len(joints) * 3 + OUTPUT_COMPONENTS[out.component])
            joints.append(joint)
            local.append(p_joint)
        self._point_joint = np.array(joints, dtype=int)
        self._point_local = np.array(local, dtype=float).reshape(-1, 3)
        self._segment_points = np.array([[a, a + 1] for a in seg_a], dtype=int).reshape(-1, 2)
        self._segment_cable = np.array(seg_cable, dtype=int)
        self._output_rows_arr = np.array(self._output_rows, dtype=int)
        self._segment_to_cable = np.zeros((len(spec.cables), len(seg_cable)))
        self._segment_to_cable[seg_cable, np.arange(len(seg_cable))] = 1.0
        # dof mask of each joint: which tangent directions move it
        support = np.zeros((self.model.njoints, self.nv), dtype=bool)
        for j in range(1, self.model.njoints):
            for anc in self.model.supports[j]:
                if anc == 0:
                    continue
                jm = self.model.joints[anc]
                support[j, jm.idx_v : jm.idx_v + jm.nv] = True
        self._point_mask = support[self._point_joint]  # (n_points, nv)
        self._used_joints = np.unique(self._point_joint)
        self._pin = pin
        self._last_q: np.ndarray | None = None
        self._last_kin: CableKinematics | None = None

    # ------------------------------------------------------------------ setup

    def _anchor(self, frame_name: str, point_in_frame: np.ndarray) -> tuple[int, np.ndarray]:
        """Parent joint of a frame and the point expressed in that joint's frame."""
        if frame_name in WORLD_FRAME_NAMES:
            return 0, point_in_frame
        frame = self.model.frames[self.model.getFrameId(frame_name)]
        return int(frame.parentJoint), np.asarray(frame.placement.act(point_in_frame), dtype=float)

    def __repr__(self) -> str:
        return (
            f"CableRobot({self.spec.path.name!r}, nq={self.nq}, nv={self.nv}, "
            f"cables={list(self.cable_names)}, outputs={list(self.output_names)})"
        )

    @property
    def n_cables(self) -> int:
        """Number of cables m."""
        return len(self.cable_names)

    @property
    def n_outputs(self) -> int:
        """Number of outputs p."""
        return len(self.output_names)

    # ---------------------------------------------------------- configuration

    def configuration(self, value: Any) -> np.ndarray:
        """Configuration vector (nq,) from a pose name, a vector (nq or nv
        natural coordinates) or a mapping ``{joint: value}``."""
        if isinstance(value, str):
            if value not in self.poses:
                from cdpm.errors import InputError

                names = ", ".join(self.poses) or "(the spec defines none)"
                raise InputError(f"pose {value!r} not in spec; poses: {names}")
            return self.poses[value].copy()
        return configuration_from_values(self.model, value)

    def as_q(self, q: Any) -> np.ndarray:
        """Validated configuration vector (nq,) from a pose name, a
        configuration vector (nq,) or natural coordinates (nv,)."""
        if isinstance(q, str):
            return self.configuration(q)
        return as_configuration(self.model, q)

    def neutral(self) -> np.ndarray:
        """The model's neutral configuration, shape (nq,)."""
        return np.array(self._pin.neutral(self.model))

    def from_natural(self, natural: Any) -> np.ndarray:
        """Configuration vector (nq,) from natural coordinates (nv,)."""
        return configuration_from_natural(self.model, natural)

    def to_natural(self, q: Any) -> np.ndarray:
        """Natural coordinates (nv,) of a configuration vector."""
        return natural_from_configuration(self.model, q)

    # ------------------------------------------------------------ kinematics

    def kinematics(self, q: Any) -> CableKinematics:
        """All cable and output kinematics at q in one forward pass.

        Raises:
            ModelError: a cable segment has zero length at q (its direction,
                hence its row of L, is undefined).
        """
        q = self.as_q(q)
        if self._last_q is not None and np.array_equal(q, self._last_q):
            return self._last_kin
        kin = self._kinematics(q)
        self._last_q, self._last_kin = q.copy(), kin
        return kin

    def _kinematics(self, q: np.ndarray) -> CableKinematics:
        batch = self._kinematics_batch(q[None, :])
        seg_len = batch["segment_lengths"][0]
        if seg_len.size and seg_len.min() < MIN_SEGMENT_LENGTH:
            k = int(np.argmin(seg_len))
            ci = int(self._segment_cable[k])
            first = k - int(np.flatnonzero(self._segment_cable == ci)[0])
            raise ModelError(
                f"cable {self.cable_names[ci]!r}: segment {first} has zero length at "
                f"q={np.round(q, 6).tolist()} (its attachment points coincide), so its "
                "direction and its row of L are undefined; move the attachment points or "
                "avoid this pose"
            )
        n_route = self._n_route_points
        return CableKinematics(
            q=q,
            lengths=batch["lengths"][0],
            jacobian=batch["jacobian"][0],
            point_positions=batch["point_positions"][0, :n_route],
            point_jacobians=batch["point_jacobians"][0, :n_route],
            segment_lengths=seg_len,
            segment_units=batch["segment_units"][0],
            segment_points=self._segment_points,
            segment_cable=self._segment_cable,
            output=batch["output"][0],
            output_jacobian=batch["output_jacobian"][0],
        )

    def kinematics_batch(self, qs: Any) -> dict[str, np.ndarray]:
        """Cable and output kinematics at many configurations at once.

        The Pinocchio forward pass runs once per configuration; everything
        else is vectorised over the batch, so this is the fast path for maps.
        Zero-length segments are not raised here: they show as
        ``segment_lengths == 0`` and NaN rows, for the caller to flag.

        Args:
            qs: configuration vectors, shape (N, nq) (validated by the caller).

        Returns:
            Arrays with a leading batch axis N: ``lengths`` (N, m),
            ``jacobian`` (N, m, nv), ``output`` (N, p), ``output_jacobian``
            (N, p, nv), ``segment_lengths`` (N, n_segments), ``segment_units``
            (N, n_segments, 3), ``point_positions`` (N, n_points, 3) and
            ``point_jacobians`` (N, n_points, 3, nv) (route points first,
            then output frame origins).
        """
        qs = np.asarray(qs, dtype=float)
        return self._kinematics_batch(qs.reshape(-1, self.nq))

    def _kinematics_batch(self, qs: np.ndarray) -> dict[str, np.ndarray]:
        pin, model, data = self._pin, self.model, self._data
        n = qs.shape[0]
        used = [int(j) for j in self._used_joints if j]
        placements = np.zeros((n, model.njoints, 4, 4))
        placements[:, 0] = np.eye(4)
        jac = np.empty((n, 6, self.nv))
        compute, o_m_i = pin.computeJointJacobians, data.oMi
        for k in range(n):
            compute(model, data, qs[k])
            jac[k] = np.asarray(data.J).reshape(6, -1)
            for j in used:
                placements[k, j] = o_m_i[j].homogeneous
        at_point = placements[:, self._point_joint]  # (N, n_points, 4, 4)
        positions = (
            np.einsum("nkij,kj->nki", at_point[:, :, :3, :3], self._point_local)
            + at_point[:, :, :3, 3]
        )
        # velocity of a point p fixed on a body, from the spatial (world)
        # Jacobian [v; w]: v + w x p, restricted to the joints that move it
        w = jac[:, None, 3:, :]  # (N, 1, 3, nv)
        p = positions[:, :, :, None]  # (N, n_points, 3, 1)
        w_cross_p = np.stack(
            (
                w[:, :, 1] * p[:, :, 2] - w[:, :, 2] * p[:, :, 1],
                w[:, :, 2] * p[:, :, 0] - w[:, :, 0] * p[:, :, 2],
                w[:, :, 0] * p[:, :, 1] - w[:, :, 1] * p[:, :, 0],
            ),
            axis=2,
        )
        point_jac = (jac[:, None, :3, :] + w_cross_p) * self._point_mask[None, :, None, :]

        a, b = self._segment_points[:, 0], self._segment_points[:, 1]
        diff = positions[:, b] - positions[:, a]
        seg_len = np.sqrt(np.einsum("nsi,nsi->ns", diff, diff))
        with np.errstate(invalid="ignore", divide="ignore"):
            units = diff / seg_len[:, :, None]
        seg_rows = np.einsum("nsi,nsiv->nsv", units, point_jac[:, b] - point_jac[:, a])
        to_cable = self._segment_to_cable  # (m, n_segments) 0/1
        flat_pos = positions.reshape(n, -1)
        flat_jac = point_jac.reshape(n, -1, self.nv)
        rows = self._output_rows_arr
        return {
            "lengths": seg_len @ to_cable.T,
            "jacobian": np.einsum("cs,nsv->ncv", to_cable, seg_rows),
            "segment_lengths": seg_len,
            "segment_units": units,
            "point_positions": positions,
            "point_jacobians": point_jac,
            "output": flat_pos[:, rows],
            "output_jacobian": flat_jac[:, rows],
        }

    def mass_matrix_batch(self, qs: Any) -> np.ndarray:
        """Mass matrices at many configurations, shape (N, nv, nv)."""
        qs = np.asarray(qs, dtype=float).reshape(-1, self.nq)
        out = np.empty((qs.shape[0], self.nv, self.nv))
        for k in range(qs.shape[0]):
            out[k] = self._pin.crba(self.model, self._dyn_data, qs[k])
        upper = np.triu(out)
        return upper + np.swapaxes(np.triu(out, 1), 1, 2)

    def cable_lengths(self, q: Any) -> np.ndarray:
        """Cable lengths l(q) [m], shape (m,): sum of each route's segment lengths."""
        return self.kinematics(q).lengths.copy()

    def cable_jacobian(self, q: Any) -> np.ndarray:
        """Cable-joint Jacobian L(q), shape (m, nv): ``l' = L q'`` (paper eq 16).

        Maps joint velocity [rad/s or m/s] to cable length rate [m/s]; the
        generalised force of tensions f >= 0 [N] is ``-L^T f``.
        """
        return self.kinematics(q).jacobian.copy()

    def output(self, q: Any) -> np.ndarray:
        """Outputs y = h(q), shape (p,) [m] (world frame)."""
        return self.kinematics(q).output.copy()

    def output_jacobian(self, q: Any) -> np.ndarray:
        """Output Jacobian dh/dq in the tangent space, shape (p, nv)."""
        return self.kinematics(q).output_jacobian.copy()

    def attachment_points(self, q: Any) -> list[np.ndarray]:
        """World positions of each cable's route points [m], one (k_i, 3) array per cable."""
        positions = self.kinematics(q).point_positions
        return [positions[s].copy() for s in self.route_point_slices]

    # --------------------------------------------------------------- dynamics

    def mass_matrix(self, q: Any) -> np.ndarray:
        """Joint-space mass matrix M(q), shape (nv, nv) [kg, kg m, kg m^2]."""
        upper = self._pin.crba(self.model, self._dyn_data, self.as_q(q))
        return np.triu(upper) + np.triu(upper, 1).T

    def gravity_torque(self, q: Any) -> np.ndarray:
        """Generalised gravity G(q), shape (nv,) [N or N m] (paper eq 11)."""
        q = self.as_q(q)
        return np.array(self._pin.computeGeneralizedGravity(self.model, self._dyn_data, q))

    @property
    def joint_damping(self) -> np.ndarray:
        """Viscous joint damping D [N s/m or N m s/rad], shape (nv,), from the
        URDF ``<dynamics damping=...>`` tags (zero when absent). Its
        generalised force is ``-D q'``."""
        return np.array(self.model.damping, dtype=float)

    # ------------------------------------------------------- cable stiffness

    def _dof_support(self) -> np.ndarray:
        """P[j, k] True when the joint of tangent direction k is the joint of
        direction j or one of its ancestors, shape (nv, nv)."""
        if getattr(self, "_dof_support_cache", None) is None:
            model = self.model
            joint_of_dof = np.zeros(self.nv, dtype=int)
            for j in range(1, model.njoints):
                jm = model.joints[j]
                joint_of_dof[jm.idx_v : jm.idx_v + jm.nv] = j
            support = np.zeros((self.nv, self.nv), dtype=bool)
            for j in range(self.nv):
                ancestors = set(model.supports[int(joint_of_dof[j])])
                support[j] = [int(joint_of_dof[k]) in ancestors for k in range(self.nv)]
            self._dof_support_cache = support
            self._hess_data = model.createData()
        return self._dof_support_cache

    def cable_stiffness(self, q: Any, tension: Any) -> np.ndarray:
        """Derivative of the cables' generalised force, ``d(L(q)^T f)/dq`` at fixed f.

        Equals ``sum_i f_i Hess(l_i)`` (each cable summing its segments),
        in the tangent space of q with Pinocchio's local convention: column k
        is the derivative along ``pin.integrate(model, q, eps * e_k)``, the
        convention of ``pin.computeABADerivatives``. For a segment from A to
        B (``d = B - A``, ``l = |d|``, ``u = d/l``, ``J_d = J_B - J_A``) the
        contribution is ``f (J_d^T (I - u u^T) J_d / l + sum_c u_c d^2 d_c/dq^2)``.
        The second derivatives of a point p on a body come from the world
        spatial Jacobian columns ``(v_k, w_k)``:
        ``dJ_p[:, j]/dq_k = w_k x J_p[:, j]`` when the joint of k is (an
        ancestor of) the joint of j, and ``w_j x J_p[:, k]`` otherwise.
        For joints whose local coordinates do not commute (spherical,
        free-flyer) the matrix is not symmetric.

        Args:
            q: configuration (nq,), natural coordinates (nv,) or pose name.
            tension: cable tensions f [N], shape (m,).

        Returns:
            The stiffness matrix, shape (nv, nv) [N m/rad, N/m, ...]; the
            cables' generalised force ``-L^T f`` changes by ``-H dq``.
        """
        q = self.as_q(q)
        f = np.asarray(tension, dtype=float).reshape(-1)
        if f.shape[0] != self.n_cables:
            raise ModelError(f"tension has {f.shape[0]} entries, expected m={self.n_cables}")
        support = self._dof_support()
        kin = self.kinematics(q)
        self._pin.computeJointJacobians(self.model, self._hess_data, q)
        omega = np.array(self._hess_data.J[3:])  # (3, nv) world angular Jacobian
        seg_f = f[self._segment_cable]
        keep = np.flatnonzero(seg_f != 0)
        if keep.size == 0:
            return np.zeros((self.nv, self.nv))
        seg_f = seg_f[keep]
        a, b = self._segment_points[keep, 0], self._segment_points[keep, 1]
        jac = kin.point_jacobians  # (n_route_points, 3, nv), masked
        units = kin.segment_units[keep]
        lengths = kin.segment_lengths[keep]
        jac_d = jac[b] - jac[a]
        proj = (np.eye(3)[None] - units[:, :, None] * units[:, None, :]) / lengths[:, None, None]
        hess = np.einsum("s,sin,sij,sjk->nk", seg_f, jac_d, proj, jac_d)
        # u x w_k for every segment and tangent direction: (S, 3, nv)
        u_cross_w = np.cross(units[:, None, :], omega.T[None, :, :]).transpose(0, 2, 1)
        for ends, sign in ((b, 1.0), (a, -1.0)):
            jp = jac[ends]
            first = np.einsum("sij,sik->sjk", jp, u_cross_w)  # J_p[:, j] . (u x w_k)
            second = np.einsum("sij,sik->sjk", u_cross_w, jp)  # J_p[:, k] . (u x w_j)
            mask = self._point_mask[ends][:, :, None]
            term = np.where(support[None], first, second * mask)
            hess += sign * np.einsum("s,sjk->jk", seg_f, term)
        return hess


def load_robot(path: str | os.PathLike) -> CableRobot:
    """Load a cable robot from its YAML cable spec (which names its URDF).

    Args:
        path: the cable spec file, e.g. ``models/two_link_planar/two_link_planar.yaml``.
            A directory holding exactly one spec ``<dir>/<dir name>.yaml`` works too.

    Raises:
        SpecError: the spec or its URDF is missing or invalid; the message
            lists every problem found.
    """
    p = Path(path).expanduser()
    if p.is_dir():
        candidate = p / f"{p.name}.yaml"
        if candidate.is_file():
            p = candidate
    return CableRobot(load_spec(p))
