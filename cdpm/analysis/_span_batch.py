"""Compiled wrench-closure certificates of many vector sets (numba, cached
on disk).

Imported lazily by :func:`cdpm.analysis.batch.positively_spanning`, so that
``import cdpm`` does not load numba.

The columns of S (d, m), scaled to unit length (U), positively span R^d iff
rank U = d and the null space of U holds a strictly positive vector w. Each
set gets a code from a certificate that is deep enough for the per-pose
analyser (:func:`cdpm.analysis.span.span_result`: one NNLS, an LP fallback,
each with its own tolerances) to reach the same verdict:

- YES: w = N x with N an orthonormal null basis (Householder QR of U^T) and
  x the min-norm point of the hull of N's rows (Wolfe's algorithm): every
  entry of w at least ``depth |w|``, U's condition number at most
  ``cond_max`` and ``|U w|`` within round-off of 0;
- NO, m <= 2d: the analyser's own NNLS, min |U mu + U 1| over mu >= 0 (its
  basis is then every column); its residual, the distance from -U 1 to
  cone(U), is unique whatever the solver, so a residual of at least
  ``depth max(1, |U 1|)`` (the analyser's YES threshold is 1e4 times
  smaller) whose separator passes the analyser's check by a factor 2 is NO;
- NO, m > 2d (the analyser's basis is then p QR pivots): a strict
  separator, the min-norm point x of the hull of U's columns with
  ``u_i . x >= depth |x|`` for every column.

Sets with no such certificate (near the boundary, nearly rank deficient, a
column near zero, a degenerate iteration) are left open, for the analyser.
"""

from __future__ import annotations

import math

import numpy as np

from cdpm.jit import kernel
from cdpm.jit.dense import back_substitute, solve_in_place

__all__ = ["span_certificates"]

#: codes of :func:`span_certificates`
OPEN, NO, YES = -1, 0, 1

#: Wolfe iterations (added points) before a hull is left open
_MAX_ITER = 64


@kernel
def _deep_separator(P, depth, x):  # pragma: no cover - compiled
    """Is 0 at least ``depth`` away from the convex hull of the columns of P
    (dim, n), with a proof? Wolfe's min-norm-point algorithm; True when it
    meets an x with ``p_i . x >= depth |x|`` for every column (x is then
    left in ``x``, (dim,)), False when the hull comes closer than ``depth``
    or the iteration degenerates."""
    dim, n = P.shape
    if n == 0:
        return False
    size = dim + 2
    corral = np.empty(size, dtype=np.int64)
    lam = np.empty(size)
    alpha = np.empty(size + 1)
    M = np.empty((size + 1, size + 1))
    first, least, scale = 0, np.inf, 0.0
    for i in range(n):
        s = 0.0
        for a in range(dim):
            s += P[a, i] * P[a, i]
        if s < least:
            first, least = i, s
        scale = max(scale, s)
    count = 1
    corral[0], lam[0] = first, 1.0
    for a in range(dim):
        x[a] = P[a, first]
    for _ in range(_MAX_ITER):
        xx = 0.0
        for a in range(dim):
            xx += x[a] * x[a]
        nx = math.sqrt(xx)
        if nx < depth:
            return False
        gmin, j = np.inf, -1
        for i in range(n):
            s = 0.0
            for a in range(dim):
                s += P[a, i] * x[a]
            if s < gmin:
                gmin, j = s, i
        if gmin >= depth * nx:
            return True
        # x is the min-norm point (to round-off), yet not deep enough
        if gmin >= xx - 1e-13 * scale or count == size:
            return False
        for c in range(count):
            if corral[c] == j:
                return False
        corral[count], lam[count] = j, 0.0
        count += 1
        # minor cycles: the affine min-norm point of the corral, stepping
        # back into the hull (dropping points) while it leaves the simplex
        while True:
            q = count
            for r in range(q):
                for c in range(r, q):
                    s = 0.0
                    for a in range(dim):
                        s += P[a, corral[r]] * P[a, corral[c]]
                    M[r, c] = s
                    M[c, r] = s
                M[r, q] = 1.0
                M[q, r] = 1.0
                alpha[r] = 0.0
            M[q, q] = 0.0
            alpha[q] = 1.0
            if not solve_in_place(M, alpha, q + 1):
                return False
            inside = True
            for r in range(q):
                if not alpha[r] > 0.0:
                    inside = False
            if inside:
                for r in range(q):
                    lam[r] = alpha[r]
                break
            theta, block = 1.0, -1
            for r in range(q):
                if not alpha[r] > 0.0 and lam[r] / (lam[r] - alpha[r]) < theta:
                    theta, block = lam[r] / (lam[r] - alpha[r]), r
            keep = 0
            for r in range(q):
                value = theta * alpha[r] + (1.0 - theta) * lam[r]
                if r != block and value > 0.0:
                    corral[keep], lam[keep] = corral[r], value
                    keep += 1
            if keep == 0:
                return False
            count = keep
        for a in range(dim):
            s = 0.0
            for r in range(count):
                s += lam[r] * P[a, corral[r]]
            x[a] = s
    return False


