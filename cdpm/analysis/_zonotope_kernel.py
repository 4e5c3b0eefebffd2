"""Compiled facet search of zonotope inradii (numba, cached on disk).

Imported lazily by :func:`cdpm.analysis.reach.zonotope_inradii`, so that
``import cdpm`` does not load numba. The result is that of the plain
search: every hyperplane spanned by p - 1 generators is a facet
candidate, and the inradius is the least ``sum_l |n . d_l| - |n . c|``
over their unit normals n. What makes it fast leaves that minimum
unchanged:

- p = 2: one sweep in angle gives every candidate's sum in O(N log N);
  the few candidates within the sweep's round-off of the least are summed
  again directly.
- p >= 3: a candidate's sum stops as soon as it cannot beat the best so
  far (its terms are >= 0, summed from the longest generator down), and
  before that a bound from below with the sums of runs of generators
  (one input's samples in time: ``|n . sum d| <= sum |n . d|``) rules out
  most candidates in a few terms. For p = 3 an upper bound of the
  inradius, from the runs' own facets, is known before the search starts.
"""

from __future__ import annotations

import math

import numpy as np

from cdpm.jit import kernel
from cdpm.jit.dense import det_in_place
from cdpm.numerics import ZONOTOPE_BOUND_RTOL

EPS = float(np.finfo(np.float64).eps)

__all__ = ["facet_inradii", "facet_inradii_normals"]


@kernel
def _length(A, i):  # pragma: no cover - compiled
    """Euclidean length of row i of A."""
    total = 0.0
    for j in range(A.shape[1]):
        total += A[i, j] * A[i, j]
    return math.sqrt(total)


@kernel
def _normal(G, subset, p, n, minor, scratch):  # pragma: no cover - compiled
    """Normal n (length p) of the hyperplane spanned by the generators
    ``G[subset]`` (rows of G, (N, p)): generalised cross product by
    cofactors (``minor`` (p-1, p-1) and ``scratch`` (p-1,) are work space)."""
    if p == 2:
        n[0], n[1] = G[subset[0], 1], -G[subset[0], 0]
    else:
        r = p - 1
        for i in range(p):
            row = 0
            for q in range(p):
                if q == i:
                    continue
                for c in range(r):
                    minor[row, c] = G[subset[c], q]
                row += 1
            n[i] = (-1.0) ** i * det_in_place(minor, r, scratch)


@kernel
def _abs_sum(n, G, bound, p):  # pragma: no cover - compiled
    """sum_l |n . G[l]| over the rows of G; +inf as soon as the sum
    reaches ``bound`` (NaN if it overflowed)."""
    total = 0.0
    for row in range(G.shape[0]):
        if p == 3:
            dot = n[0] * G[row, 0] + n[1] * G[row, 1] + n[2] * G[row, 2]
        elif p == 2:
            dot = n[0] * G[row, 0] + n[1] * G[row, 1]
        else:
            dot = 0.0
            for i in range(p):
                dot += n[i] * G[row, i]
        total += abs(dot)
        if total >= bound:
            return np.inf
    return total


@kernel
def _rows_longest_first(D, s, p, run, count):  # pragma: no cover - compiled
    """Rows g = 0..count-1: the sums of the columns g run + [0, run) of
    D[s], sorted by decreasing length; shape (count, p)."""
    rows = np.zeros((count, p))
    lengths = np.empty(count)
    for g in range(count):
        for col in range(g * run, (g + 1) * run):
            for i in range(p):
                rows[g, i] += D[s, i, col]
        lengths[g] = _length(rows, g)
    return rows[np.argsort(-lengths)]


