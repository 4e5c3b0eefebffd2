"""Gaussian elimination for the compiled kernels (numba, cached on disk).

The kernels' matrices are tiny (a few rows), so they eliminate in place
inside their loops instead of calling LAPACK, which would allocate per
call. One elimination serves the linear solves of the equilibrium Newton
and of the wrench-closure certificates and the determinants of the reach
margin's facet normals. Imported by those kernel modules only.
"""

from __future__ import annotations

from cdpm.jit import kernel

__all__ = ["eliminate", "solve_in_place", "back_substitute", "det_in_place"]


@kernel
def eliminate(M, rhs, n):  # pragma: no cover - compiled
    """Gaussian elimination with partial pivoting (as LAPACK's getrf) of the
    leading n x n block of M, in place, applied to ``rhs`` (n,) as well.

    Returns:
        The number of row swaps (>= 0); -1 when a pivot is exactly 0 (the
        elimination stops there). The upper triangle of M's block then holds
        U; below it is left as it was.
    """
    swaps = 0
    for c in range(n):
        p = c
        best = abs(M[c, c])
        for i in range(c + 1, n):
            if abs(M[i, c]) > best:
                best = abs(M[i, c])
                p = i
        if best == 0.0:
            return -1
        if p != c:
            for j in range(n):
                M[c, j], M[p, j] = M[p, j], M[c, j]
            rhs[c], rhs[p] = rhs[p], rhs[c]
            swaps += 1
        pivot = M[c, c]
        for i in range(c + 1, n):
            factor = M[i, c] / pivot
            if factor != 0.0:
                for j in range(c + 1, n):
                    M[i, j] -= factor * M[c, j]
                rhs[i] -= factor * rhs[c]
    return swaps


@kernel
def solve_in_place(M, rhs, n):  # pragma: no cover - compiled
    """Solve M y = rhs for the leading n x n block of M (destroyed): rhs
    (n,) becomes y. False (rhs then meaningless) when M is singular to a
    zero pivot."""
    if eliminate(M, rhs, n) < 0:
        return False
    back_substitute(M, rhs, rhs, n)
    return True


@kernel
def back_substitute(U, y, out, n):  # pragma: no cover - compiled
    """out (n,) solving U out = y for the upper triangle of U's leading
    n x n block (nonzero diagonal); ``out`` may be ``y``."""
    for c in range(n - 1, -1, -1):
        s = y[c]
        for j in range(c + 1, n):
            s -= U[c, j] * out[j]
        out[c] = s / U[c, c]


@kernel
def det_in_place(M, n, scratch):  # pragma: no cover - compiled
    """Determinant of the leading n x n block of M (destroyed); ``scratch``
    (>= n,) is overwritten."""
    swaps = eliminate(M, scratch, n)
    if swaps < 0:
        return 0.0
    det = -1.0 if swaps % 2 else 1.0
    for c in range(n):
        det *= M[c, c]
    return det