@kernel
def _least_squares(U, cols, q, b, z):  # pragma: no cover - compiled
    """z (q,) minimising |U[:, cols[:q]] z - b| (Householder QR); False
    when a column is numerically dependent on the previous ones."""
    d = U.shape[0]
    M = np.empty((d, q))
    for c in range(q):
        for a in range(d):
            M[a, c] = U[a, cols[c]]
    y = b.copy()
    for j in range(q):
        s = 0.0
        for i in range(j, d):
            s += M[i, j] * M[i, j]
        alpha = math.sqrt(s)
        if not alpha > 1e-12:  # unit columns: dependent
            return False
        if M[j, j] > 0:
            alpha = -alpha
        M[j, j] -= alpha
        beta = 0.0
        for i in range(j, d):
            beta += M[i, j] * M[i, j]
        for c in range(j + 1, q):
            t = 0.0
            for i in range(j, d):
                t += M[i, j] * M[i, c]
            f = 2.0 * t / beta
            for i in range(j, d):
                M[i, c] -= f * M[i, j]
        t = 0.0
        for i in range(j, d):
            t += M[i, j] * y[i]
        f = 2.0 * t / beta
        for i in range(j, d):
            y[i] -= f * M[i, j]
        M[j, j] = alpha
    back_substitute(M, y, z, q)
    return True


@kernel
def _nnls_residual(U, b, r):  # pragma: no cover - compiled
    """Lawson-Hanson NNLS, min |U mu - b| over mu >= 0 (U (d, m) unit
    columns). Returns |U mu - b| and leaves ``U mu - b`` in r (d,); -1
    when the iteration degenerates."""
    d, m = U.shape
    mu = np.zeros(m)
    passive = np.zeros(m, dtype=np.bool_)
    cols = np.empty(m, dtype=np.int64)
    z = np.empty(m)
    stop = 1e-13 * max(1.0, math.sqrt(np.sum(b * b)))
    for _ in range(3 * m + 3):
        for a in range(d):
            s = -b[a]
            for i in range(m):
                s += U[a, i] * mu[i]
            r[a] = s
        enter, best = -1, stop
        for i in range(m):
            if not passive[i]:
                s = 0.0
                for a in range(d):
                    s -= U[a, i] * r[a]
                if s > best:
                    enter, best = i, s
        if enter < 0:
            return math.sqrt(np.sum(r * r))
        passive[enter] = True
        for _inner in range(m + 1):
            q = 0
            for i in range(m):
                if passive[i]:
                    cols[q] = i
                    q += 1
            if q > d or not _least_squares(U, cols, q, b, z):
                return -1.0
            feasible = True
            for c in range(q):
                if not z[c] > 0.0:
                    feasible = False
            if feasible:
                for c in range(q):
                    mu[cols[c]] = z[c]
                break
            theta, block = 1.0, -1
            for c in range(q):
                i = cols[c]
                if not z[c] > 0.0 and mu[i] / (mu[i] - z[c]) < theta:
                    theta, block = mu[i] / (mu[i] - z[c]), i
            for c in range(q):
                i = cols[c]
                mu[i] += theta * (z[c] - mu[i])
                if i == block or not mu[i] > 0.0:
                    mu[i] = 0.0
                    passive[i] = False
    return -1.0


