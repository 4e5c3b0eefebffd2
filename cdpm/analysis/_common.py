"""Shared pieces of the analysis layer: the verdict enum, input validation
and tolerance-aware linear algebra (ranks, null spaces, Krylov bases).

Everything here is private except :class:`Verdict`.
"""

from __future__ import annotations

import enum
import math
import re

import numpy as np
from scipy import linalg as sla
from scipy.linalg import lapack as _lapack

from cdpm.errors import InputError, float_array
from cdpm.numerics import (
    KRYLOV_RTOL,
    MATRIX_SCALE_RANGE,
    NULL_SPACE_RTOL,
    RANK_RTOL,
    ROW_ZERO_RTOL,
    SQUARE_ZERO_RTOL,
)

__all__ = ["Verdict"]


class Verdict(enum.Enum):
    """Outcome of a decision: ``YES``, ``NO`` or ``MARGINAL`` (undecided at
    the working tolerance; the result's ``reason`` says why)."""

    YES = "yes"
    NO = "no"
    MARGINAL = "marginal"

    def __str__(self) -> str:
        return self.value.upper()

    def __bool__(self) -> bool:
        return self is Verdict.YES


# --------------------------------------------------------------------------
# validation


def as_matrix(
    name: str,
    value,
    rows: int | None = None,
    cols: int | None = None,
    rows_from: str = "",
    cols_from: str = "",
    check_finite: bool = True,
) -> np.ndarray:
    # rows_from / cols_from read like "n (rows of A)": the symbol, then why
    """Return ``value`` as a finite 2-D float array (a copy), checking its shape.

    Raises:
        InputError: naming the argument, the expected shape and where the
            expectation comes from, e.g. "B has 5 rows, expected n=6 (rows of A)".
    """
    try:
        arr = float_array(value, copy=True)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} must be a numeric matrix: {e}") from e
    if arr.ndim == 1 and rows == 1:
        arr = arr[None, :]
    if arr.ndim != 2:
        raise InputError(f"{name} must be 2-D, got an array of shape {arr.shape}")
    if rows is not None and arr.shape[0] != rows:
        raise InputError(f"{name} has {arr.shape[0]} rows, expected {_expect(rows_from, rows)}")
    if cols is not None and arr.shape[1] != cols:
        raise InputError(f"{name} has {arr.shape[1]} columns, expected {_expect(cols_from, cols)}")
    if check_finite:
        _check_finite(name, arr)
    return arr


def _expect(label: str, value: int) -> str:
    """ "n (rows of A)", 6 -> "n=6 (rows of A)"."""
    symbol, _, why = label.partition(" ")
    return f"{symbol}={value} {why}".strip()


def _check_finite(name: str, arr: np.ndarray) -> None:
    if not np.isfinite(arr).all():
        raise InputError(f"{name} contains non-finite values (nan or inf)")


def as_mask(sign_constrained, m: int) -> np.ndarray:
    """Bool mask of sign-constrained inputs, default all True (the paper)."""
    if sign_constrained is None:
        return np.ones(m, dtype=bool)
    if isinstance(sign_constrained, np.ndarray) and sign_constrained.dtype == bool:
        if sign_constrained.shape == (m,):
            return sign_constrained.copy()
    mask = np.asarray(sign_constrained)
    if mask.dtype != bool:
        if mask.dtype.kind not in "iu" or not np.isin(mask, (0, 1)).all():
            raise InputError(f"sign_constrained must be a bool mask of length m={m}, got {mask!r}")
        mask = mask.astype(bool)
    if mask.shape != (m,):
        raise InputError(
            f"sign_constrained has shape {mask.shape}, expected (m,)=({m},) (columns of B)"
        )
    return mask.copy()


def as_positive_vector(name: str, value, size: int, size_from: str) -> np.ndarray:
    """A strictly positive, finite vector of length ``size`` (or ones if None)."""
    if value is None:
        return np.ones(size)
    try:
        arr = float_array(value, copy=True).reshape(-1)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} must be {size} numbers: {e}") from e
    if arr.size == 1:
        arr = np.full(size, float(arr[0]))
    if arr.shape != (size,):
        raise InputError(f"{name} has {arr.size} entries, expected {_expect(size_from, size)}")
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise InputError(f"{name} must be finite and strictly positive, got {arr}")
    return arr


