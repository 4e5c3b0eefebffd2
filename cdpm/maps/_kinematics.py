"""Vectorised rigid-body kinematics for maps: many poses in one numpy pass.

A map evaluates the same model at thousands of poses. Calling Pinocchio
once per pose costs a few microseconds of Python overhead per call, which
is more than the arithmetic of a small arm; this module instead composes the
joint placements of a whole batch with array operations, directly from
natural coordinates (see :mod:`cdpm.configuration`).

Everything follows Pinocchio's conventions, so results equal
:meth:`cdpm.robot.CableRobot.kinematics` and ``mass_matrix`` to round-off
(checked by the tests at random poses):

- joint placement ``oMi[j] = oMi[parent] * jointPlacement[j] * M_j(q_j)``;
- tangent directions are the joint motion subspaces expressed in the joint
  (child) frame: a free-flyer's velocity is its body twist;
- the mass matrix is ``sum_b m_b Jc_b^T Jc_b + Jw_b^T (R_b I_b R_b^T) Jw_b``
  over the bodies b (kinetic energy of rigid bodies; equal to CRBA);
- gravity ``G = -sum_b m_b Jc_b^T g``.

Joints supported: revolute (aligned, unaligned, unbounded), prismatic
(aligned, unaligned), free-flyer, spherical, planar and translation. Models
with other joints report ``supported = False`` and maps fall back to the
per-pose robot path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpm.spec import OUTPUT_COMPONENTS, WORLD_FRAME_NAMES

__all__ = ["BatchKinematics", "BatchResult"]

_AXES = {"X": np.eye(3)[0], "Y": np.eye(3)[1], "Z": np.eye(3)[2]}


@dataclass(frozen=True)
class BatchResult:
    """Kinematics and inertia of a batch of N poses (world frame); the pose
    axis is the LAST one.

    Attributes:
        lengths: cable lengths [m], shape (m, N).
        segment_min: shortest straight segment of each pose [m], shape (N,).
        jacobian: cable Jacobian L, shape (m, nv, N) (NaN rows where a
            segment has zero length).
        output: outputs y [m], shape (p, N).
        output_jacobian: dh/dq, shape (p, nv, N).
        frame_position: world position of the first output's frame [m], (3, N).
        mass_matrix: M(q), shape (nv, nv, N).
        gravity: generalised gravity G(q), shape (nv, N).
    """

    lengths: np.ndarray
    segment_min: np.ndarray
    jacobian: np.ndarray
    output: np.ndarray
    output_jacobian: np.ndarray
    frame_position: np.ndarray
    mass_matrix: np.ndarray
    gravity: np.ndarray


# Batched arrays keep the pose axis LAST: vectors are (3, N), rotations
# (3, 3, N). Element-wise arithmetic on contiguous rows of N values is what
# numpy does fastest; batched linear algebra on tiny matrices is not.


def _matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of 3x3 matrices, each constant (3, 3) or batched (3, 3, N)."""
    if a.ndim == 2 and b.ndim == 2:
        return a @ b
    if a.ndim == 2:
        return np.einsum("ij,jkn->ikn", a, b)
    if b.ndim == 2:
        return np.einsum("ijn,jk->ikn", a, b)
    return np.einsum("ijn,jkn->ikn", a, b)


