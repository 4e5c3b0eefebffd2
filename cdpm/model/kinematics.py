"""Kinematics results: one pose (:class:`CableKinematics`) and many
(:class:`BatchKinematics`), as :class:`cdpm.model.robot.CableRobot` computes them.

Every array is in the world frame; lengths in m, Jacobians map the tangent
velocity (nv,) [rad/s or m/s] to the rate of the quantity.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

__all__ = ["CableKinematics", "BatchKinematics"]


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


@dataclass(frozen=True)
class BatchKinematics:
    """Cable and output kinematics (and optionally M, G) at N configurations.

    Every array has the pose axis first. Poses with a zero-length segment
    are not raised here: they show as ``segment_lengths == 0`` and NaN rows.

    Attributes:
        qs: configuration vectors, shape (N, nq).
        lengths: cable lengths [m], shape (N, m).
        jacobian: cable Jacobians L, shape (N, m, nv).
        segment_lengths: segment lengths [m], shape (N, n_segments).
        segment_units: segment unit vectors A -> B, shape (N, n_segments, 3).
        point_positions: tracked points (route points, then output points)
            [m], shape (N, n_points, 3).
        point_jacobians: their translational Jacobians, shape (N, n_points, 3, nv).
        output: outputs y, shape (N, p).
        output_jacobian: dy/dv, shape (N, p, nv).
        spatial_jacobian: Pinocchio's world joint Jacobians ``data.J``
            (column k: the world spatial velocity [v; w] of tangent
            direction k at its joint), shape (N, 6, nv).
        mass_matrix: M(q) [kg, kg m^2], shape (N, nv, nv), or None.
        gravity: generalised gravity G(q) [N, N m], shape (N, nv), or None.
    """

    qs: np.ndarray
    lengths: np.ndarray
    jacobian: np.ndarray
    segment_lengths: np.ndarray
    segment_units: np.ndarray
    point_positions: np.ndarray
    point_jacobians: np.ndarray
    output: np.ndarray
    output_jacobian: np.ndarray
    spatial_jacobian: np.ndarray
    mass_matrix: np.ndarray | None = None
    gravity: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.qs.shape[0])

    def take(self, idx) -> BatchKinematics:
        """The kinematics of the poses ``idx`` (indices or a boolean mask)."""
        idx = np.asarray(idx)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        if idx.shape == (len(self),) and np.array_equal(idx, np.arange(len(self))):
            return self
        return BatchKinematics(
            **{
                f.name: (None if (v := getattr(self, f.name)) is None else v[idx])
                for f in dataclasses.fields(self)
            }
        )
