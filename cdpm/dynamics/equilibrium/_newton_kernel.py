"""Compiled kernel of :func:`cdpm.dynamics.equilibrium.newton.min_norm_tensions`: the
semismooth Newton method on the dual of the least-norm tension QP, one pose
after another (numba; compiled once, cached on disk).

The matrices are tiny (nv <= 6 rows, m <= a dozen cables), so a loop over
poses with scratch arrays allocated once costs a few microseconds a pose,
where whole-batch numpy pays its per-call overhead fifty times over.
"""

from __future__ import annotations

import math

import numpy as np

from cdpm.jit import kernel
from cdpm.jit.dense import solve_in_place

__all__ = ["solve_poses"]


@kernel
def _solve(a, x, n):
    """Solve a y = x in place (x (n,) becomes y; a is destroyed); an exactly
    singular a gives NaN, which the callers' comparisons reject."""
    if not solve_in_place(a, x, n):
        x[:n] = np.nan


@kernel
def _tensions(LT, lam, lower, upper, z, f):
    """z = L lam and f = clip(z, lower, upper), each (m,), for one pose's
    L^T (nv, m) and multipliers lam (nv,)."""
    nv, m = LT.shape
    for j in range(m):
        s = 0.0
        for a in range(nv):
            s += LT[a, j] * lam[a]
        z[j] = s
        v = s
        if v < lower[j]:
            v = lower[j]
        if v > upper[j]:
            v = upper[j]
        f[j] = v


@kernel
def _residual(LT, f, load, r):
    """r = L^T f - load (nv,); returns max |r| (nan when r has a nan)."""
    nv, m = LT.shape
    largest = 0.0
    for a in range(nv):
        s = 0.0
        for j in range(m):
            s += LT[a, j] * f[j]
        s -= load[a]
        r[a] = s
        largest = max(largest, abs(s))
    for a in range(nv):
        if math.isnan(r[a]):
            return math.nan
    return largest


@kernel
def _dual_value(load, lam, z, f):
    """Dual objective of min 1/2 |f|^2 s.t. L^T f = load, lower <= f <= upper
    at multipliers lam (nv,), with z = L lam and f = clip(z) (m,):
    load.lam + sum_j (f_j^2 / 2 - f_j z_j)."""
    s = 0.0
    for a in range(lam.shape[0]):
        s += load[a] * lam[a]
    t = 0.0
    for j in range(z.shape[0]):
        t += 0.5 * f[j] * f[j] - f[j] * z[j]
    return s + t


@kernel
def _newton_matrix(LT, z, lower, upper, all_free, diagonal, free, hess):
    """hess = L^T diag(free) L + diagonal I (nv, nv), cable j free when
    lower_j < z_j < upper_j (or every cable when all_free): the generalised
    Hessian of the dual's negative (plus a ridge). free: scratch (m,) ints."""
    nv, m = LT.shape
    n_free = 0
    for j in range(m):
        if all_free or lower[j] < z[j] < upper[j]:
            free[n_free] = j
            n_free += 1
    for a in range(nv):
        for c in range(a + 1):
            s = 0.0
            for q in range(n_free):
                s += LT[a, free[q]] * LT[c, free[q]]
            hess[a, c] = s
            hess[c, a] = s
        hess[a, a] += diagonal


@kernel
def _farkas_gap(LT, load, lower, upper, cand, sign):
    """v.load - max_{lower <= f <= upper} v.L^T f for v = sign cand / |cand|
    (nv,), or -inf when cand = 0 (no direction)."""
    nv, m = LT.shape
    norm = 0.0
    for a in range(nv):
        norm += cand[a] * cand[a]
    norm = math.sqrt(norm)
    if not norm > 0.0:
        return -math.inf
    gap = 0.0
    for a in range(nv):
        gap += load[a] * sign * cand[a] / norm
    reach = 0.0
    for j in range(m):
        w = 0.0
        for a in range(nv):
            w += LT[a, j] * sign * cand[a] / norm
        if w > 0.0:
            reach += upper[j] * w
        elif w < 0.0:
            reach += lower[j] * w
    return gap - reach


@kernel
def _solved(largest, statics_rtol, scale, trace, f):
    """The statics residual ``largest`` is below statics_rtol of the
    statics' scale, max(scale, |L| |f|) (|L|^2 = trace)."""
    f_sq = 0.0
    for j in range(f.shape[0]):
        f_sq += f[j] * f[j]
    return largest <= statics_rtol * max(scale, math.sqrt(trace) * math.sqrt(f_sq))


@kernel
def _farkas(LT, load, lower, upper, lam, r, threshold):
    """Farkas: a unit v with v.load > max over the box of v.L^T f (by more
    than ``threshold``) proves that no tension holds the pose; candidates:
    the direction the multipliers run off to, and the statics residual's."""
    return (
        _farkas_gap(LT, load, lower, upper, lam, 1.0) > threshold
        or _farkas_gap(LT, load, lower, upper, r, -1.0) > threshold
    )


