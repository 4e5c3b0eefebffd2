"""Compiled Krylov rank test of the batched exits (numba, cached on disk).

Imported lazily by :func:`cdpm.analysis.exits.free_controllable` and
:func:`cdpm.analysis.exits.output_controllable`, so that ``import cdpm``
does not load numba. For each system it builds the Krylov matrix
``K = [C W, C A W, ..., C A^{n-1} W]`` (r, n m) column by column (``C = I``
when there is no output map; W the inputs in use), scales its columns to
unit length (those shorter than KRYLOV_COLUMN_NEGLIGIBLE times the longest
dropped, as :func:`cdpm.analysis.exits._full_rank` does) and accumulates the
Gram matrix ``G = K K^T`` of the scaled columns, whose eigenvalues are the
squared singular values. The rank test is
``lambda_min(G) > RANK_RATIO^2 lambda_max(G)``; it is decided here only
beyond doubt, by Cholesky factorisations (their success or failure is the
sign of the smallest eigenvalue of the shifted matrix):

- ``lambda_max`` is bracketed in [lo, hi]: lo a Rayleigh quotient (a few
  power steps), hi the least of the trace and Gershgorin's bound, narrowed
  by bisection with factorisations of ``mu I - G``;
- full rank when ``G - (t hi + band) I`` factorises (t = RANK_RATIO^2),
  deficient when ``G - (t lo - band) I`` does not, with
  ``band = 4 (r^2 + r) eps hi`` the round-off allowance of the Gram matrix
  and its eigenvalues.

The systems it cannot decide so (the smallest eigenvalue within about the
band of the threshold, or lambda_max not bracketed within BRACKET_RTOL) are
returned undecided; :func:`krylov_matrices` builds their matrices for the
exact test.
"""

from __future__ import annotations

import math

import numpy as np

from cdpm.jit import kernel
from cdpm.numerics import KRYLOV_COLUMN_NEGLIGIBLE, RANK_RATIO

EPS = float(np.finfo(np.float64).eps)

#: lambda_max is bracketed to this relative width before a system near the
#: threshold is left undecided (a cost knob: it never changes a decision)
BRACKET_RTOL = 0.01

__all__ = ["krylov_rank_codes", "krylov_matrices"]


@kernel
def _krylov_rows(A, B, use, C, s, project, W, R, Rn, K):  # pragma: no cover - compiled
    """System s's Krylov matrix into the leading columns of K (r, n m);
    returns how many columns (inputs not in use and zero inputs give none:
    their columns are zero, which the scaling drops). Sums run in the order
    of the plain products ``A @ W`` and ``C @ W``."""
    n = A.shape[1]
    m = B.shape[2]
    r = K.shape[0]
    nw = 0
    for j in range(m):
        if use[s, j]:
            nonzero = False
            for a in range(n):
                W[a, nw] = B[s, a, j]
                nonzero |= B[s, a, j] != 0.0
            if nonzero:
                nw += 1
    if not project:  # blocks A^i W, each from the one before (in R, Rn)
        for i in range(n):
            if i > 0:
                Rn[:, :nw] = 0.0
                for b in range(n):
                    w = W[b]  # rows as 1-d views: the inner loops vectorise
                    for a in range(n):
                        x = A[s, a, b]
                        row = Rn[a]
                        for c in range(nw):
                            row[c] += x * w[c]
                W, Rn = Rn, W
            for a in range(n):
                for c in range(nw):
                    K[a, i * nw + c] = W[a, c]
        return n * nw
    for q in range(r):  # blocks (C A^i) W, with R = C A^i
        for b in range(n):
            R[q, b] = C[s, q, b]
    for i in range(n):
        for q in range(r):
            for c in range(nw):
                K[q, i * nw + c] = 0.0
        for b in range(n):
            w = W[b]
            for q in range(r):
                x = R[q, b]
                row = K[q, i * nw : (i + 1) * nw]
                for c in range(nw):
                    row[c] += x * w[c]
        if i + 1 < n:
            Rn[:, :] = 0.0
            for b in range(n):
                ab = A[s, b]
                for q in range(r):
                    x = R[q, b]
                    row = Rn[q]
                    for a in range(n):
                        row[a] += x * ab[a]
            R, Rn = Rn, R
    return n * nw


@kernel(fastmath={"reassoc", "contract"})
def _gram(K, nc, G):  # pragma: no cover - compiled
    """G = K K^T of the leading nc columns of K (r, .); the sums in any
    order (round-off within the band)."""
    r = K.shape[0]
    for a in range(r):
        ka = K[a]
        for b in range(a, r):
            kb = K[b]
            x = 0.0
            for c in range(nc):
                x += ka[c] * kb[c]
            G[a, b] = x
            G[b, a] = x


@kernel
def _factorises(G, r, sign, shift, L):  # pragma: no cover - compiled
    """Does the Cholesky factorisation of ``sign G - shift I`` (r x r)
    complete with positive pivots?"""
    for j in range(r):
        d = sign * G[j, j] - shift
        for q in range(j):
            d -= L[j, q] * L[j, q]
        if not d > 0.0:
            return False
        ljj = math.sqrt(d)
        L[j, j] = ljj
        for i in range(j + 1, r):
            x = sign * G[i, j]
            for q in range(j):
                x -= L[i, q] * L[j, q]
            L[i, j] = x / ljj
    return True