@kernel
def _cross_unit(A, i, B, j, n):  # pragma: no cover - compiled
    """n = a x b / |a x b| for the rows a = A[i], b = B[j] (3-vectors);
    returns |a x b| (n untouched if 0)."""
    n0 = A[i, 1] * B[j, 2] - A[i, 2] * B[j, 1]
    n1 = A[i, 2] * B[j, 0] - A[i, 0] * B[j, 2]
    n2 = A[i, 0] * B[j, 1] - A[i, 1] * B[j, 0]
    length = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if length > 0.0:
        n[0], n[1], n[2] = n0 / length, n1 / length, n2 / length
    return length


@kernel
def _spread(n, rows, c, bound):  # pragma: no cover - compiled
    """``sum_l |n . rows_l| - |n . c|`` in R^3; +inf once the sum reaches
    ``bound + |n . c|``."""
    shift = abs(n[0] * c[0] + n[1] * c[1] + n[2] * c[2])
    return _abs_sum(n, rows, bound + shift, 3) - shift


@kernel
def _upper_bound(runs, exact, c, slack):  # pragma: no cover - compiled
    """An upper bound of the inradius (when 0 is inside): the least exact
    spread over the 3 normals of pairs of runs whose run bound is least,
    plus ``slack``. The spread in any direction is at least the inradius,
    so this rules out candidates without changing the minimum."""
    m = runs.shape[0]
    low = np.full(3, np.inf)
    normals = np.zeros((3, 3))
    n = np.empty(3)
    for j in range(m):
        for q in range(j + 1, m):
            if _cross_unit(runs, j, runs, q, n) == 0.0:
                continue
            w = np.argmax(low)
            v = _spread(n, runs, c, low[w])
            if v < low[w]:
                low[w] = v
                normals[w] = n
    best = np.inf
    for w in range(3):
        if low[w] < np.inf:
            n[:] = normals[w]
            best = min(best, _spread(n, exact, c, best))
    return best + slack


@kernel
def _circle_above(G, a, runs, c, bound):  # pragma: no cover - compiled
    """True when every candidate normal orthogonal to generator a (the
    facets containing it) has a spread of at least ``bound`` (>= 0).

    With the runs' sums H_j in place of the generators the spread is a
    bound from below; over the circle n . d_a = 0 it is the support
    function of the zonogon of the H_j projected along d_a, less |n . c|,
    whose least value, when it is >= 0 (the projected c is inside), is at
    one of the zonogon's edge normals ``d_a x H_j``.
    """
    n = np.empty(3)
    kinks = 0
    for j in range(runs.shape[0]):
        if _cross_unit(G, a, runs, j, n) == 0.0:
            continue
        kinks += 1
        shift = abs(n[0] * c[0] + n[1] * c[1] + n[2] * c[2])
        if _abs_sum(n, runs, bound + shift, 3) != np.inf:
            return False  # this edge normal's bound is below ``bound``
    return kinks > 0


@kernel
def _inradius3(G, norms, runs, exact, c, normal_rtol, slack, best_normal):  # pragma: no cover
    """The facet search in R^3 (pairs of generators), with the run bound,
    an upper bound from the runs' own facets and the circles it shuts when
    ``runs`` is not ``exact``; leaves the least candidate's unit normal in
    ``best_normal`` (untouched if there is none)."""
    N = G.shape[0]
    grouped = runs.shape[0] < N
    ceiling = _upper_bound(runs, exact, c, slack) if grouped else np.inf
    n = np.empty(3)
    best = np.inf
    # circles (the facets containing one generator) that cannot win: a
    # candidate (a, b) lies on the circles of both a and b
    shut = np.zeros(N, dtype=np.bool_)
    if grouped:
        for a in range(N):
            shut[a] = _circle_above(G, a, runs, c, ceiling + slack)
    for a in range(N):
        if shut[a] or (grouped and _circle_above(G, a, runs, c, best + slack)):
            continue  # no facet containing generator a can win
        least = normal_rtol * norms[a]
        for b in range(a + 1, N):
            if shut[b]:
                continue
            length = _cross_unit(G, a, G, b, n)
            if not length > least * norms[b]:
                continue  # dependent generators
            shift = abs(n[0] * c[0] + n[1] * c[1] + n[2] * c[2])
            bound = min(best, ceiling) + shift  # a sum reaching this cannot win
            if grouped and _abs_sum(n, runs, bound, 3) == np.inf:
                continue
            spread = _abs_sum(n, exact, bound, 3) - shift
            if math.isnan(spread):
                return np.nan
            if spread < best:
                best = spread
                best_normal[:] = n
    return best


