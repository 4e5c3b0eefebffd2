"""Robot: the Pinocchio model plus the cable layer.

:class:`CableRobot` evaluates, at a configuration q, everything the
linearisation needs: cable lengths l(q), the cable-joint Jacobian L(q)
(``l' = L q'``, seed paper eq 16), the mass matrix M(q), gravity G(q), and
the outputs y = h(q) with their Jacobian.

Conventions (docs/analysis.md): a straight segment from attachment point
A to B has length ``|B - A|`` and unit vector ``u = (B - A)/|B - A|``; its row
of L is ``u^T (J_B - J_A)`` with ``J_X`` the (3, nv) world-aligned
translational Jacobian of the point X. A cable with several segments sums
its segments' rows. A tension f pulls B towards A; the generalised force of
all cables is ``-L^T f``.
"""

from __future__ import annotations

import ctypes
import functools
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError, ModelError
from cdpm.model.coordinates import (
    as_configuration,
    configuration_from_natural,
    configuration_from_values,
    coordinate_names,
    natural_from_configuration,
)
from cdpm.model.kinematics import BatchKinematics, CableKinematics
from cdpm.model.outputs import OutputBasis, anchor_in_joint, joint_support
from cdpm.model.spec import (
    CableSpec,
    find_specs,
    folder_error,
    load_spec,
    usable_path,
)
from cdpm.numerics import MAX_MODEL_DOF, MIN_SEGMENT_LENGTH, REACH_MIN_ACCELERATION

__all__ = ["CableRobot", "CableKinematics", "BatchKinematics", "load_robot", "spec_in_folder"]

#: the magnitudes cdpm analyses: link masses [kg] and principal moments of
#: inertia [kg m^2] within these bounds (zero allowed: a massless link), and
#: lengths (attachment and output points, joint placements) up to
#: MAX_MODEL_LENGTH [m]. Outside them the dynamics' matrices span so many
#: orders of magnitude that the solvers' round-off decides the verdict.
MODEL_MASS_RANGE = (1e-9, 1e9)
MODEL_INERTIA_MAX = 1e12
MAX_MODEL_LENGTH = 1e5
#: an inertia matrix is positive semi-definite: a principal moment below
#: -MODEL_INERTIA_NEGATIVE_RTOL times the largest |moment| is negative, not
#: round-off (Pinocchio combines the inertias of links joined by fixed joints)
MODEL_INERTIA_NEGATIVE_RTOL = 1e-9