@kernel
def _decide(G, r, L, v, w):  # pragma: no cover - compiled
    """1: lambda_min(G) > t lambda_max(G) beyond doubt, 0: below it beyond
    doubt, -1: undecided (module docstring)."""
    t = RANK_RATIO * RANK_RATIO
    rel = 4.0 * (r * r + r) * EPS
    trace = 0.0
    top_diag = 0.0
    gersh = 0.0
    imax = 0
    for a in range(r):
        trace += G[a, a]
        if G[a, a] > top_diag:
            top_diag, imax = G[a, a], a
        row = 0.0
        for b in range(r):
            row += abs(G[a, b])
        gersh = max(gersh, row)
    if not trace > 0.0:
        return 0
    # a Rayleigh quotient after a few power steps from the largest diagonal
    for a in range(r):
        v[a] = G[a, imax]
    rayleigh = 0.0
    for _ in range(3):
        vv = 0.0
        vw = 0.0
        for a in range(r):
            x = 0.0
            for b in range(r):
                x += G[a, b] * v[b]
            w[a] = x
            vv += v[a] * v[a]
            vw += v[a] * x
        if not vv > 0.0:
            break
        rayleigh = max(rayleigh, vw / vv)
        scale = 1.0 / math.sqrt(vv)
        for a in range(r):
            v[a] = w[a] * scale
    lo = max(rayleigh, top_diag, trace / r) * (1.0 - rel)
    hi = min(trace, gersh) * (1.0 + rel)
    test_full = True
    test_deficient = True
    for step in range(64):
        band = rel * hi
        if test_full and _factorises(G, r, 1.0, t * hi + band, L):
            return 1
        shift = t * lo - band
        if test_deficient and shift > 0.0 and not _factorises(G, r, 1.0, shift, L):
            return 0
        if hi <= lo * (1.0 + BRACKET_RTOL):
            return -1
        mu = lo * (1.0 + 0.5 * BRACKET_RTOL) if step == 0 else math.sqrt(lo * hi)
        if _factorises(G, r, -1.0, -mu, L):  # mu I - G positive definite
            hi = min(hi, mu * (1.0 + rel))
            test_full, test_deficient = True, False
        else:
            lo = max(lo, mu * (1.0 - rel))
            test_full, test_deficient = False, True
    return -1


@kernel
def _codes(A, B, use, C, idx, project):  # pragma: no cover - compiled
    n = A.shape[1]
    m = B.shape[2]
    r = C.shape[1] if project else n
    codes = np.empty(idx.size, dtype=np.int8)
    if r == 0 or n * m < r:
        codes[:] = 1 if r == 0 else 0
        return codes
    W = np.empty((n, m))
    R = np.empty((max(r, n), max(n, m)))
    Rn = np.empty((max(r, n), max(n, m)))
    K = np.empty((r, n * m))
    norms = np.empty(n * m)
    G = np.empty((r, r))
    L = np.empty((r, r))
    v = np.empty(r)
    w = np.empty(r)
    for i in range(idx.size):
        nc = _krylov_rows(A, B, use, C, idx[i], project, W, R, Rn, K)
        norms[:nc] = 0.0
        for a in range(r):
            for c in range(nc):
                norms[c] += K[a, c] * K[a, c]
        big = 0.0
        for c in range(nc):
            norms[c] = math.sqrt(norms[c])
            big = max(big, norms[c])
        for c in range(nc):  # 1 / length of the columns kept, 0 for the others
            norms[c] = 1.0 / norms[c] if norms[c] > KRYLOV_COLUMN_NEGLIGIBLE * big else 0.0
        for a in range(r):
            for c in range(nc):
                K[a, c] *= norms[c]
        _gram(K, nc, G)
        codes[i] = _decide(G, r, L, v, w)
    return codes


@kernel
def _matrices(A, B, use, C, idx, project):  # pragma: no cover - compiled
    n = A.shape[1]
    m = B.shape[2]
    r = C.shape[1] if project else n
    out = np.zeros((idx.size, r, n * m))
    W = np.empty((n, m))
    R = np.empty((max(r, n), max(n, m)))
    Rn = np.empty((max(r, n), max(n, m)))
    K = np.empty((r, n * m))
    for i in range(idx.size):
        nc = _krylov_rows(A, B, use, C, idx[i], project, W, R, Rn, K)
        out[i, :, :nc] = K[:, :nc]
    return out


def _arguments(A, B, use, C, idx):
    """The kernels' arguments as they are compiled for: float64 and bool C
    arrays, int64 indices, and a 0-row C standing for 'no output map'."""
    project = C is not None
    C = np.zeros((1, 0, 0)) if C is None else C
    return (
        np.ascontiguousarray(A, dtype=np.float64),
        np.ascontiguousarray(B, dtype=np.float64),
        np.ascontiguousarray(use, dtype=np.bool_),
        np.ascontiguousarray(C, dtype=np.float64),
        np.ascontiguousarray(idx, dtype=np.int64),
        project,
    )


def krylov_rank_codes(A, B, use, C, idx) -> np.ndarray:
    """Full row rank of the Krylov matrices of systems ``idx``, decided
    where it is beyond doubt (module docstring).

    Args:
        A: (k, n, n); B: (k, n, m); use: (k, m) bool, the inputs in the
            Krylov matrix; C: (k, p, n), or None for the state Krylov matrix
            (C = I); idx: int (s,), the systems to test.

    Returns:
        int8 (s,): 1 full rank, 0 rank deficient, -1 undecided (then
        :func:`krylov_matrices` and the exact test decide).
    """
    return _codes(*_arguments(A, B, use, C, idx))


def krylov_matrices(A, B, use, C, idx) -> np.ndarray:
    """The Krylov matrices of systems ``idx`` (arguments of
    :func:`krylov_rank_codes`), shape (s, r, n m), as it tests them (the
    columns of the inputs not in use or zero are zero, at the end)."""
    return _matrices(*_arguments(A, B, use, C, idx))