@kernel
def _inradius2(G, norms, c, slack, best_normal):  # pragma: no cover - compiled
    """The facet search in R^2 by one sweep in angle: the candidates are
    the normals n_a of the generators; between two consecutive ones (in
    angle on [0, pi)) the signs of n . d_l are constant, so the sum
    ``S = sum_l sign(n . d_l) d_l`` is updated by one generator per
    candidate and ``h(n_a) = S . n_a``. The candidates within the sweep's
    round-off (``slack``) of its least value are summed again exactly; the
    least one's unit normal is left in ``best_normal``."""
    N = G.shape[0]
    angle = np.empty(N)  # a key increasing with the angle of n_a
    normals = np.zeros((N, 2))
    S = np.zeros(2)
    for row in range(N):
        if norms[row] == 0.0:
            angle[row] = np.inf  # no candidate, no contribution
            continue
        n0, n1 = G[row, 1] / norms[row], -G[row, 0] / norms[row]
        if n1 < 0.0 or (n1 == 0.0 and n0 < 0.0):
            n0, n1 = -n0, -n1  # angle in [0, pi)
        normals[row, 0], normals[row, 1] = n0, n1
        angle[row] = -n0  # increasing with the angle on [0, pi)
        # sign of (cos t, sin t) . d_l just before t = 0 (every crossing
        # in [0, pi) is then met in the sweep)
        sign = 1.0 if G[row, 0] > 0.0 or (G[row, 0] == 0.0 and G[row, 1] < 0.0) else -1.0
        S[0] += sign * G[row, 0]
        S[1] += sign * G[row, 1]
    order = np.argsort(angle)
    values = np.full(N, np.inf)
    least = np.inf
    for a in order:
        if angle[a] == np.inf:
            break
        n0, n1 = normals[a, 0], normals[a, 1]
        values[a] = S[0] * n0 + S[1] * n1 - abs(n0 * c[0] + n1 * c[1])
        least = min(least, values[a])
        # past n_a, n . d_a takes the sign of its derivative in the angle
        sign = 1.0 if G[a, 1] * n0 - G[a, 0] * n1 > 0.0 else -1.0
        S[0] += 2.0 * sign * G[a, 0]
        S[1] += 2.0 * sign * G[a, 1]
    best = np.inf
    for a in range(N):
        if values[a] <= least + slack:
            spread = _abs_sum(normals[a], G, np.inf, 2) - abs(
                normals[a, 0] * c[0] + normals[a, 1] * c[1]
            )
            if spread < best:
                best = spread
                best_normal[:] = normals[a]
    return best


@kernel
def _search(G, norms, runs, exact, c, normal_rtol, ceiling, best_normal):  # pragma: no cover
    """The facet search in R^p, any p >= 2: every (p - 1)-subset of the
    rows of G (N, p) in lexicographic order; candidates whose run sum or
    exact sum reaches min(best, ceiling) are dropped. Returns the least
    spread (NaN on overflow, +inf if no candidate) and leaves its unit
    normal in ``best_normal``."""
    N, p = G.shape
    r = p - 1
    n = np.empty(p)
    minor = np.empty((max(r, 1), max(r, 1)))
    scratch = np.empty(max(r, 1))
    subset = np.arange(r)
    grouped = runs.shape[0] < N
    best = np.inf
    while True:
        _normal(G, subset, p, n, minor, scratch)
        length = 0.0
        for i in range(p):
            length += n[i] * n[i]
        length = math.sqrt(length)
        scale = 1.0
        for i in range(r):
            scale *= norms[subset[i]]
        if length > normal_rtol * scale:  # else dependent generators
            shift = 0.0
            for i in range(p):
                n[i] /= length
                shift += n[i] * c[i]
            bound = min(best, ceiling) + abs(shift)  # a sum reaching this cannot win
            if not grouped or _abs_sum(n, runs, bound, p) != np.inf:
                spread = _abs_sum(n, exact, bound, p) - abs(shift)
                if math.isnan(spread):
                    return np.nan
                if spread < best:
                    best = spread
                    best_normal[:] = n
        # next subset in lexicographic order
        i = r - 1
        while i >= 0 and subset[i] == N - r + i:
            i -= 1
        if i < 0:
            return best
        subset[i] += 1
        for j in range(i + 1, r):
            subset[j] = subset[j - 1] + 1