def as_system(A, B, C=None, sign_constrained=None):
    """Validate (A, B[, C]) and the input mask once; return float copies."""
    A = as_matrix("A", A, check_finite=False)
    n = A.shape[0]
    if A.shape[1] != n:
        raise InputError(f"A must be square, got shape {A.shape}")
    B = as_matrix("B", B, rows=n, rows_from="n (rows of A)", check_finite=False)
    mask = as_mask(sign_constrained, B.shape[1])
    mats = [("A", A), ("B", B)]
    if C is not None:
        C = as_matrix("C", C, cols=n, cols_from="n (rows of A)", check_finite=False)
        mats.append(("C", C))
    # one cheap sum first; the exact per-matrix check only if it is not finite
    if not math.isfinite(sum(float(M.sum()) for _, M in mats)):
        for name, M in mats:
            _check_finite(name, M)
    low, high = MATRIX_SCALE_RANGE
    for name, M in mats:
        big = float(np.abs(M).max()) if M.size else 0.0
        if big > high or 0 < big < low:
            raise InputError(
                f"{name}'s largest entry is {big:.3g} in magnitude; the analysis takes matrices "
                f"whose largest entry is between {low:g} and {high:g} (or 0), where products "
                "of entries neither under- nor overflow: express the model in other units"
            )
    return (A, B, mask) if C is None else (A, B, C, mask)


# --------------------------------------------------------------------------
# linear algebra


# Small dense factorisations called directly through LAPACK: a decision runs
# a few dozen of them on tiny matrices (sizes ~2-24), where numpy.linalg's
# per-call checks cost as much as the factorisation. Each falls back to
# numpy.linalg when LAPACK reports a failure.


def svdvals(X: np.ndarray) -> np.ndarray:
    """Singular values of X (descending), LAPACK gesdd."""
    if X.size == 0:
        return np.zeros(0)
    _, s, _, info = _lapack.dgesdd(X, compute_uv=0)
    return s if info == 0 else np.linalg.svd(X, compute_uv=False)


def svd(X: np.ndarray, full_matrices: bool = False):
    """(U, s, Vt) of X, LAPACK gesdd."""
    if X.size == 0:
        return np.linalg.svd(X, full_matrices=full_matrices)
    U, s, Vt, info = _lapack.dgesdd(X, compute_uv=1, full_matrices=int(full_matrices))
    if info != 0:  # pragma: no cover - LAPACK failure
        return np.linalg.svd(X, full_matrices=full_matrices)
    return U, s, Vt


def eigh(G: np.ndarray):
    """(ascending eigenvalues, eigenvectors) of a symmetric G, LAPACK syevd."""
    w, V, info = _lapack.dsyevd(G)
    if info != 0:  # pragma: no cover - LAPACK failure
        return np.linalg.eigh(G)
    return w, V