def _matvec(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """a v for a (3, 3) or (3, 3, N) and v (3,) or (3, N)."""
    if a.ndim == 2:
        return a @ v
    if v.ndim == 1:
        return a[:, 0] * v[0] + a[:, 1] * v[1] + a[:, 2] * v[2]
    return a[:, 0] * v[0] + a[:, 1] * v[1] + a[:, 2] * v[2]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for vectors (3,) or (3, N)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _axis_rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations about a fixed unit axis by angles (N,) -> (3, 3, N) (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c1 = np.sin(angle), 1.0 - np.cos(angle)
    return np.eye(3)[:, :, None] + k[:, :, None] * s + (k @ k)[:, :, None] * c1


def _rpy_rotation(roll, pitch, yaw) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll), each (N,) -> (3, 3, N) (Pinocchio's rpyToMatrix)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True)
class _Joint:
    """One joint: kind, parent, placement and motion subspace in its own frame."""

    kind: str  # "revolute", "prismatic", "freeflyer", "spherical", "planar", "translation"
    parent: int
    rotation: np.ndarray  # jointPlacement rotation (3, 3)
    translation: np.ndarray  # jointPlacement translation (3,)
    axis: np.ndarray | None  # revolute / prismatic axis in the joint frame
    idx_v: int
    nv: int
    linear: np.ndarray  # (3, nv_j) linear part of the motion subspace (joint frame)
    angular: np.ndarray  # (3, nv_j) angular part


def _unaligned_axis(joint) -> np.ndarray:
    """Axis of an unaligned revolute or prismatic joint (from the concrete
    joint model: the generic wrapper does not expose it)."""
    concrete = joint.extract() if hasattr(joint, "extract") else joint
    axis = np.array(concrete.axis, dtype=float).reshape(3)
    return axis / np.linalg.norm(axis)


def _joint_from_model(joint, parent: int, placement) -> _Joint | None:
    name = joint.shortname()
    eye = np.eye(3)
    base = dict(
        parent=parent,
        rotation=np.array(placement.rotation),
        translation=np.array(placement.translation),
        idx_v=int(joint.idx_v),
        nv=int(joint.nv),
    )
    zeros1 = np.zeros((3, 1))
    kind = None
    for prefix, prefix_kind in (
        ("JointModelRUB", "revolute"),
        ("JointModelR", "revolute"),
        ("JointModelP", "prismatic"),
    ):
        if name.startswith(prefix) and name[len(prefix) :] in _AXES:
            kind, axis = prefix_kind, _AXES[name[len(prefix) :]]
            break
    if kind is None and name in (
        "JointModelRevoluteUnaligned",
        "JointModelRevoluteUnboundedUnaligned",
    ):
        kind, axis = "revolute", _unaligned_axis(joint)
    if kind is None and name == "JointModelPrismaticUnaligned":
        kind, axis = "prismatic", _unaligned_axis(joint)
    if kind == "revolute":
        return _Joint(kind=kind, axis=axis, linear=zeros1, angular=axis[:, None], **base)
    if kind == "prismatic":
        return _Joint(kind=kind, axis=axis, linear=axis[:, None], angular=zeros1, **base)
    if name == "JointModelFreeFlyer":
        lin = np.hstack([eye, np.zeros((3, 3))])
        ang = np.hstack([np.zeros((3, 3)), eye])
        return _Joint(kind="freeflyer", axis=None, linear=lin, angular=ang, **base)
    if name == "JointModelSpherical":
        return _Joint(kind="spherical", axis=None, linear=np.zeros((3, 3)), angular=eye, **base)
    if name == "JointModelTranslation":
        return _Joint(kind="translation", axis=None, linear=eye, angular=np.zeros((3, 3)), **base)
    if name == "JointModelPlanar":
        lin = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
        ang = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        return _Joint(kind="planar", axis=None, linear=lin, angular=ang, **base)
    return None


def _joint_motion(joint: _Joint, x: np.ndarray):
    """Rotation (3, 3, N) or None and translation (3, N) or None of M_j(x),
    x the joint's natural coordinates (nv_j, N)."""
    if joint.kind == "revolute":
        return _axis_rotation(joint.axis, x[0]), None
    if joint.kind == "prismatic":
        return None, joint.axis[:, None] * x[0]
    if joint.kind == "freeflyer":
        return _rpy_rotation(x[3], x[4], x[5]), x[:3]
    if joint.kind == "spherical":
        return _rpy_rotation(x[0], x[1], x[2]), None
    if joint.kind == "translation":
        return None, x[:3]
    # planar: x, y [m], theta [rad]
    return _axis_rotation(_AXES["Z"], x[2]), np.array([x[0], x[1], np.zeros_like(x[0])])


class BatchKinematics:
    """Cable, output and inertia quantities of a robot at many poses.

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.

    Attributes:
        supported: False when the model has a joint this engine does not
            implement (callers then use the robot's per-pose methods).
    """

    def __init__(self, robot) -> None:
        model = robot.model
        self.nv = int(model.nv)
        self.n_cables = robot.n_cables
        joints: list[_Joint] = []
        self.supported = True
        for j in range(1, model.njoints):
            jm = _joint_from_model(model.joints[j], int(model.parents[j]), model.jointPlacements[j])
            if jm is None:
                self.supported = False
                return
            joints.append(jm)
        self._joints = joints
        # tangent directions that move joint j (its own and its ancestors')
        support = np.zeros((model.njoints, self.nv), dtype=bool)
        for j in range(1, model.njoints):
            for anc in model.supports[j]:
                if anc:
                    jm = model.joints[anc]
                    support[j, jm.idx_v : jm.idx_v + jm.nv] = True
        self._support = support

        def anchor(frame_name: str, point: np.ndarray) -> tuple[int, np.ndarray]:
            if frame_name in WORLD_FRAME_NAMES:
                return 0, point
            frame = model.frames[model.getFrameId(frame_name)]
            return int(frame.parentJoint), np.asarray(frame.placement.act(point), dtype=float)

        point_joint, point_local, seg_a, seg_cable = [], [], [], []
        for ci, cable in enumerate(robot.spec.cables):
            start = len(point_joint)
            for point in cable.route:
                j, p = anchor(point.frame, np.array(point.point_in_frame, dtype=float))
                point_joint.append(j)
                point_local.append(p)
            seg_a.extend(range(start, len(point_joint) - 1))
            seg_cable.extend([ci] * (len(cable.route) - 1))
        n_route = len(point_joint)
        out_rows = []
        for k, out in enumerate(robot.spec.outputs):
            j, p = anchor(out.frame, np.zeros(3))
            point_joint.append(j)
            point_local.append(p)
            out_rows.append((n_route + k, OUTPUT_COMPONENTS[out.component]))
        self._point_joint = np.array(point_joint, dtype=int)
        self._point_local = np.array(point_local, dtype=float).reshape(-1, 3)
        self._seg_a = np.array(seg_a, dtype=int)
        self._seg_cable = np.array(seg_cable, dtype=int)
        self._out_point = np.array([r[0] for r in out_rows], dtype=int)
        self._out_comp = np.array([r[1] for r in out_rows], dtype=int)
        self._first_output_point = n_route if out_rows else None
        self._bodies = [
            (
                j,
                float(model.inertias[j].mass),
                np.array(model.inertias[j].lever),
                np.array(model.inertias[j].inertia),
            )
            for j in range(1, model.njoints)
        ]
        self._gravity = np.array(robot.gravity, dtype=float)

    # ------------------------------------------------------------------

    def _placements(self, x: np.ndarray):
        """World rotation and origin of every joint: lists of (3, 3[, N]) and
        (3[, N]) arrays (the universe's are constants)."""
        rot: list[np.ndarray] = [np.eye(3)]
        pos: list[np.ndarray] = [np.zeros(3)]
        for jm in self._joints:
            r_parent, p_parent = rot[jm.parent], pos[jm.parent]
            r_place = _matmul(r_parent, jm.rotation)
            p_place = _matvec(r_parent, jm.translation)
            p_place = p_place + (p_parent if p_parent.ndim == 1 else p_parent)
            if p_place.ndim == 1:
                p_place = p_place[:, None]
            r_motion, t_motion = _joint_motion(jm, x[jm.idx_v : jm.idx_v + jm.nv])
            rot.append(r_place if r_motion is None else _matmul(r_place, r_motion))
            pos.append(p_place if t_motion is None else p_place + _matvec(r_place, t_motion))
        return rot, pos

    def _columns(self, rot, pos):
        """Per tangent direction c: world angular velocity w_c (3, N) or None
        and linear velocity v0_c (3, N) of the point at the world origin."""
        omega: list = [None] * self.nv
        v0: list = [None] * self.nv
        for j, jm in enumerate(self._joints, start=1):
            for k in range(jm.nv):
                c = jm.idx_v + k
                lin, ang = jm.linear[:, k], jm.angular[:, k]
                v = _matvec(rot[j], lin) if lin.any() else None
                if ang.any():
                    w = _matvec(rot[j], ang)
                    if w.ndim == 1:
                        w = np.broadcast_to(w[:, None], pos[j].shape)
                    omega[c] = w
                    # linear velocity of the point at the world origin: v_o - w x o
                    wxo = _cross(w, pos[j])
                    v0[c] = -wxo if v is None else v - wxo
                else:
                    v0[c] = v if v.ndim == 2 else np.broadcast_to(v[:, None], pos[j].shape)
        return omega, v0

    def _point_column(self, omega, v0, c: int, point: np.ndarray) -> np.ndarray:
        """Column c of the translational Jacobian of a point (3, N)."""
        if omega[c] is None:
            return v0[c]
        return v0[c] + _cross(omega[c], point)

    def evaluate(self, natural: np.ndarray) -> BatchResult:
        """Everything a map needs at the poses ``natural`` (N, nv)."""
        x = np.ascontiguousarray(np.asarray(natural, dtype=float).T)  # (nv, N)
        n, nv = x.shape[1], self.nv
        rot, pos = self._placements(x)
        omega, v0 = self._columns(rot, pos)
        support = self._support
        points = [
            _matvec(rot[j], local) + pos[j] if j else np.broadcast_to(local[:, None], (3, n))
            for j, local in zip(self._point_joint, self._point_local, strict=True)
        ]

        # segment rows of L: u . (J_B - J_A) with (w x p) . u = w . (p x u)
        m = self.n_cables
        lengths = np.zeros((m, n))
        jacobian = np.zeros((m, nv, n))
        segment_min = np.full(n, np.inf)
        for a, cable in zip(self._seg_a, self._seg_cable, strict=True):
            b = a + 1
            ja, jb = self._point_joint[a], self._point_joint[b]
            diff = points[b] - points[a]
            length = np.sqrt(_dot(diff, diff))
            lengths[cable] += length
            np.minimum(segment_min, length, out=segment_min)
            with np.errstate(invalid="ignore", divide="ignore"):
                u = diff / length
            pa_u, pb_u = _cross(points[a], u), _cross(points[b], u)
            for c in range(nv):
                sa, sb = support[ja, c], support[jb, c]
                if sa == sb and (not sa or ja == jb):
                    continue  # both ends move alike (or not at all) along c
                u_v = _dot(u, v0[c])
                w = omega[c]
                if sb:
                    jacobian[cable, c] += u_v if w is None else u_v + _dot(w, pb_u)
                if sa:
                    jacobian[cable, c] -= u_v if w is None else u_v + _dot(w, pa_u)

        p = len(self._out_point)
        output = np.empty((p, n))
        output_jac = np.zeros((p, nv, n))
        for k, (pt, comp) in enumerate(zip(self._out_point, self._out_comp, strict=True)):
            point, j = points[pt], self._point_joint[pt]
            output[k] = point[comp]
            for c in np.flatnonzero(support[j]):
                output_jac[k, c] = self._point_column(omega, v0, c, point)[comp]
        if self._first_output_point is None:
            frame_position = np.full((3, n), np.nan)
        else:
            frame_position = np.array(points[self._first_output_point])

        mass = np.zeros((nv, nv, n))
        gravity = np.zeros((nv, n))
        g = self._gravity
        for j, m_b, lever, inertia in self._bodies:
            cols = np.flatnonzero(support[j])
            if m_b:
                com = _matvec(rot[j], lever) + pos[j]
                jc = {c: self._point_column(omega, v0, c, com) for c in cols}
                for i1, c in enumerate(cols):
                    for d in cols[i1:]:
                        mass[c, d] += m_b * _dot(jc[c], jc[d])
                    if g.any():
                        gravity[c] -= m_b * _dot(jc[c], g)
            if inertia.any():
                world = _matmul(_matmul(rot[j], inertia), np.swapaxes(rot[j], 0, 1))
                for i1, c in enumerate(cols):
                    if omega[c] is None:
                        continue
                    iw = _matvec(world, omega[c])
                    for d in cols[i1:]:
                        if omega[d] is not None:
                            mass[c, d] += _dot(omega[d], iw)
        for c in range(nv):
            for d in range(c + 1, nv):
                mass[d, c] = mass[c, d]
        return BatchResult(
            lengths=lengths,
            segment_min=segment_min,
            jacobian=jacobian,
            output=output,
            output_jacobian=output_jac,
            frame_position=frame_position,
            mass_matrix=mass,
            gravity=gravity,
        )