@kernel
def facet_inradii(D, center, normal_rtol, group):  # pragma: no cover - compiled
    """Least ``sum_l |n . d_l| - |n . c|`` over the unit normals n of the
    hyperplanes spanned by p - 1 generators, per zonotope: the first output
    of :func:`facet_inradii_normals`, shape (k,)."""
    return facet_inradii_normals(D, center, normal_rtol, group)[0]


@kernel
def facet_inradii_normals(D, center, normal_rtol, group):  # pragma: no cover - compiled
    """Least ``sum_l |n . d_l| - |n . c|`` over the unit normals n of the
    hyperplanes spanned by p - 1 generators, per zonotope, and that n.

    A candidate is first bounded from below with the sums of consecutive
    runs of ``group`` generators (``|n . sum d| <= sum |n . d|``, tight
    when the run's generators lie on one side of the candidate's plane):
    it is summed in full only when that bound does not rule it out.

    Args:
        D: generators, shape (k, p, N), p >= 2, N >= p - 1.
        center: centres, shape (k, p).
        normal_rtol: a candidate whose normal is not longer than this times
            the product of its generators' lengths is skipped (dependent).
        group: run length of the lower bound (1: no bound; must divide N).

    Returns:
        (values, normals): values shape (k,), the least value; +inf when no
        candidate is valid; NaN when a value overflowed (NaN or inf
        arithmetic). normals shape (k, p): the unit normal of the least
        candidate (0 where there is none).
    """
    k, p, N = D.shape
    out = np.empty(k)
    normals = np.zeros((k, p))
    n = np.empty(p)
    G = np.empty((N, p))
    norms = np.empty(N)
    for s in range(k):
        for row in range(N):
            for i in range(p):
                G[row, i] = D[s, i, row]
            norms[row] = _length(G, row)
        c = center[s]
        slack = ZONOTOPE_BOUND_RTOL * norms.sum()
        if not np.isfinite(slack + c.sum()):
            out[s] = np.nan
            continue
        if p == 2:
            sweep = (8 * N * EPS + ZONOTOPE_BOUND_RTOL) * (norms.sum() + abs(c[0]) + abs(c[1]))
            out[s] = _inradius2(G, norms, c, sweep, normals[s])
            continue
        exact = _rows_longest_first(D, s, p, 1, N)  # the generators
        runs = _rows_longest_first(D, s, p, group, N // group)
        if p == 3:
            out[s] = _inradius3(G, norms, runs, exact, c, normal_rtol, slack, normals[s])
        else:
            ceiling = np.inf
            if p - 1 <= runs.shape[0] < N:  # the runs' least facet: an upper bound
                lengths = np.array([_length(runs, g) for g in range(runs.shape[0])])
                if _search(runs, lengths, runs, runs, c, normal_rtol, np.inf, n) < np.inf:
                    ceiling = _abs_sum(n, exact, np.inf, p) - abs((n * c).sum()) + slack
            n[:] = 0.0
            out[s] = _search(G, norms, runs, exact, c, normal_rtol, ceiling, n)
            normals[s] = n
    return out, normals
