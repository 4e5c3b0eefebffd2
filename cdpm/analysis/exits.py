"""Vectorised exits of the analysis: tests that decide many systems at
once beyond doubt (the system axis last or first, as each says).

:mod:`cdpm.analysis.batch` runs them on every map chunk and on the batch of
one of :func:`cdpm.analyze_pose`; the per-system analyser shares
:func:`nilpotent_sign`. The threshold tests (nilpotent POC, output rank,
span codes) also return the systems they leave open, within a few round-off
units of their thresholds; the rank exits (:func:`output_controllable`,
:func:`free_controllable`) return NOT_ANALYSED where they are not sure.
"""

from __future__ import annotations

import math

import numpy as np

from cdpm.numerics import (
    ANGULAR_DEFER_BAND,
    KRYLOV_COLUMN_NEGLIGIBLE,
    RANK_DEFICIENT_RATIO,
    RANK_RATIO,
    SPAN_TOL,
    THRESHOLD_DEFER_FRACTION,
    ZERO_RTOL,
)
from cdpm.verdicts import NO, NOT_ANALYSED, YES

__all__ = [
    "nilpotent_sign",
    "times",
    "nilpotent_poc",
    "output_rank_full",
    "span_codes",
    "free_controllable",
    "output_controllable",
    "nilpotent_mechanical",
]


def nilpotent_sign(x0: np.ndarray | None, y1: np.ndarray, axis: int = 1) -> np.ndarray:
    """POC of p = 1 systems with A^2 = 0 and every input sign-constrained.

    ``g_j(t) = x0_j + t x1_j``; a point is positive (negative) when
    ``x0_j`` or ``y1_j = tau x1_j`` exceeds ``ZERO_RTOL`` times the largest
    of them (a late point has the sign of x1_j). POC iff both signs occur.

    Args:
        x0: CB, shape (k, m), or None when CB = 0.
        y1: tau CAB, shape (k, m).
        axis: the input axis (1; 0 for (m, k) arrays, system axis last).

    Returns:
        bool (k,): YES.
    """
    big = np.abs(y1).max(axis=axis, initial=0.0)
    if x0 is not None:
        big = np.maximum(np.abs(x0).max(axis=axis, initial=0.0), big)
    thr = np.expand_dims(ZERO_RTOL * big, axis)
    pos = np.any(y1 > thr, axis=axis)
    neg = np.any(y1 < -thr, axis=axis)
    if x0 is not None:
        pos |= np.any(x0 > thr, axis=axis)
        neg |= np.any(x0 < -thr, axis=axis)
    return pos & neg


# --------------------------------------------------------------------------
# arrays with the system axis last (contiguous element-wise work)


