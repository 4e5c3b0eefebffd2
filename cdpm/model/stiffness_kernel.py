"""Compiled cable stiffness of many poses (numba, cached on disk).

Imported lazily by :meth:`cdpm.model.robot.CableRobot.cable_stiffness_batch`, so
that ``import cdpm`` does not load numba. The poses run in blocks of
BLOCK side by side, every pose with the same arithmetic whatever its block
and lane, so a pose's result does not depend on its batch (bit for bit);
within a pose the segments are summed in their order into three sums (the
Gram terms, the second derivatives at the segments' ends B and at their
starts A), added at the end as ``gram + ends - starts``.

The arrays keep the layout the caller has (the kinematics are views with
the pose axis first over batch-last storage): the signature takes any
strides, so there is one compiled version.
"""

from __future__ import annotations

import numpy as np

from cdpm.jit import kernel

__all__ = ["stiffness_batch"]

_SIGNATURE = (
    "void(float64[:, :, :, :], float64[:, :, :], float64[:, :], float64[:, :, :],"
    " float64[:, :], int64[:, :], int64[:], boolean[:, :], boolean[:, :], float64[:, :, :])"
)


#: poses computed side by side (their lanes are independent: each pose's
#: arithmetic is the same whatever its block and lane)
BLOCK = 8


@kernel(_SIGNATURE, error_model="numpy")
def _stiffness_poses(
    jac, units, seg_len, spatial, tension, seg_points, seg_cable, support, point_mask, out
):  # pragma: no cover - compiled
    """Fill out[n] with the stiffness of pose n (see :func:`stiffness_batch`).

    The inputs of BLOCK poses are gathered into small buffers with the pose
    last (reading whole cache lines when the caller's storage has the pose
    axis last), and every step runs over the block's poses in the innermost
    loop; unused lanes of the last block hold copies of its first
    pose and are not written out.
    """
    n_poses, n_seg, nv = out.shape[0], seg_points.shape[0], out.shape[1]
    n_points = point_mask.shape[0]
    moves = np.zeros(n_points, dtype=np.bool_)
    for p in range(n_points):
        for k in range(nv):
            moves[p] = moves[p] or point_mask[p, k]
    jp = np.zeros((n_points, 3, nv, BLOCK))  # J_p (zero for points fixed in the world)
    us = np.empty((n_seg, 3, BLOCK))  # u
    fs = np.empty((n_seg, BLOCK))  # the segment's tension f
    fl = np.empty((n_seg, BLOCK))  # f / l
    ws = np.empty((3, nv, BLOCK))  # world angular velocities w_k
    jd = np.empty((3, nv, BLOCK))
    uj = np.empty((nv, BLOCK))
    cw = np.empty((3, nv, BLOCK))
    gram_sum = np.empty((nv, nv, BLOCK))
    end_sums = np.empty((2, nv, nv, BLOCK))  # 0: at B (sign +), 1: at A (sign -)
    lane = np.empty(BLOCK, dtype=np.int64)
    for n0 in range(0, n_poses, BLOCK):
        for i in range(BLOCK):
            lane[i] = n0 + i if n0 + i < n_poses else n0
        for p in range(n_points):
            if moves[p]:
                for c in range(3):
                    for j in range(nv):
                        for i in range(BLOCK):
                            jp[p, c, j, i] = jac[lane[i], p, c, j]
        for s in range(n_seg):
            for i in range(BLOCK):
                fs[s, i] = tension[lane[i], seg_cable[s]]
                fl[s, i] = fs[s, i] / seg_len[lane[i], s]
            for c in range(3):
                for i in range(BLOCK):
                    us[s, c, i] = units[lane[i], s, c]
        for c in range(3):
            for j in range(nv):
                for i in range(BLOCK):
                    ws[c, j, i] = spatial[lane[i], 3 + c, j]
        gram_sum[:] = 0.0
        end_sums[:] = 0.0
        for s in range(n_seg):
            a, b = seg_points[s, 0], seg_points[s, 1]
            for j in range(nv):
                for i in range(BLOCK):
                    u0, u1, u2 = us[s, 0, i], us[s, 1, i], us[s, 2, i]
                    d0 = jp[b, 0, j, i] - jp[a, 0, j, i]
                    d1 = jp[b, 1, j, i] - jp[a, 1, j, i]
                    d2 = jp[b, 2, j, i] - jp[a, 2, j, i]
                    jd[0, j, i], jd[1, j, i], jd[2, j, i] = d0, d1, d2
                    uj[j, i] = u0 * d0 + u1 * d1 + u2 * d2
                    # u x w_j
                    w0, w1, w2 = ws[0, j, i], ws[1, j, i], ws[2, j, i]
                    cw[0, j, i] = u1 * w2 - u2 * w1
                    cw[1, j, i] = u2 * w0 - u0 * w2
                    cw[2, j, i] = u0 * w1 - u1 * w0
            # J_d^T (I - u u^T) J_d / l = (J_d^T J_d - (J_d^T u)(u^T J_d)) / l,
            # symmetric: the upper triangle, mirrored at the end
            for j in range(nv):
                for k in range(j, nv):
                    for i in range(BLOCK):
                        g = jd[0, j, i] * jd[0, k, i] + jd[1, j, i] * jd[1, k, i]
                        g += jd[2, j, i] * jd[2, k, i]
                        gram_sum[j, k, i] += fl[s, i] * (g - uj[j, i] * uj[k, i])
            for e in range(2):
                p = b if e == 0 else a
                if not moves[p]:  # a point fixed in the world: J_p = 0
                    continue
                # T_p[j, k] = J_p[:, j] . (u x w_k) where support[j, k], else
                # J_p[:, k] . (u x w_j) where direction j moves p; zero
                # otherwise (J_p[:, j] = 0 when j does not move p)
                for j in range(nv):
                    if not point_mask[p, j]:
                        continue
                    for k in range(nv):
                        r, q = (j, k) if support[j, k] else (k, j)
                        for i in range(BLOCK):
                            t = jp[p, 0, r, i] * cw[0, q, i] + jp[p, 1, r, i] * cw[1, q, i]
                            t += jp[p, 2, r, i] * cw[2, q, i]
                            end_sums[e, j, k, i] += fs[s, i] * t
        for i in range(min(BLOCK, n_poses - n0)):
            for j in range(nv):
                for k in range(nv):
                    g = gram_sum[j, k, i] if k >= j else gram_sum[k, j, i]
                    out[n0 + i, j, k] = g + end_sums[0, j, k, i] - end_sums[1, j, k, i]