@kernel
def _null_basis(U, cond_max, N):  # pragma: no cover - compiled
    """An orthonormal basis of the null space of U (d, m), m > d, in N
    (m, m - d), from a Householder QR of U^T; False (N unset) unless U has
    rank d with ``|R|_F |R^-1|_F <= cond_max`` (a bound of its condition
    number). Returns (ok, a lower bound of U's least singular value)."""
    d, m = U.shape
    A = U.T.copy()
    V = np.zeros((m, d))
    for j in range(d):
        s = 0.0
        for i in range(j, m):
            s += A[i, j] * A[i, j]
        alpha = math.sqrt(s)
        if alpha == 0.0:
            return False, 0.0
        if A[j, j] > 0:
            alpha = -alpha
        for i in range(j, m):
            V[i, j] = A[i, j]
        V[j, j] -= alpha
        beta = 0.0
        for i in range(j, m):
            beta += V[i, j] * V[i, j]
        for c in range(j, d):
            s = 0.0
            for i in range(j, m):
                s += V[i, j] * A[i, c]
            f = 2.0 * s / beta
            for i in range(j, m):
                A[i, c] -= f * V[i, j]
        root = math.sqrt(beta)
        for i in range(j, m):
            V[i, j] /= root
    Rinv = np.zeros((d, d))
    for c in range(d):
        if A[c, c] == 0.0:
            return False, 0.0
        Rinv[c, c] = 1.0 / A[c, c]
        for r in range(c - 1, -1, -1):
            s = 0.0
            for t in range(r + 1, c + 1):
                s += A[r, t] * Rinv[t, c]
            Rinv[r, c] = -s / A[r, r]
    fr, fi = 0.0, 0.0
    for r in range(d):
        for c in range(r, d):
            fr += A[r, c] * A[r, c]
            fi += Rinv[r, c] * Rinv[r, c]
    sigma_min = 1.0 / math.sqrt(fi)
    if not math.sqrt(fr) <= cond_max * sigma_min:
        return False, sigma_min
    # N = H_0 ... H_{d-1} [0; I]
    N[:, :] = 0.0
    for c in range(m - d):
        N[d + c, c] = 1.0
    for j in range(d - 1, -1, -1):
        for c in range(m - d):
            s = 0.0
            for i in range(j, m):
                s += V[i, j] * N[i, c]
            s *= 2.0
            for i in range(j, m):
                N[i, c] -= s * V[i, j]
    return True, sigma_min


@kernel
def _decide(S, depth, cond_max, tol):  # pragma: no cover - compiled
    """The code of one set S (d, m): YES, NO or OPEN (module docstring)."""
    d, m = S.shape
    norms = np.empty(m)
    big = 0.0
    for i in range(m):
        s = 0.0
        for a in range(d):
            s += S[a, i] * S[a, i]
        norms[i] = math.sqrt(s)
        big = max(big, norms[i])
    if not big > 0.0:
        return OPEN
    for i in range(m):
        # a column near zero: the analyser drops it (or not) at its own threshold
        if not norms[i] > big / cond_max:
            return OPEN
    U = np.empty((d, m))
    for a in range(d):
        for i in range(m):
            U[a, i] = S[a, i] / norms[i]
    if m > d:
        N = np.empty((m, m - d))
        full, sigma_min = _null_basis(U, cond_max, N)
        y = np.empty(m - d)
        if full and _deep_separator(N.T.copy(), depth, y):
            w = N @ y
            nw = math.sqrt(np.sum(w * w))
            res = U @ w
            # the null vector of U nearest w is within |U w| / sigma_min of it
            if np.min(w) >= depth * nw and math.sqrt(np.sum(res * res)) <= (
                0.5 * depth * nw * sigma_min
            ):
                return YES
    if m <= 2 * d:
        b = np.zeros(d)
        for a in range(d):
            for i in range(m):
                b[a] -= U[a, i]
        r = np.empty(d)
        dist = _nnls_residual(U, b, r)
        if dist >= depth * max(1.0, math.sqrt(np.sum(b * b))):
            # the analyser's separator -r / |r| must pass v.u_i <= tol
            if np.max(-(U.T @ r)) / dist <= 0.5 * tol:
                return NO
        return OPEN
    x = np.empty(d)
    if _deep_separator(U, depth, x):
        return NO
    return OPEN


@kernel
def _decide_all(S, depth, cond_max, tol):  # pragma: no cover - compiled
    k = S.shape[0]
    codes = np.empty(k, dtype=np.int8)
    for p in range(k):
        codes[p] = _decide(S[p], depth, cond_max, tol)
    return codes


def span_certificates(vectors: np.ndarray, depth: float, cond_max: float, tol: float) -> np.ndarray:
    """Codes of many vector sets from deep certificates (module docstring).

    Args:
        vectors: (k, d, m), d >= 1; the columns of each (d, m) matrix.
        depth: least relative depth of a certificate, in (0, 1).
        cond_max: largest condition number (a Frobenius bound) of the
            unit-column matrix of a YES; columns shorter than the longest
            over this are left open.
        tol: the analyser's angle-like tolerance (its separator check).

    Returns:
        int8 (k,): 1 (the columns positively span R^d), 0 (they do not) or
        -1 (open: no deep certificate).
    """
    S = np.ascontiguousarray(vectors, dtype=float)
    return _decide_all(S, float(depth), float(cond_max), float(tol))
