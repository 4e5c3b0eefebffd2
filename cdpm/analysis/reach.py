"""The reach margin r_T: how far the outputs can be moved in time T.

docs/analysis.md, the reach margin. For a linear system ``x' = A x + B u``,
``y = C x`` started at rest (x(0) = 0), with inputs bounded elementwise by
``lower <= u(t) <= upper`` (``lower <= 0 <= upper``: tension deviations from
the equilibrium within the cables' bounds), the outputs reachable at time T
form the convex set

    R_T = { integral_0^T C e^{A t} B u(t) dt : lower <= u(t) <= upper },

which contains 0. ``r_T`` is the radius of the largest ball about 0 inside
``W R_T`` (``W = diag(weight)``), i.e. the least value of the support
function of ``W R_T`` over unit directions. It is positive exactly when
every output direction is reachable within T with these inputs.

Computation: R_T is the sum over t of the boxes' images, and its support
function is ``h(v) = integral_0^T sum_j max(upper_j s_j(t), lower_j s_j(t)) dt``
with ``s_j(t) = v^T W C e^{A t} b_j``. Composite Simpson's rule on K
intervals (positive weights) turns R_T into a zonotope (one generator per
input and node), whose inradius about 0 is computed exactly: the least
``sum_l |n . d_l| - |n . c|`` over the normals n of its facets (hyperplanes
spanned by p - 1 generators). The rule's error is the same for r_T as for
the support function in the worst direction; it is estimated as
``|r(K) - r(K/2)|`` (for integrands smooth in t the true error is about a
fifteenth of that, where a direction's integrand has kinks (an input's
output direction crossing v's normal plane) about a third). When ``A^2 = 0``
(a mechanical system at zero tension and gravity) the integrand is linear
in t on (0, T] for every direction and
``r_T = (T^2 / 2) inradius{ W C A B u : lower <= u <= upper }`` exactly,
up to the ``C B`` term (0 for mechanical systems, whose outputs are
positions; bounded by ``T sum_j max(upper_j, -lower_j) |W C b_j|``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cdpm.analysis._common import spectral_abscissae, square_zero
from cdpm.analysis.margin import state_samples
from cdpm.numerics import (
    REACH_GROWTH_MAX,
    REACH_MAX_FACET_WORK,
    REACH_NODES,
    REACH_NODES_HIGH,
    REACH_ZERO_RTOL,
    ZONOTOPE_NORMAL_RTOL,
)

__all__ = ["ReachMargins", "reach_margins", "reach_margin", "zonotope_inradii", "reach_nodes"]

#: largest state-sample array (systems x n x nodes x m doubles) the
#: quadrature builds at once [bytes]; more systems go in blocks. The
#: quadrature's arrays of a 2048-pose map chunk (tens of MB) otherwise come
#: from fresh pages, whose first touch cost the first chunk of a process
#: 6-10 ms; blocks of this size are reused and stay in the CPU's cache,
#: at the same speed on later chunks
QUADRATURE_BLOCK_BYTES = 2**20


@dataclass(frozen=True)
class ReachMargins:
    """Reach margins of k systems.

    Attributes:
        value: r_T, shape (k,), >= 0 [output units, weighted; outputs in
            different units count one of each as one].
        error: estimate of |value - exact r_T| from the time quadrature,
            shape (k,) (0 where the value is exact).
        intervals: quadrature intervals K per system, shape (k,).
    """

    value: np.ndarray
    error: np.ndarray
    intervals: np.ndarray


def reach_nodes(p: int) -> int:
    """Simpson intervals K (a multiple of 4) for p outputs: the zonotope has
    m K generators and (m K)^(p - 1) facet candidates."""
    return REACH_NODES.get(p, REACH_NODES_HIGH)


def reach_margins(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    horizon: float,
    weight: np.ndarray | None = None,
) -> ReachMargins:
    """The reach margins r_T of k systems (module docstring).

    Args:
        A: state matrices, shape (k, n, n), finite.
        B: input matrices, shape (k, n, m).
        C: output matrices, shape (k, p, n), p >= 1.
        lower: least input values, shape (k, m), <= 0 [input units, N].
        upper: largest input values, shape (k, m), >= 0 and finite.
        horizon: T > 0 [time unit of A, s].
        weight: output weights, shape (p,), positive; default 1.

    Returns:
        :class:`ReachMargins` (value, error estimate, intervals); value NaN
        (error inf) where a growing mode grows by more than REACH_GROWTH_MAX
        within T (the horizon is too long for the pose: the reachable set
        is too thin across that mode to resolve in floating point).
    """
    with np.errstate(over="ignore", invalid="ignore"):
        return _reach_margins(A, B, C, lower, upper, horizon, weight)


def _reach_margins(A, B, C, lower, upper, horizon, weight) -> ReachMargins:
    k, n, m = B.shape
    p = C.shape[1]
    T = float(horizon)
    Cw = C if weight is None else C * np.asarray(weight, dtype=float)[:, None]
    value, error = np.zeros(k), np.zeros(k)
    intervals = np.ones(k, dtype=int)
    if k == 0 or m == 0 or p == 0:
        return ReachMargins(np.full(k, math.inf) if p == 0 else value, error, intervals)
    mid = (upper + lower) / 2  # (k, m)
    half = (upper - lower) / 2
    wide = np.maximum(upper, -lower)  # (k, m)
    CB = Cw @ B  # (k, p, m)
    cb_bound = T * np.einsum("km,km->k", wide, np.sqrt((CB * CB).sum(axis=1)))
    exact = square_zero(A) if n else np.ones(k, dtype=bool)
    skipped = np.zeros(k, dtype=bool)
    if exact.any() and facet_work(m, p) > REACH_MAX_FACET_WORK:
        value[exact], error[exact], intervals[exact] = np.nan, np.nan, 0  # not computed
        skipped, exact = exact, np.zeros(k, dtype=bool)
    if exact.any():
        i = np.flatnonzero(exact)
        G = (T * T / 2) * (Cw[i] @ (A[i] @ B[i]))  # (k', p, m)
        value[i] = zonotope_inradii(G * half[i][:, None], np.einsum("kpm,km->kp", G, mid[i]))
        error[i] = cb_bound[i]
    rest = np.flatnonzero(~exact & ~skipped)
    if rest.size:
        # growing modes: beyond e^{Re(lambda) T} = REACH_GROWTH_MAX every
        # sample lines up with the fastest mode and the zonotope's width
        # across it drowns in round-off: not resolvable in floating point
        growth = spectral_abscissae(A[rest]) * T
        lost = rest[growth > math.log(REACH_GROWTH_MAX)]
        value[lost], error[lost] = np.nan, np.inf
        rest = rest[growth <= math.log(REACH_GROWTH_MAX)]
    if rest.size:
        K = reach_nodes(p)
        if facet_work(K * m, p) > REACH_MAX_FACET_WORK:
            # too many facet candidates to enumerate (the set of them alone
            # would not fit in memory): not computed
            value[rest], error[rest], intervals[rest] = np.nan, np.nan, 0
            rest = rest[:0]
    if rest.size:
        intervals[rest] = K
        block = max(1, QUADRATURE_BLOCK_BYTES // (8 * n * (K + 1) * m))
        for i in range(0, rest.size, block):
            j = rest[i : i + block]
            value[j], error[j] = _quadrature(A[j], B[j], Cw[j], mid[j], half[j], T, K)
    overflow = ~(np.isfinite(value) & np.isfinite(error)) & ~np.isnan(error)
    value[overflow], error[overflow] = np.nan, np.inf
    return ReachMargins(np.maximum(value, 0.0), error, intervals)


def reach_margin(A, B, C, lower, upper, horizon: float, weight=None) -> tuple[float, float]:
    """:func:`reach_margins` of one system: (r_T, error estimate).

    Args:
        A: (n, n); B: (n, m); C: (p, n); lower, upper: (m,); horizon: T [s];
        weight: (p,) or None.
    """
    r = reach_margins(
        A[None], B[None], C[None], np.asarray(lower)[None], np.asarray(upper)[None], horizon, weight
    )
    return float(r.value[0]), float(r.error[0])


def _quadrature(A, B, Cw, mid, half, T: float, K: int):
    """Simpson's r_T on K intervals (K a multiple of 4) and the estimate
    ``|r(K) - r(K/2)|`` of its error, for k systems."""
    k, n, m = B.shape
    X = state_samples(A, B, np.full(k, T), K + 1)  # (k, n, (K+1) m)
    G = (Cw @ X).reshape(k, Cw.shape[1], K + 1, m)  # [:, :, i, j] = W C e^{A t_i} b_j
    values = []
    for step in (1, 2):
        Gs = G[:, :, ::step] * simpson_weights(K // step, T)[:, None]
        if not np.any(Gs[:, :, 0]):  # C B = 0 (mechanical systems): drop t = 0
            Gs = Gs[:, :, 1:]
        # summed per system in the same order whatever k (einsum's order
        # depends on k: a pose's margin changed in its last bit with the
        # block it was computed in)
        center = (Gs * mid[:, None, None, :]).sum(axis=(2, 3))
        # generators input-major: each input's samples in time form a run
        D = np.swapaxes(Gs * half[:, None, None, :], 2, 3).reshape(k, Gs.shape[1], -1)
        values.append(zonotope_inradii(D, center, group=Gs.shape[2]))
    return values[0], np.abs(values[0] - values[1])


def facet_work(generators: int, p: int) -> float:
    """Work of the facet search of a zonotope with ``generators`` generators
    in R^p: C(N, p-1) candidate normals times (N + p)."""
    return math.comb(generators, max(p - 1, 0)) * float(generators + p)


def simpson_weights(K: int, T: float) -> np.ndarray:
    """Composite Simpson weights of the K + 1 nodes ``t_i = i T / K`` (K even)."""
    h = T / K
    w = np.full(K + 1, 2 * h / 3)
    w[1::2] = 4 * h / 3
    w[0] = w[-1] = h / 3
    return w


def zonotope_inradii(D: np.ndarray, center: np.ndarray, group: int = 1) -> np.ndarray:
    """Inradius about 0 of the zonotopes ``{c + D s : |s_i| <= 1}``.

    The least ``sum_l |n . d_l| - |n . c|`` over unit normals n of
    hyperplanes spanned by p - 1 generators (the facet normals), clipped at
    0: the distance from 0 to the boundary when 0 is inside, else 0. A
    zonotope whose generators do not span R^p has inradius 0, and so has
    one whose inradius is below REACH_ZERO_RTOL times the sum of its
    generators' lengths (round-off).

    The search is compiled (cdpm.analysis._zonotope_kernel); it skips a
    candidate as soon as a partial sum shows it cannot be the least, which
    leaves the result unchanged.

    Args:
        D: generators, shape (k, p, N).
        center: centres, shape (k, p).
        group: a hint that consecutive runs of this many generators point
            mostly the same way (one input's samples in time): their sums
            give a cheap lower bound that rules out most candidates. Any
            value gives the same result; 1 or a value not dividing N: no
            bound.

    Returns:
        Shape (k,).
    """
    k, p, N = D.shape
    size = np.sqrt((D * D).sum(axis=1)).sum(axis=1)  # (k,)
    if p == 1:
        r = np.abs(D[:, 0]).sum(axis=1) - np.abs(center[:, 0])
        return np.where(r > REACH_ZERO_RTOL * size, r, 0.0)
    if N < p - 1 or k == 0:
        return np.zeros(k)
    from cdpm.analysis._zonotope_kernel import facet_inradii  # numba: loaded on use

    r = facet_inradii(
        np.ascontiguousarray(D, dtype=float),
        np.ascontiguousarray(center, dtype=float),
        ZONOTOPE_NORMAL_RTOL,
        group if N % group == 0 else 1,
    )
    r = np.where(np.isposinf(r), 0.0, r)  # no valid candidate: generators do not span
    return np.where(r > REACH_ZERO_RTOL * size, r, 0.0)  # NaN (overflow) and round-off: 0