def qr_pivots(U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Column pivoting order of a rank-revealing QR of U (LAPACK geqp3) and
    |R_kk| in that order (non-increasing)."""
    qr, jpvt, _, _, info = _lapack.dgeqp3(U)
    if info != 0:  # pragma: no cover - LAPACK failure
        _, R, piv = sla.qr(U, mode="economic", pivoting=True)
        return piv, np.abs(np.diag(R))
    k = min(U.shape)
    return jpvt - 1, np.abs(np.diag(qr)[:k])


def numerical_rank(s: np.ndarray, rtol: float = RANK_RTOL) -> int:
    """Rank from singular values ``s`` (descending) with a relative tolerance."""
    if s.size == 0 or s[0] <= 0:
        return 0
    return int(np.count_nonzero(s > rtol * s[0]))


def orth(X: np.ndarray, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis of the column space of X (columns scaled first)."""
    if X.size == 0:
        return np.zeros((X.shape[0], 0))
    norms = np.linalg.norm(X, axis=0)
    keep = norms > 0
    if not keep.any():
        return np.zeros((X.shape[0], 0))
    U, s, _ = svd(X[:, keep] / norms[keep])
    return U[:, : numerical_rank(s, rtol)]


def complement(Q: np.ndarray, dim: int) -> np.ndarray:
    """Orthonormal basis of the orthogonal complement of range(Q) in R^dim."""
    if Q.shape[1] == 0:
        return np.eye(dim)
    if Q.shape[1] >= dim:
        return np.zeros((dim, 0))
    U, _, _ = svd(Q, full_matrices=True)
    return U[:, Q.shape[1] :]


def null_space(M: np.ndarray, rtol: float = NULL_SPACE_RTOL, atol: float = 0.0) -> np.ndarray:
    """Orthonormal basis of the (right) null space of M.

    Singular values at most ``max(rtol * s_max, atol)`` count as zero: pass
    ``atol`` when M is known to be small against a scale of its own (a
    relative tolerance alone turns a matrix of round-off into full rank).
    """
    if M.shape[0] == 0:
        return np.eye(M.shape[1])
    _, s, Vt = np.linalg.svd(M, full_matrices=True)
    scale = max(s[0] if s.size else 0.0, 1e-300)
    r = int(np.count_nonzero(s > max(rtol * scale, atol)))
    return Vt[r:].T.conj()


def balance(A: np.ndarray) -> np.ndarray:
    """Diagonal state scaling d with D^-1 A D better conditioned (LAPACK gebal)."""
    if A.shape[0] == 0 or not np.any(A):
        return np.ones(A.shape[0])
    # LAPACK directly: scipy.linalg.matrix_balance costs 25x more per call
    _, _, _, d, info = sla.lapack.dgebal(A, scale=1, permute=0)
    if info != 0 or not np.all(np.isfinite(d)) or np.any(d <= 0):  # pragma: no cover
        return np.ones(A.shape[0])
    return d


def scaled_system(A: np.ndarray, B: np.ndarray, C: np.ndarray | None):
    """Similarity- and input/output-scaled copy of a system.

    Returns (As, Bs, Cs, d, col, row, rho) with
    ``As = D^-1 A D / rho``, ``Bs[:, j] = D^-1 B[:, j] * col[j]`` and
    ``Cs[i] = row[i] * C[i] D`` (0 for a row shorter than ``ROW_ZERO_RTOL``
    times the longest, with ``row[i] = 1``), and time measured in units of 1/rho
    (``t = ts / rho``) with rho the Frobenius norm of ``D^-1 A D`` (so
    ``|As|_2 <= 1``; no SVD). None of these changes a positive-controllability
    verdict (positive scalings and similarities).
    """
    d = balance(A)
    As = A * (1.0 / d)[:, None] * d[None, :]
    rho = float(np.linalg.norm(As)) if As.size else 0.0
    if rho == 0.0:
        rho = 1.0
    As = As / rho
    Bs = B / d[:, None]
    col = np.linalg.norm(Bs, axis=0)
    col = np.where(col > 0, 1.0 / np.where(col > 0, col, 1.0), 1.0)
    Bs = Bs * col
    if C is None:
        return As, Bs, None, d, col, None, rho
    Cs = C * d[None, :]
    rn = np.linalg.norm(Cs, axis=1)
    live = rn > ROW_ZERO_RTOL * rn.max() if rn.size else rn > 0
    row = np.where(live, 1.0 / np.where(live, rn, 1.0), 1.0)
    # round-off rows (ROW_ZERO_RTOL) become exact zero rows
    Cs = Cs * np.where(live, row, 0.0)[:, None]
    return As, Bs, Cs, d, col, row, rho


def krylov_basis(A: np.ndarray, B: np.ndarray, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis of the reachable subspace span[B, AB, ..., A^{n-1}B].

    Block Arnoldi with re-orthogonalisation: never forms badly scaled powers.
    """
    n = A.shape[0]
    if B.shape[1] == 0 or n == 0:
        return np.zeros((n, 0))
    Q = orth(B, rtol)
    new = Q
    # callers pass a scaled A (|A|_2 = 1); the Frobenius norm bounds |A|_2
    # within sqrt(n) and costs no SVD
    ref = float(np.linalg.norm(A)) + 1e-300
    while new.shape[1] and Q.shape[1] < n:
        X = A @ new
        for _ in range(2):
            X = X - Q @ (Q.T @ X)
        U, s, _ = svd(X)
        # X was orthogonalised against Q twice: its left singular vectors are
        # orthonormal and orthogonal to Q to round-off
        new = U[:, : int(np.count_nonzero(s > KRYLOV_RTOL * ref))]
        if new.shape[1] == 0:
            break
        Q = np.hstack([Q, new])
    return Q[:, :n]


def is_square_zero(A: np.ndarray) -> bool:
    """A^2 = 0 up to round-off, entrywise relative to |A| @ |A| (scale-free)."""
    return bool(square_zero(A[None])[0])


def square_zero(A: np.ndarray) -> np.ndarray:
    """:func:`is_square_zero` of the matrices A (k, n, n), shape (k,)."""
    AA = A @ A
    small = np.abs(AA) <= SQUARE_ZERO_RTOL * (np.abs(A) @ np.abs(A))
    return ~np.any(AA, axis=(1, 2)) | np.all(small, axis=(1, 2))


def cluster(values: np.ndarray, atol: float) -> list[np.ndarray]:
    """Group (real) values closer than ``atol`` (chained); returns index arrays."""
    order = np.argsort(values)
    groups: list[list[int]] = []
    for i in order:
        if groups and values[i] - values[groups[-1][-1]] <= atol:
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    return [np.array(g) for g in groups]


# --------------------------------------------------------------------------
# presentation


def fmt_array(x, digits: int = 4) -> str:
    """Compact one-line rendering of a small array; an entry shown as zero
    has no minus sign (-6e-17 beside 1 reads ``0.``, not ``-0.``)."""

    text = np.array2string(
        np.asarray(x), precision=digits, suppress_small=True, max_line_width=10_000, separator=", "
    )
    return re.sub(r"-(0\.0*)(?=\s*[,\]])", r" \1", text)


#: Pade [13/13] coefficients b_0..b_13 of the scaling-and-squaring method
#: (N. J. Higham, "The scaling and squaring method for the matrix
#: exponential revisited", SIAM J. Matrix Anal. Appl. 26(4), 2005)
_PADE13 = (
    64764752532480000.0,
    32382376266240000.0,
    7771770303897600.0,
    1187353796428800.0,
    129060195264000.0,
    10559470521600.0,
    670442572800.0,
    33522128640.0,
    1323241920.0,
    40840800.0,
    960960.0,
    16380.0,
    182.0,
    1.0,
)
#: the 1-norm up to which Pade [13/13] meets double precision (same paper)
_THETA13 = 5.371920351148152


def expm_batch(A: np.ndarray) -> np.ndarray:
    """e^A of many square matrices at once, shape (k, n, n) -> (k, n, n).

    The scaling-and-squaring method with the Pade [13/13] approximant
    (Higham 2005), its scaling chosen from ``max(|A^3|^(1/3), |A^4|^(1/4))``
    (1-norms) rather than |A| (Al-Mohy and Higham, "A new scaling and
    squaring algorithm for the matrix exponential", SIAM J. Matrix Anal.
    Appl. 31(3), 2009, Theorem 4.2: the same backward error bound, and no
    needless squarings for badly scaled matrices): each matrix is scaled by
    2^-s, the approximant is evaluated with a few matrix products and one
    solve over the whole batch, and squared s times. Backward error within
    double precision, like :func:`scipy.linalg.expm` (which loops over a
    stack in Python: about 10 us a matrix, where this costs about 1 us for
    4 x 4 matrices; it still computes the few matrices whose squarings
    overflow here). Finite input only.
    """
    k, n, _ = A.shape
    if k == 0 or n == 0:
        return np.broadcast_to(np.eye(n), A.shape).copy()

    def norm1(X):
        return np.abs(X).sum(axis=1).max(axis=1)

    def doublings(size):
        """s >= 0 with size / 2^s <= theta_13."""
        return np.ceil(np.log2(np.maximum(size, _THETA13) / _THETA13)).astype(int)

    def powers(X, s):
        """X 2^-s and its square, fourth and sixth powers."""
        X = X * np.ldexp(1.0, -s)[:, None, None]
        X2 = X @ X
        X4 = X2 @ X2
        return X, X2, X4, X4 @ X2

    b, eye, given = _PADE13, np.eye(n), A
    with np.errstate(over="ignore", invalid="ignore"):
        A2 = A @ A
        A4 = A2 @ A2
        alpha = np.maximum(norm1(A2 @ A) ** (1 / 3), norm1(A4) ** 0.25)
    finite = np.isfinite(alpha)
    # powers that overflow: the 1-norm itself sets the scaling (Higham 2005)
    s = np.where(finite, doublings(np.where(finite, alpha, 0.0)), doublings(norm1(A)))
    # scaling by 2^-s is exact: the powers already computed are reused
    scale = np.ldexp(1.0, -s)[:, None, None]
    A, A2, A4 = A * scale, A2 * scale**2, A4 * scale**4
    lost = np.flatnonzero(~finite)
    if lost.size:
        A[lost], A2[lost], A4[lost], _ = powers(given[lost], s[lost])
    A6 = A4 @ A2
    U = A @ (
        A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * eye
    )
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 + b[0] * eye
    R = np.linalg.solve(V - U, V + U)
    with np.errstate(over="ignore", invalid="ignore"):
        for j in range(int(s.max())):
            i = np.flatnonzero(s > j)
            R[i] = R[i] @ R[i]
    # extremely badly scaled matrices (stiffness near the float range) whose
    # squarings overflow: scipy's expm, one by one
    lost = np.flatnonzero(~np.isfinite(R).all(axis=(1, 2)))
    if lost.size:
        R[lost] = sla.expm(given[lost])
    return R


def spectral_abscissae(A: np.ndarray) -> np.ndarray:
    """The largest real part of an eigenvalue of each A (k, n, n), shape (k,).

    A system whose A is that of an undamped mechanical system,
    ``[[0, I], [F, 0]]`` (checked exactly, per system; F = -M^-1 K), has the
    eigenvalues ``+-sqrt(mu)`` for the eigenvalues mu of F (``lambda^2 x =
    F x``): its abscissa is the largest real part of their principal square
    roots, from an eigenvalue problem of half the size (about a third of the
    work). The others take the eigenvalues of A.
    """
    k, n = A.shape[0], A.shape[-1]
    out = np.empty(k)
    if k == 0:
        return out
    if n == 0:
        out[:] = -np.inf
        return out
    half = n // 2
    undamped = np.zeros(k, dtype=bool)
    if n % 2 == 0:
        top = A[:, :half]
        undamped = (
            ~np.any(top[:, :, :half], axis=(1, 2))
            & np.all(top[:, :, half:] == np.eye(half), axis=(1, 2))
            & ~np.any(A[:, half:, half:], axis=(1, 2))
        )
    if undamped.any():
        mu = np.linalg.eigvals(A[undamped][:, half:, :half])
        out[undamped] = np.sqrt(mu.astype(complex)).real.max(axis=1)
    if not undamped.all():
        out[~undamped] = np.linalg.eigvals(A[~undamped]).real.max(axis=1)
    return out


def in_norm_range(S: np.ndarray) -> tuple[np.ndarray, float]:
    """``(S * c, c)`` with ``c`` a power of two that brings the largest
    entry of the array ``S`` near 1 when it is so small or so large that squaring
    it (in a column norm) under- or overflows; otherwise ``(S, 1.0)``.
    A power of two scales exactly, so directions and ratios are unchanged."""
    big = float(np.max(np.abs(S))) if S.size else 0.0
    low, high = MATRIX_SCALE_RANGE
    if big == 0.0 or low < big < high or not math.isfinite(big):
        return S, 1.0
    # at most 2^1000: the smallest subnormal entries then come to about 1e-23
    c = math.ldexp(1.0, min(-math.frexp(big)[1], 1000))
    return S * c, c