def times(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched product a b of (r, s, k) and (s, t, k) arrays, system axis last."""
    out = a[:, 0, None] * b[0]
    for j in range(1, a.shape[1]):
        out += a[:, j, None] * b[j]
    return out


def _max_angular_gap(S: np.ndarray):
    """Largest angular gap between the nonzero columns of S (2, m, k), as the
    analyser's angular test computes it, and a mask of systems with a column
    near its zero threshold.

    Each system's angles are sorted (the dropped columns last, as +inf): the
    gaps are the steps between neighbours and the step from the last back
    to the first, modulo 2 pi (0 when they are one direction, as -pi and
    pi); a single direction, or copies of one, leaves a gap of 2 pi.
    """
    norms = np.sqrt(S[0] ** 2 + S[1] ** 2)  # (m, k)
    m, k = norms.shape
    big = norms.max(axis=0)
    zero = ZERO_RTOL * big
    keep = norms > zero
    near = np.any(np.abs(norms - zero) <= THRESHOLD_DEFER_FRACTION * zero, axis=0)
    theta = np.where(keep, np.arctan2(S[1], S[0]), np.inf)
    theta.sort(axis=0)
    count = keep.sum(axis=0)
    two_pi = 2 * math.pi
    last = np.take_along_axis(theta, np.maximum(count - 1, 0)[None], axis=0)[0]
    with np.errstate(invalid="ignore"):  # inf - inf: systems without columns
        gap = np.mod(theta[0] - last, two_pi)  # the step back to the first
        if m > 1:
            steps = np.diff(theta, axis=0)  # (m - 1, k); inf, nan past the kept
            between = np.arange(m - 1)[:, None] < (count - 1)[None]
            np.maximum(gap, np.where(between, steps, -np.inf).max(axis=0), out=gap)
    gap[(count == 0) | (gap == 0)] = two_pi
    return gap, near


def _inradius_2d(S: np.ndarray) -> np.ndarray:
    """min_{|v|=1} max_j v.s_j for S (2, m, k) whose columns positively span
    R^2: the minimum of the support function sits at a normal of a pair of
    columns, so evaluating it at every pair's normals is exact."""
    _, m, k = S.shape
    if k == 0:
        return np.zeros(0)
    i, j = np.triu_indices(m, 1)
    d = S[:, j] - S[:, i]  # (2, pairs, k)
    length = np.sqrt(d[0] ** 2 + d[1] ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.array([d[1], -d[0]]) / length
    cand = np.concatenate([normal, -normal], axis=1)  # (2, candidates, k)
    support = (cand[0][:, None] * S[0][None] + cand[1][:, None] * S[1][None]).max(axis=1)
    support = np.where(np.isfinite(support), support, np.inf)
    return np.maximum(support.min(axis=0), 0.0)


def nilpotent_poc(CAB: np.ndarray, tol: float):
    """POC codes, margins and a 'leave open' mask from CAB (p, m, k) of
    nilpotent systems (CB = 0, tau = 1), as the analyser's nilpotent path
    and margin decide them."""
    p, m, k = CAB.shape
    codes = np.full(k, NO, dtype=np.int8)
    margin = np.zeros(k)
    todo = np.zeros(k, dtype=bool)
    if p == 1:
        x = CAB[0]  # (m, k)
        big = np.abs(x).max(axis=0)
        thr = ZERO_RTOL * big
        yes = nilpotent_sign(None, x, axis=0) & (big > 0)
        codes[yes] = YES
        margin[yes] = np.minimum(x.max(axis=0), -x.min(axis=0))[yes]
        # the analyser's CAB differs by round-off (~1e-16 |x|): only values
        # close to the threshold could be decided differently
        todo |= np.any(np.abs(np.abs(x) - thr) <= THRESHOLD_DEFER_FRACTION * thr, axis=0) & (
            big > 0
        )
        return codes, margin, todo
    if p == 2:
        gap, near = _max_angular_gap(CAB)
        yes = gap < math.pi - tol
        codes[yes] = YES
        todo |= near | (np.abs(gap - (math.pi - tol)) <= ANGULAR_DEFER_BAND)
        margin[yes] = _inradius_2d(CAB[..., yes])
        return codes, margin, todo
    todo[:] = True
    return codes, margin, todo


def output_rank_full(CAB: np.ndarray, Cq: np.ndarray, X: np.ndarray):
    """Output controllability codes of nilpotent systems (rank CAB = p, as
    CB = 0) and a 'leave open' mask for nearly rank-deficient ones."""
    p, m, k = CAB.shape
    rows = np.sqrt((CAB**2).sum(axis=1))  # (p, k)
    scale = np.sqrt((Cq**2).sum(axis=1)) * np.sqrt((X**2).sum(axis=(0, 1)))
    rel = rows / np.where(scale > 0, scale, 1.0)
    if p == 1:
        ratio = rel[0]
    elif p == 2:
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = CAB / rows[:, None, :]
        cos = np.abs((unit[0] * unit[1]).sum(axis=0))
        ratio = np.sqrt(np.maximum(1.0 - cos, 0.0) / (1.0 + cos))
        ratio = np.where(np.isfinite(ratio), np.minimum(ratio, rel.min(axis=0)), 0.0)
    else:
        s = np.linalg.svd(
            np.moveaxis(CAB / np.maximum(rows, 1e-300)[:, None], -1, 0), compute_uv=False
        )
        ratio = np.minimum(s[:, -1] / np.maximum(s[:, 0], 1e-300), rel.min(axis=0))
    full = ratio > RANK_RATIO
    defer = ~full & (ratio > RANK_DEFICIENT_RATIO)
    return np.where(full, YES, NO).astype(np.int8), defer


def span_codes(S: np.ndarray, defer: tuple[float, float], tol: float = SPAN_TOL):
    """Do the columns of S (d, m, k) positively span R^d (the analyser's
    angular test)? Returns codes and a mask of systems to leave open: those
    whose angular deficit ``pi - gap`` (d = 2), or smallest nonzero relative
    entry (d = 1), lies in ``defer = (lo, hi)``. d >= 3 is always left open."""
    d, m, k = S.shape
    codes = np.full(k, NO, dtype=np.int8)
    todo = np.zeros(k, dtype=bool)
    lo, hi = defer
    if d == 1:
        x = S[0]  # (m, k)
        scale = np.abs(x).max(axis=0)
        yes = np.any(x > tol * scale, axis=0) & np.any(x < -tol * scale, axis=0)
        codes[yes] = YES
        rel = np.abs(x) / np.where(scale > 0, scale, 1.0)
        todo |= np.any((rel > 0) & (rel >= lo) & (rel <= hi), axis=0)
    elif d == 2:
        gap, near = _max_angular_gap(S)
        codes[gap < math.pi - tol] = YES
        deficit = math.pi - gap
        todo |= near | ((deficit >= lo) & (deficit <= hi))
    else:
        todo[:] = True
    return codes, todo


# --------------------------------------------------------------------------
# general systems, system axis first


def _full_rank(S: np.ndarray) -> np.ndarray:
    """Rows of each (r, c) matrix of S (k, r, c) independent beyond doubt:
    columns scaled to unit length (negligible ones dropped), singular-value
    ratio above RANK_RATIO. The definition of the exits' rank test: the
    compiled test (cdpm.analysis.rank_kernel) decides by it where
    round-off cannot change the answer and sends the rest here."""
    norms = np.sqrt(np.einsum("krc,krc->kc", S, S))
    keep = norms > KRYLOV_COLUMN_NEGLIGIBLE * norms.max(axis=1, keepdims=True)
    S = np.where(keep[:, None, :], S / np.where(keep, norms, 1.0)[:, None, :], 0.0)
    r = S.shape[1]
    if r == 0 or S.shape[2] < r:
        return np.zeros(S.shape[0], dtype=bool) if r else np.ones(S.shape[0], dtype=bool)
    sv = np.linalg.svd(S, compute_uv=False)
    return sv[:, -1] > RANK_RATIO * sv[:, 0]


def free_controllable(A, B, mask):
    """YES where the free (taut) inputs alone make (A, B) controllable beyond
    doubt, else NOT_ANALYSED. Then no real left eigenvector v of A has
    v^T B_free = 0, so Brammer's obstruction cannot exist.

    The rank test of the Krylov matrix [B_free, A B_free, ...] is compiled
    (cdpm.analysis.rank_kernel); the few matrices it leaves undecided get
    :func:`_full_rank`."""
    k, n, _ = A.shape
    codes = np.full(k, NOT_ANALYSED, dtype=np.int8)
    free = np.flatnonzero(np.any(~mask & np.any(B != 0, axis=1), axis=1))
    if free.size == 0:  # every input sign-constrained (or zero): no free input
        return codes
    from cdpm.analysis.rank_kernel import krylov_matrices, krylov_rank_codes  # numba

    full = krylov_rank_codes(A, B, ~mask, None, free)
    open_ = np.flatnonzero(full < 0)
    if open_.size:
        full[open_] = _full_rank(krylov_matrices(A, B, ~mask, None, free[open_]))
    codes[free[full == 1]] = YES
    return codes


def output_controllable(A, B, C):
    """YES where rank [CB, CAB, ..., CA^{n-1}B] = p beyond doubt, else
    NOT_ANALYSED. With B restricted to the free inputs this is the
    analyser's mixed-cone exit: those inputs alone reach every output
    direction, so POC holds.

    The rank test is compiled (cdpm.analysis.rank_kernel); the few
    matrices it leaves undecided get :func:`_full_rank`."""
    k, p, n = C.shape
    codes = np.full(k, NOT_ANALYSED, dtype=np.int8)
    if p == 0 or k == 0:
        codes[:] = YES
        return codes
    from cdpm.analysis.rank_kernel import krylov_matrices, krylov_rank_codes  # numba

    every = np.ones((k, B.shape[2]), dtype=bool)
    full = krylov_rank_codes(A, B, every, C, np.arange(k))
    open_ = np.flatnonzero(full < 0)
    if open_.size:
        full[open_] = _full_rank(krylov_matrices(A, B, every, C, open_))
    codes[full == 1] = YES
    return codes


def nilpotent_mechanical(A, B, C, mask) -> np.ndarray:
    """Systems of the nilpotent exit: A = [[0, I], [0, 0]], B = [0; Bv],
    C = [Cq, 0] exactly, every input sign-constrained; bool (k,)."""
    k, n, _ = A.shape
    if n % 2 or n == 0:
        return np.zeros(k, dtype=bool)
    nv = n // 2
    pattern = np.zeros((n, n))
    pattern[:nv, nv:] = np.eye(nv)
    return (
        np.all(A == pattern, axis=(1, 2))
        & ~np.any(B[:, :nv], axis=(1, 2))
        & ~np.any(C[:, :, nv:], axis=(1, 2))
        & np.all(mask, axis=1)
    )