class CableRobot:
    """A cable-driven manipulator: Pinocchio model, cables and outputs.

    Build one with :func:`load_robot`. Every method that takes ``q`` accepts
    the model's configuration vector (nq,) or, when nq != nv, natural
    coordinates (nv,) (see :mod:`cdpm.model.coordinates`).

    Attributes:
        spec: the validated :class:`~cdpm.model.spec.CableSpec`.
        model: the ``pinocchio.Model`` (gravity set from the spec).
        nq, nv: sizes of the configuration vector and of the tangent space.
        cable_names: names of the m cables, in spec order.
        output_names: names of the p outputs.
        output_units: unit of each output: ``"m"``, ``"rad"`` or the
            spec's ``unit:`` (``"mixed"`` for sums of both).
        output_points: index of each output's tracked point (route points
            first, then one per output drawn at a frame) in
            ``point_positions``, or -1 for joint and cable outputs, (p,).
        coordinate_names: names of the nv natural coordinates.
        poses: named configuration vectors from the spec, each (nq,).
        tension_min, tension_max: tension bounds [N], each shape (m,).
    """

    def __init__(self, spec: CableSpec) -> None:
        # pinocchio: loaded on first use
        import pinocchio as pin

        self.spec = spec
        self.model = spec.model
        self._check_size()
        self._dyn_data = self.model.createData()
        self.nq = int(self.model.nq)
        self.nv = int(self.model.nv)
        self.cable_names = tuple(c.name for c in spec.cables)
        self.output_names = tuple(o.name for o in spec.outputs)
        self.output_units = tuple(o.unit for o in spec.outputs)
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
                joint, p_joint = anchor_in_joint(
                    self.model, point.frame, np.array(point.point_in_frame)
                )
                joints.append(joint)
                local.append(p_joint)
            for k in range(len(cable.route) - 1):
                seg_a.append(start + k)
                seg_cable.append(ci)
            self.route_point_slices.append(slice(start, len(joints)))
        self._n_route_points = len(joints)
        output_points = []
        for out in spec.outputs:
            marker = out.marker_term
            if marker is None:
                output_points.append(-1)
                continue
            output_points.append(len(joints))
            joint, p_joint = anchor_in_joint(
                self.model, marker.frame, np.array(marker.point_in_frame)
            )
            joints.append(joint)
            local.append(p_joint)
        self.output_points = np.array(output_points, dtype=int)
        # dof mask of each joint: which tangent directions move it
        support = joint_support(self.model)
        self._output_basis = OutputBasis(self.model, spec, self.output_points, len(joints), support)
        for joint, p_joint in self._output_basis.points:
            joints.append(joint)
            local.append(p_joint)
        self._point_joint = np.array(joints, dtype=int)
        self._point_local = np.array(local, dtype=float).reshape(-1, 3)
        self._check_magnitudes()
        self._segment_points = np.array([[a, a + 1] for a in seg_a], dtype=int).reshape(-1, 2)
        self._segment_cable = np.array(seg_cable, dtype=int)
        self._segment_to_cable = np.zeros((len(spec.cables), len(seg_cable)))
        self._segment_to_cable[seg_cable, np.arange(len(seg_cable))] = 1.0
        self._point_mask = support[self._point_joint]  # (n_points, nv)
        self._joint_support = support  # (njoints, nv)
        self._pin = pin
        self._last_q: np.ndarray | None = None
        self._last_kin: CableKinematics | None = None
        self._last_batch: BatchKinematics | None = None  # its batch-of-one arrays

    # ------------------------------------------------------------------ setup

    def _check_size(self) -> None:
        """Refuse models with more than MAX_MODEL_DOF degrees of freedom
        before Pinocchio's data for them (about 64 nv^3 bytes) is created."""
        model = self.model
        if model.nv > MAX_MODEL_DOF:
            joints = sum(1 for j in range(1, model.njoints) if model.joints[j].nv > 0)
            raise ModelError(
                f"{self.spec.path.name}: the model has {joints:,} moving joints with "
                f"{model.nv:,} degrees of freedom, more than the {MAX_MODEL_DOF} cdpm "
                f"analyses (its dynamics would need about {64 * model.nv**3 / 1e9:.0f} GB of "
                'memory); fix the joints that should not move as type="fixed" in the URDF, '
                "or model fewer links"
            )

    def _check_magnitudes(self) -> None:
        """Refuse models whose masses, inertias or lengths are outside the
        range cdpm analyses (MODEL_MASS_RANGE, MODEL_INERTIA_MAX,
        MAX_MODEL_LENGTH), or whose inertia matrices have a negative principal
        moment (MODEL_INERTIA_NEGATIVE_RTOL), before any solver sees them."""
        model, problems = self.model, []
        low, high = MODEL_MASS_RANGE
        for j in range(1, model.njoints):
            name = model.names[j]
            mass = float(model.inertias[j].mass)
            inertia = np.array(model.inertias[j].inertia)
            finite = np.all(np.isfinite(inertia))
            moments = np.linalg.eigvalsh(inertia) if finite else np.full(3, np.nan)
            if mass != 0 and not low <= mass <= high:
                problems.append(f"the body moved by joint {name!r} has mass {mass:g} kg")
            if not (np.all(np.isfinite(moments)) and np.abs(moments).max() <= MODEL_INERTIA_MAX):
                problems.append(
                    f"the body moved by joint {name!r} has moments of inertia "
                    f"{np.array2string(moments, precision=3)} kg m^2"
                )
            elif moments.min() < -MODEL_INERTIA_NEGATIVE_RTOL * np.abs(moments).max():
                problems.append(
                    f"the body moved by joint {name!r} has an inertia matrix with a negative "
                    f"principal moment ({np.array2string(moments, precision=3)} kg m^2), which "
                    "no body has: fix its ixx, iyy, izz and the signs of ixy, ixz, iyz"
                )
            offset = float(np.abs(model.jointPlacements[j].translation).max())
            if not offset <= MAX_MODEL_LENGTH:
                problems.append(f"joint {name!r} is placed {offset:g} m from its parent")
        far = np.abs(self._point_local).max(axis=1, initial=0.0)
        for k in np.flatnonzero(~(far <= MAX_MODEL_LENGTH))[:3]:
            problems.append(f"an attachment or output point lies {far[k]:g} m from its frame")
        if problems:
            raise ModelError(
                f"{self.spec.path.name}: {'; '.join(problems)}. cdpm analyses masses of "
                f"{low:g} to {high:g} kg (or 0), moments of inertia up to "
                f"{MODEL_INERTIA_MAX:g} kg m^2 and lengths up to {MAX_MODEL_LENGTH:g} m; "
                "check the URDF's units (kg, m) and values"
            )

    @functools.cached_property
    def mass(self) -> float:
        """Total mass of the links [kg] (0 for a massless model)."""
        model = self.model
        return float(sum(model.inertias[i].mass for i in range(1, model.njoints)))

    @functools.cached_property
    def force_scale(self) -> float:
        """The robot's own force scale [N]: its weight, or its mass times
        REACH_MIN_ACCELERATION (1 m/s^2) under weaker gravity; 1 N for a
        massless model.

        The statics are judged relative to it, never to an absolute newton:
        a residual or a tension is round-off when it is below a relative
        tolerance of the tensions this force scale (or larger given
        tensions, or a larger load) produces through L^T
        (:func:`cdpm.dynamics.equilibrium.statics.statics_tolerance`). So
        scaling every mass (with bounds [0, inf)) or every length of a robot
        changes no verdict. It is also the default tension budget of the
        reach margin."""
        mass = self.mass
        if not mass > 0:
            return 1.0
        return mass * max(float(np.linalg.norm(self.gravity)), REACH_MIN_ACCELERATION)

    @functools.cached_property
    def size(self) -> float:
        """The robot's size l [m]: the largest distance between two cable
        route points at the spec's first named pose (else the neutral
        configuration; 1 m when they coincide). The length scale of the
        reach margin's defaults and of round-off in the outputs."""
        q = self.configuration(next(iter(self.poses))) if self.poses else self.neutral()
        kin = self.kinematics_batch(q[None])
        n_route = self.route_point_slices[-1].stop if self.route_point_slices else 0
        P = kin.point_positions[0, :n_route]
        size = float(np.max(np.linalg.norm(P[:, None] - P[None], axis=2))) if n_route > 1 else 0.0
        return size if size > 0 and math.isfinite(size) else 1.0

    @functools.cached_property
    def output_scales(self) -> np.ndarray:
        """How far each output moves when the robot turns by about one
        radian, shape (p,) [each output's unit]: the sum over its terms of
        ``|weight|`` times the robot's :attr:`size` l [m] for terms in metres
        (positions, cable lengths, prismatic joints) or times 1 for terms in
        radians (rotations, revolute joints). The scale that round-off of an
        output's row is judged against
        (:func:`cdpm.dynamics.linearisation.output_jacobian_rounded`)."""
        size = self.size
        scales = [
            sum(abs(t.weight) * (1.0 if t.unit == "rad" else size) for t in out.terms)
            for out in self.spec.outputs
        ]
        return np.array(scales, dtype=float)

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
                names = ", ".join(self.poses) or "(the spec defines none)"
                raise InputError(f"pose {value!r} not in spec; poses: {names}")
            return self.poses[value].copy()
        return configuration_from_values(self.model, value)

    def as_q(self, q: Any) -> np.ndarray:
        """Validated configuration vector (nq,) from a pose name, a
        configuration vector (nq,), natural coordinates (nv,) or a mapping
        ``{joint or coordinate name: value}`` as a spec's poses give it
        (coordinates not named are 0)."""
        if isinstance(q, (str, Mapping)):
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
        kin, batch = self._kinematics(q)
        self._last_q, self._last_kin, self._last_batch = q.copy(), kin, batch
        return kin

    def _kinematics(self, q: np.ndarray) -> tuple[CableKinematics, BatchKinematics]:
        batch = self._kinematics_batch(q[None, :])
        seg_len = batch.segment_lengths[0]
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
        kin = CableKinematics(
            q=q,
            lengths=batch.lengths[0],
            jacobian=batch.jacobian[0],
            point_positions=batch.point_positions[0, :n_route],
            point_jacobians=batch.point_jacobians[0, :n_route],
            segment_lengths=seg_len,
            segment_units=batch.segment_units[0],
            segment_points=self._segment_points,
            segment_cable=self._segment_cable,
            output=batch.output[0],
            output_jacobian=batch.output_jacobian[0],
        )
        return kin, batch

    def kinematics_batch(self, qs: Any, dynamics: bool = False) -> BatchKinematics:
        """Cable and output kinematics (and optionally M, G) at many configurations.

        One Pinocchio call per configuration, ``crba`` with the WORLD
        convention, fills the mass matrix, the world joint Jacobians and the
        joint placements at once (plus ``computeGeneralizedGravity`` when
        ``dynamics`` is asked for and gravity is nonzero); everything else
        (cable points, their Jacobians, segments, L, outputs) is array
        arithmetic over the whole batch, so this is the fast path for maps.
        Zero-length segments are not raised here: they show as
        ``segment_lengths == 0`` and NaN rows, for the caller to flag.

        Args:
            qs: configuration vectors, shape (N, nq) (validated by the caller).
            dynamics: also return ``mass_matrix`` and ``gravity``.

        Returns:
            :class:`~cdpm.model.kinematics.BatchKinematics` with a leading pose
            axis N on every array (route points first, then output points;
            world frame); ``mass_matrix`` and ``gravity`` only with
            ``dynamics``. The arrays are computed with the batch axis last
            and returned as views with it first: ``np.moveaxis(a, 0, -1)``
            gives the contiguous batch-last array back without a copy.
        """
        qs = np.asarray(qs, dtype=float)
        return self._kinematics_batch(qs.reshape(-1, self.nq), dynamics)

    def _batch_views(self):
        """Pinocchio data for batches and live numpy views of what one
        ``crba(..., WORLD)`` call fills: J (6, nv), M (nv, nv) and the joint
        placements, as one (njoints, 12) array (each row the column-major
        rotation then the translation) when ``data.oMi`` is laid out that
        way in memory (checked), else one (rotation, translation) pair per
        joint; plus the indices of the tracked points fixed in the world."""
        views = getattr(self, "_batch_views_cache", None)
        if views is not None:
            return views

        pin, model = self._pin, self.model
        data = model.createData()
        nj = model.njoints
        placements = None
        first = data.oMi[0].rotation
        base = first.__array_interface__["data"][0]
        stride = 12 * first.itemsize
        layout_ok = first.flags["F_CONTIGUOUS"] and all(
            data.oMi[j].rotation.__array_interface__["data"][0] == base + j * stride
            and data.oMi[j].translation.__array_interface__["data"][0] == base + j * stride + 72
            for j in range(nj)
        )
        if layout_ok:
            buffer = (ctypes.c_double * (12 * nj)).from_address(base)
            flat = np.frombuffer(buffer, dtype=float).reshape(nj, 12)
            # a pose where every placement differs from the neutral one
            q = pin.integrate(model, pin.neutral(model), 0.3 + 0.1 * np.arange(model.nv))
            pin.crba(model, data, q, pin.Convention.WORLD)
            layout_ok = all(
                np.array_equal(flat[j, :9].reshape(3, 3, order="F"), data.oMi[j].rotation)
                and np.array_equal(flat[j, 9:], data.oMi[j].translation)
                for j in range(nj)
            )
            if layout_ok:
                placements = flat
        if placements is None:
            placements = [(data.oMi[j].rotation, data.oMi[j].translation) for j in range(nj)]
        fixed = np.flatnonzero(self._point_joint == 0)  # points fixed in the world
        # one-DOF models: eigenpy hands out J as (6,) and M as (1,) views
        jac, mass = data.J, data.M
        jac = jac if jac.ndim == 2 else jac.reshape(6, self.nv)
        mass = mass if mass.ndim == 2 else mass.reshape(self.nv, self.nv)
        views = (data, jac, mass, placements, fixed)
        self._batch_views_cache = views
        return views

    def _kinematics_batch(self, qs: np.ndarray, dynamics: bool = False) -> BatchKinematics:
        pin, model = self._pin, self.model
        data, J, M, placements, fixed = self._batch_views()
        n, nv, nj = qs.shape[0], self.nv, model.njoints
        jac = np.empty((n, 6, nv))
        pl = np.empty((n, nj, 12))
        mass = np.empty((n, nv, nv)) if dynamics else None
        gravity = np.zeros((n, nv)) if dynamics else None
        crba, world = pin.crba, pin.Convention.WORLD
        # one crba per pose fills data.M (upper triangle), data.J and
        # data.oMi; the views read them without temporaries
        if isinstance(placements, np.ndarray):
            if dynamics and np.any(self.gravity):
                g_of = pin.computeGeneralizedGravity
                for k in range(n):
                    q = qs[k]
                    crba(model, data, q, world)
                    jac[k] = J
                    mass[k] = M
                    pl[k] = placements
                    gravity[k] = g_of(model, data, q)
            elif dynamics:
                for k in range(n):
                    crba(model, data, qs[k], world)
                    jac[k] = J
                    mass[k] = M
                    pl[k] = placements
            else:
                for k in range(n):
                    crba(model, data, qs[k], world)
                    jac[k] = J
                    pl[k] = placements
        else:  # Pinocchio builds with another SE3 layout
            for k in range(n):
                crba(model, data, qs[k], world)
                jac[k] = J
                if dynamics:
                    mass[k] = M
                    if np.any(self.gravity):
                        gravity[k] = pin.computeGeneralizedGravity(model, data, qs[k])
                for j, (r, t) in enumerate(placements):
                    pl[k, j, :9] = r.reshape(-1, order="F")
                    pl[k, j, 9:] = t
        # batch axis last from here: element-wise work on contiguous rows
        pl_t = np.ascontiguousarray(pl.transpose(2, 1, 0))  # (12, nj, N)
        jac_t = np.ascontiguousarray(jac.transpose(1, 2, 0))  # (6, nv, N)
        pj = self._point_joint
        rot = pl_t[:9, pj]  # (9, P, N), rot[i + 3 c] = R[i, c]
        local = self._point_local.T[:, :, None]  # (3, P, 1)
        pos = pl_t[9:, pj] + rot[0:3] * local[0] + rot[3:6] * local[1] + rot[6:9] * local[2]
        # velocity of a point p fixed on a body, from the spatial (world)
        # Jacobian [v; w]: v + w x p, restricted to the joints that move it;
        # points fixed in the world have none (rows of +0.0)
        v, w = jac_t[:3, None], jac_t[3:, None]  # (3, 1, nv, N)
        p = pos[:, :, None, :]  # (3, P, 1, N)
        pjac = np.empty((3, pos.shape[1], nv, n))  # (3, P, nv, N)
        term = np.empty(pjac.shape[1:])
        for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):  # (w x p)_i = w_j p_k - w_k p_j
            np.multiply(w[j], p[k], out=pjac[i])
            np.multiply(w[k], p[j], out=term)
            pjac[i] -= term
        pjac += v
        pjac *= self._point_mask[None, :, :, None]
        if fixed.size:
            pjac[:, fixed] = 0.0

        a, b = self._segment_points[:, 0], self._segment_points[:, 1]
        diff = pos[:, b] - pos[:, a]  # (3, S, N)
        seg_len = np.sqrt(diff[0] * diff[0] + diff[1] * diff[1] + diff[2] * diff[2])
        with np.errstate(invalid="ignore", divide="ignore"):
            units = diff / seg_len
        jd = pjac[:, b]  # (3, S, nv, N)
        jd -= pjac[:, a]  # x - (+0.0) is x exactly
        seg_rows = units[0, :, None] * jd[0]
        for i in (1, 2):
            jd[i] *= units[i, :, None]
            seg_rows += jd[i]
        to_cable = self._segment_to_cable  # (m, S) 0/1
        if to_cable.shape[0] == to_cable.shape[1]:  # one segment per cable
            lengths, rows_l = seg_len, seg_rows
        else:
            lengths = np.einsum("cs,sn->cn", to_cable, seg_len)
            rows_l = np.einsum("cs,svn->cvn", to_cable, seg_rows)
        output, output_jac = self._output_basis.evaluate(qs, pos, pjac, pl, jac, lengths, rows_l)
        if dynamics and nv > 1:  # crba fills the upper triangle
            iu, ju = np.triu_indices(nv, 1)
            mass[:, ju, iu] = mass[:, iu, ju]
        return BatchKinematics(
            qs=qs,
            lengths=lengths.T,
            jacobian=rows_l.transpose(2, 0, 1),
            segment_lengths=seg_len.T,
            segment_units=units.transpose(2, 1, 0),
            point_positions=pos.transpose(2, 1, 0),
            point_jacobians=pjac.transpose(3, 1, 0, 2),
            output=output,
            output_jacobian=output_jac,
            spatial_jacobian=jac,
            mass_matrix=mass,
            gravity=gravity,
        )

    def mass_matrix_batch(self, qs: Any) -> np.ndarray:
        """Mass matrices at many configurations, shape (N, nv, nv)."""
        qs = np.asarray(qs, dtype=float).reshape(-1, self.nq)
        pin, model = self._pin, self.model
        data, _, M, _, _ = self._batch_views()
        crba, world = pin.crba, pin.Convention.WORLD
        out = np.empty((qs.shape[0], self.nv, self.nv))
        for k in range(qs.shape[0]):
            crba(model, data, qs[k], world)
            out[k] = M
        if self.nv > 1:  # crba fills the upper triangle
            iu, ju = np.triu_indices(self.nv, 1)
            out[:, ju, iu] = out[:, iu, ju]
        return out

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
        """Outputs y = h(q), shape (p,), each in its unit (``output_units``):
        world coordinates [m], rotation vector components [rad], joint
        coordinates [rad or m], cable lengths [m], or their weighted sums."""
        return self.kinematics(q).output.copy()

    def output_jacobian(self, q: Any) -> np.ndarray:
        """Output Jacobian in the tangent space, shape (p, nv): ``y' = J v``.

        Rows of orientation components are the frame's angular velocity
        about the world axes (so they are the derivative of
        ``log3(R(q + dq) R(q)^T)``, not of the stored rotation vector
        ``log3(R(q))`` away from the identity); see docs/outputs.md."""
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
        self.kinematics(q)  # raises on a zero-length segment; keeps its batch arrays
        return self.cable_stiffness_batch(self._last_batch, f[None, :])[0]

    def cable_stiffness_batch(self, kin: BatchKinematics, tension: np.ndarray) -> np.ndarray:
        """:meth:`cable_stiffness` at many poses from their batch kinematics.

        Compiled (:mod:`cdpm.model.stiffness_kernel`): one loop over the poses,
        so a pose alone gives bit for bit its result inside any batch.

        Args:
            kin: the output of :meth:`kinematics_batch` at N poses, none with
                a zero-length segment.
            tension: cable tensions f [N], shape (N, m).

        Returns:
            The stiffness matrices, shape (N, nv, nv).
        """
        from cdpm.model.stiffness_kernel import stiffness_batch  # numba: loaded on use

        return stiffness_batch(
            kin.point_jacobians,
            kin.segment_units,
            kin.segment_lengths,
            kin.spatial_jacobian,
            tension,
            self._segment_points,
            self._segment_cable,
            self._dof_support(),
            self._point_mask,
        )


def load_robot(path: str | os.PathLike) -> CableRobot:
    """Load a cable robot from its YAML cable spec (which names its URDF).

    Args:
        path: the cable spec file, e.g. ``models/two_link_planar/two_link_planar.yaml``.
            A folder works too: ``<dir>/<dir name>.yaml`` when it exists, else
            the folder's only spec (:func:`spec_in_folder`).

    Raises:
        SpecError: the spec or its URDF is missing or invalid (the message
            lists every problem found), or a folder holds no spec or several
            (the message lists them).
    """
    p = usable_path(path)
    if p.is_dir():
        p = spec_in_folder(path)
    return CableRobot(load_spec(p))


def spec_in_folder(folder: str | os.PathLike) -> Path:
    """The spec a folder stands for: ``<folder>/<folder name>.yaml`` when
    it exists, else the folder's only spec (:func:`cdpm.model.spec.find_specs`:
    in it or one folder down).

    Raises:
        SpecError: the folder holds no spec or several; the message lists
            them.
    """
    root = Path(folder).expanduser()
    own = root / f"{root.resolve().name}.yaml"
    if own.is_file():
        return own
    specs = find_specs(folder)
    if len(specs) == 1:
        return specs[0]
    raise folder_error(folder, specs)