def stiffness_batch(
    point_jacobians: np.ndarray,
    segment_units: np.ndarray,
    segment_lengths: np.ndarray,
    spatial_jacobian: np.ndarray,
    tension: np.ndarray,
    segment_points: np.ndarray,
    segment_cable: np.ndarray,
    support: np.ndarray,
    point_mask: np.ndarray,
) -> np.ndarray:
    """``sum_i f_i Hess(l_i)`` at N poses, summed over the cables' segments.

    A segment from point A to point B (unit u, length l, ``J_d = J_B - J_A``)
    with tension f adds ``f J_d^T (I - u u^T) J_d / l + f (T_B - T_A)``, where
    ``T_p[j, k] = J_p[:, j] . (u x w_k)`` when ``support[j, k]`` and
    ``point_mask[p, j] J_p[:, k] . (u x w_j)`` otherwise (w_k: the world
    angular velocity of tangent direction k).

    Args:
        point_jacobians: J_p of the tracked points (zero where the point's
            mask is False), shape (N, P, 3, nv).
        segment_units: u, shape (N, S, 3).
        segment_lengths: l [m], shape (N, S), none zero.
        spatial_jacobian: world joint Jacobians [v; w], shape (N, 6, nv).
        tension: cable tensions f [N], shape (N, m).
        segment_points: A and B of each segment (point indices), shape (S, 2).
        segment_cable: each segment's cable, shape (S,).
        support: True where direction k's joint is (an ancestor of)
            direction j's joint, shape (nv, nv).
        point_mask: True where direction k moves point p, shape (P, nv).

    Returns:
        The stiffness matrices, shape (N, nv, nv).
    """
    out = np.empty((tension.shape[0], support.shape[0], support.shape[1]))
    _stiffness_poses(
        np.asarray(point_jacobians, dtype=np.float64),
        np.asarray(segment_units, dtype=np.float64),
        np.asarray(segment_lengths, dtype=np.float64),
        np.asarray(spatial_jacobian, dtype=np.float64),
        np.asarray(tension, dtype=np.float64),
        np.asarray(segment_points, dtype=np.int64),
        np.asarray(segment_cable, dtype=np.int64),
        np.asarray(support, dtype=np.bool_),
        np.asarray(point_mask, dtype=np.bool_),
        out,
    )
    return out
