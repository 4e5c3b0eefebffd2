"""Least-norm equilibrium tensions of many poses at once (semismooth Newton
on the dual), deciding most poses without a per-pose QP."""

from __future__ import annotations

import numpy as np

from cdpm.numerics import (
    BATCH_NEWTON_STOP_RTOL,
    BATCH_STATICS_RTOL,
    FARKAS_RTOL,
    NEWTON_DAMPING,
    NEWTON_HALVINGS,
    NEWTON_ITERATIONS,
    NEWTON_RIDGE_RTOL,
)

__all__ = ["min_norm_tensions"]


def _dual_value(b, lam, z, lower, upper):
    """Dual objective of min 1/2 |f|^2 s.t. L^T f = b, lower <= f <= upper at
    multipliers lam (..., nv) with z = L lam (..., m): b.lam + sum_i min_f_i
    (f_i^2 / 2 - f_i z_i) over the box."""
    f = np.clip(z, lower, upper)
    return (b * lam).sum(axis=-1) + (0.5 * f * f - f * z).sum(axis=-1)


def min_norm_tensions(
    LT: np.ndarray,
    load: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    iterations: int = NEWTON_ITERATIONS,
):
    """Least-norm tensions ``f`` with ``L^T f = load`` and ``lower <= f <= upper``
    at many poses (the problem of :func:`cdpm.equilibrium.equilibrium_tension`).

    Semismooth Newton ascent on the dual, with a backtracking line search,
    all poses at once: the optimum is ``f = clip(L lam, lower, upper)`` for
    the multipliers lam solving ``L^T clip(L lam) = load`` (KKT), so a pose
    whose statics residual vanishes has the exact optimum (bounds met
    exactly). A pose whose multipliers run off along a direction v proving
    ``v.load > max_{lower <= f <= upper} v.L^T f`` (Farkas) has no
    equilibrium. Poses with neither are left undecided for the per-pose
    solver.

    Args:
        LT: L^T of each pose, shape (k, nv, m).
        load: the generalised force to balance, -G - w_ext, shape (k, nv).
        lower, upper: tension bounds [N], each (m,) (upper may be inf).
        iterations: Newton steps at most.

    Returns:
        (f (k, m), solved (k,), infeasible (k,)): ``solved`` poses have the
        least-norm tension with a statics residual below BATCH_STATICS_RTOL of the
        statics' scale (max(1, |load|, |L| |f|)); ``infeasible`` ones provably have none.
    """
    k, nv, m = LT.shape
    L = np.swapaxes(LT, 1, 2)  # (k, m, nv)
    scale = np.maximum(1.0, np.abs(load).max(axis=1))
    eye = np.eye(nv)
    gram = LT @ L
    ridge = NEWTON_RIDGE_RTOL * np.maximum(np.trace(gram, axis1=1, axis2=2), 1e-300)
    lam = np.linalg.solve(gram + ridge[:, None, None] * eye, load[..., None])[..., 0]
    lam = np.ascontiguousarray(lam)
    steps = 0.5 ** np.arange(NEWTON_HALVINGS)
    trace = np.trace(gram, axis1=1, axis2=2)
    load_norm = np.maximum(np.linalg.norm(load, axis=1), 1.0)
    active = np.arange(k)  # poses still iterating
    for _ in range(iterations):
        La, LTa, lam_a, b = L[active], LT[active], lam[active], load[active]
        z = (La @ lam_a[..., None])[..., 0]
        f = np.clip(z, lower, upper)
        r = (LTa @ f[..., None])[..., 0] - b
        going = np.abs(r).max(axis=1) > BATCH_NEWTON_STOP_RTOL * scale[active]
        if not going.all():
            active, La, LTa, lam_a, b = (x[going] for x in (active, La, LTa, lam_a, b))
            z, f, r = z[going], f[going], r[going]
        if active.size == 0:
            break
        # Levenberg-Marquardt regularised semismooth Newton: gradient-like
        # steps (safe for a dual with gradient Lipschitz |L|^2) far from
        # the solution, Newton steps near it
        free = ((z > lower) & (z < upper)).astype(float)
        mu = (
            NEWTON_DAMPING
            * trace[active]
            * np.minimum(1.0, np.linalg.norm(r, axis=1) / load_norm[active])
        )
        hess = LTa @ (free[..., None] * La) + (mu + ridge[active])[:, None, None] * eye
        step = np.linalg.solve(hess, r[..., None])[..., 0]
        # backtracking: the largest of 1, 1/2, ... that raises the dual
        now = _dual_value(b, lam_a, z, lower, upper)
        trial = lam_a[None] - steps[:, None, None] * step[None]  # (s, k_active, nv)
        zt = np.einsum("kmv,skv->skm", La, trial)
        better = _dual_value(b[None], trial, zt, lower, upper) > now
        first = better.argmax(axis=0)
        new = np.where(better.any(axis=0)[:, None], trial[first, np.arange(active.size)], lam_a)
        lam[active] = new
    # polish: a full Newton step on the final active set (the line search
    # cannot see the last round-off-sized gains of the dual)
    for _ in range(2):
        z = (L @ lam[..., None])[..., 0]
        f = np.clip(z, lower, upper)
        r = (LT @ f[..., None])[..., 0] - load
        free = ((z > lower) & (z < upper)).astype(float)
        hess = LT @ (free[..., None] * L) + ridge[:, None, None] * eye
        polished = lam - np.linalg.solve(hess, r[..., None])[..., 0]
        zp = (L @ polished[..., None])[..., 0]
        rp = (LT @ np.clip(zp, lower, upper)[..., None])[..., 0] - load
        better = np.abs(rp).max(axis=1) < np.abs(r).max(axis=1)
        lam = np.where(better[:, None], polished, lam)
    z = (L @ lam[..., None])[..., 0]
    f = np.clip(z, lower, upper)
    r = (LT @ f[..., None])[..., 0] - load
    f_scale = np.maximum(scale, np.sqrt((LT * LT).sum(axis=(1, 2))) * np.linalg.norm(f, axis=1))
    solved = np.abs(r).max(axis=1) <= BATCH_STATICS_RTOL * f_scale
    # Farkas: a unit v with v.load > max over the box of v.L^T f proves that
    # no tension holds the pose; candidates: the direction the multipliers
    # run off to, and the statics residual's
    infeasible = np.zeros(k, dtype=bool)
    for cand in (lam, -r):
        norm = np.linalg.norm(cand, axis=1)
        v = cand / np.where(norm > 0, norm, 1.0)[:, None]
        w = (L @ v[..., None])[..., 0]  # (k, m)
        with np.errstate(invalid="ignore"):
            reach = np.where(w > 0, upper * w, np.where(w < 0, lower * w, 0.0)).sum(axis=1)
        gap = (load * v).sum(axis=1) - reach
        infeasible |= ~solved & (norm > 0) & (gap > FARKAS_RTOL * scale)
    return f, solved, infeasible