@kernel
def solve_poses(
    LT,
    load,
    lower,
    upper,
    iterations,
    halvings,
    damping,
    ridge_rtol,
    stop_rtol,
    statics_rtol,
    farkas_rtol,
    force,
    f_out,
    solved_out,
    infeasible_out,
):
    """The least-norm tensions of every pose, written into f_out (k, m),
    solved_out (k,) and infeasible_out (k,) (the contract of
    :func:`cdpm.dynamics.equilibrium.newton.min_norm_tensions`).

    Args:
        LT: L^T of each pose, shape (k, nv, m), C-contiguous.
        load: the generalised force to balance, shape (k, nv).
        lower, upper: tension bounds [N], each (m,) (upper may be inf).
        iterations, halvings: Newton steps at most and halvings of the
            backtracking line search.
        damping, ridge_rtol: Levenberg-Marquardt damping and ridge, relative
            to trace(L^T L).
        stop_rtol: Newton stops below this residual relative to the pose's
            force scale, max(|load|, |L|_F force).
        statics_rtol: residual, relative to the statics' scale, of a solved pose.
        farkas_rtol: Farkas gap, relative to the pose's force scale, proving
            infeasibility.
        force: the robot's force scale [N]: no absolute newton enters a
            decision (:attr:`cdpm.model.robot.CableRobot.force_scale`).
    """
    k, nv, m = LT.shape
    lam = np.empty(nv)
    trial = np.empty(nv)
    step = np.empty(nv)
    r = np.empty(nv)
    rp = np.empty(nv)
    z = np.empty(m)
    f = np.empty(m)
    zt = np.empty(m)
    ft = np.empty(m)
    hess = np.empty((nv, nv))
    free = np.empty(m, dtype=np.int64)
    for i in range(k):
        A = LT[i]
        b = load[i]
        trace = 0.0
        for a in range(nv):
            for j in range(m):
                trace += A[a, j] * A[a, j]
        # the pose's force scale: the load, or what the robot's force scale
        # exerts through L^T (a bound on it: |L|_F >= |L|_2)
        scale = math.sqrt(trace) * force
        load_sq = 0.0
        for a in range(nv):
            scale = max(scale, abs(b[a]))
            load_sq += b[a] * b[a]
        load_norm = max(math.sqrt(load_sq), scale, 1e-300)
        ridge = ridge_rtol * max(trace, 1e-300)
        # start: the least-norm multipliers of the unbounded problem
        for a in range(nv):
            lam[a] = b[a]
        _newton_matrix(A, z, lower, upper, True, ridge, free, hess)
        _solve(hess, lam, nv)
        # z = L lam, f = clip(z) and r = L^T f - load follow lam throughout
        _tensions(A, lam, lower, upper, z, f)
        largest = _residual(A, f, b, r)
        proven = False
        for _ in range(iterations):
            if not largest > stop_rtol * scale:
                break
            # Levenberg-Marquardt regularised semismooth Newton: gradient-like
            # steps (safe for a dual with gradient Lipschitz |L|^2) far from
            # the solution, Newton steps near it
            r_norm = 0.0
            for a in range(nv):
                r_norm += r[a] * r[a]
            mu = damping * trace * min(1.0, math.sqrt(r_norm) / load_norm)
            _newton_matrix(A, z, lower, upper, False, mu + ridge, free, hess)
            step[:] = r
            _solve(hess, step, nv)
            # backtracking: the largest of 1, 1/2, ... that raises the dual
            now = _dual_value(b, lam, z, f)
            t = 1.0
            for _ in range(halvings):
                for a in range(nv):
                    trial[a] = lam[a] - t * step[a]
                _tensions(A, trial, lower, upper, zt, ft)
                if _dual_value(b, trial, zt, ft) > now:
                    lam[:] = trial
                    z[:] = zt
                    f[:] = ft
                    largest = _residual(A, f, b, r)
                    break
                t *= 0.5
            # an unsolved iterate that proves no tension holds the pose (the
            # Farkas test below): further steps only run the multipliers off
            if not _solved(largest, statics_rtol, scale, trace, f) and (
                _farkas(A, b, lower, upper, lam, r, farkas_rtol * scale)
            ):
                proven = True
                break
        # polish: a full Newton step on the final active set (the line search
        # cannot see the last round-off-sized gains of the dual)
        for _ in range(0 if proven else 2):
            _newton_matrix(A, z, lower, upper, False, ridge, free, hess)
            step[:] = r
            _solve(hess, step, nv)
            for a in range(nv):
                trial[a] = lam[a] - step[a]
            _tensions(A, trial, lower, upper, zt, ft)
            polished = _residual(A, ft, b, rp)
            if polished < largest:
                lam[:] = trial
                z[:] = zt
                f[:] = ft
                r[:] = rp
                largest = polished
        for j in range(m):
            f_out[i, j] = f[j]
        solved = _solved(largest, statics_rtol, scale, trace, f)
        solved_out[i] = solved
        infeasible_out[i] = not solved and (
            proven or _farkas(A, b, lower, upper, lam, r, farkas_rtol * scale)
        )
