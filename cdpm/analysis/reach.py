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
with ``s_j(t) = v^T W C e^{A t} b_j``. Inputs constant on each of K equal
intervals of [0, T] reach a zonotope Z inside R_T (one generator per input
and interval, the exact integral ``int W C e^{A t} b_j dt`` over it, from
one exponential of ``[[A, I], [0, 0]] T / K``), whose inradius about 0 is
computed exactly: the least ``sum_l |n . d_l| - |n . c|`` over the normals
n of its facets (hyperplanes spanned by p - 1 generators). It is the
reported value, a lower bound of r_T (Z is inside R_T). In the direction v
of that facet ``r_T <= h(v)``, and ``h(v) - h_Z(v)`` is the sum over
intervals and inputs of Jensen gaps ``(upper_j - lower_j) min(P, N)`` (P, N
the integrals of the positive and negative parts of s_j there), 0 unless
s_j changes sign in the interval; P and N are bounded from s_j and its
first two derivatives at the interval's ends and a bound of its third
derivative from the modes of A. That bound, plus round-off, is the reported
error: the exact r_T lies in ``[value, value + error]``. When ``A^2 = 0``
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

from cdpm.analysis._common import expm_batch, spectral_abscissae, square_zero
from cdpm.analysis.margin import stepped_samples
from cdpm.numerics import (
    REACH_GROWTH_MAX,
    REACH_MAX_FACET_WORK,
    REACH_NODES,
    REACH_NODES_HIGH,
    REACH_ZERO_RTOL,
    ZONOTOPE_BOUND_RTOL,
    ZONOTOPE_NORMAL_RTOL,
)

__all__ = ["ReachMargins", "reach_margins", "reach_margin", "zonotope_inradii", "reach_nodes"]

#: the reach margin's error bound: where the bound of the third derivative
#: from norms of A leaves a gap above this times the value, it is also
#: bounded from the modes of A (an eigen-decomposition per pose)
GAP_REFINE_RTOL = 1e-3

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
        error: a bound of |value - exact r_T|, shape (k,): on the
            quadrature path the exact r_T lies in ``[value, value + error]``
            (value is a lower bound); where ``A^2 = 0`` the bound of the
            C B term (0 for position outputs).
        intervals: quadrature intervals K per system, shape (k,).
    """

    value: np.ndarray
    error: np.ndarray
    intervals: np.ndarray


def reach_nodes(p: int) -> int:
    """Time intervals K (a multiple of 4) for p outputs: the zonotope has
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
        :class:`ReachMargins` (value, error bound, intervals); value NaN
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
        K = fitting_intervals(m, p)
        if K == 0:
            # too many facet candidates to enumerate even on the fewest
            # intervals (the set of them alone would not fit in memory):
            # not computed
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
    """:func:`reach_margins` of one system: (r_T, error bound).

    Args:
        A: (n, n); B: (n, m); C: (p, n); lower, upper: (m,); horizon: T [s];
        weight: (p,) or None.
    """
    r = reach_margins(
        A[None], B[None], C[None], np.asarray(lower)[None], np.asarray(upper)[None], horizon, weight
    )
    return float(r.value[0]), float(r.error[0])


def fitting_intervals(m: int, p: int) -> int:
    """Time intervals K for m inputs and p outputs: :func:`reach_nodes`,
    or fewer (a multiple of 4, at least REACH_NODES_HIGH) where the facet
    search of m K generators would exceed REACH_MAX_FACET_WORK (many
    cables: a looser but still valid bracket, a larger error bound); 0
    where even the fewest do not fit (r_T not computed)."""
    for K in range(reach_nodes(p), REACH_NODES_HIGH - 1, -4):
        if facet_work(K * m, p) <= REACH_MAX_FACET_WORK:
            return K
    return 0


def _quadrature(A, B, Cw, mid, half, T: float, K: int):
    """r_T of k systems bracketed on K intervals of [0, T]: (value, error)
    with the exact r_T in ``[value, value + error]`` (module docstring).

    value: the inradius of the zonotope reachable with inputs constant on
    each interval (exact interval integrals, a subset of R_T). error: in the
    direction v of that inradius, a bound of ``h(v) - value``, the Jensen gap
    of each interval and input, which is not 0 only where ``s_j = v . g_j``
    changes sign (bounded from s_j and its first two derivatives at the
    interval's ends and a bound of its third derivative), plus round-off.
    """
    k, n, m = B.shape
    p = Cw.shape[1]
    tau = T / K
    # e^{A tau} and Phi = int_0^tau e^{A s} ds from one exponential
    aug = np.zeros((k, 2 * n, 2 * n))
    aug[:, :n, :n] = A * tau
    aug[:, :n, n:] = tau * np.eye(n)
    E_Phi = expm_batch(aug)
    X = stepped_samples(E_Phi[:, :n, :n], B, K + 1)  # (k, n, (K+1) m): e^{A t_i} b_j
    # G[:, :, i, j] = int_{t_i}^{t_i+1} W C e^{A t} b_j dt = W C Phi e^{A t_i} b_j
    G = ((Cw @ E_Phi[:, :n, n:]) @ X[:, :, : K * m]).reshape(k, p, K, m)
    # summed per system in the same order whatever k (einsum's order
    # depends on k: a pose's margin changed in its last bit with the
    # block it was computed in)
    center = (G * mid[:, None, None, :]).sum(axis=(2, 3))
    # generators input-major: each input's intervals form a run
    D = np.swapaxes(G * half[:, None, None, :], 2, 3).reshape(k, p, K * m)
    inner, v = _inradii_and_directions(D, center, K)
    # h_in(v) = sum_ij max(upper_j v.G_ij, lower_j v.G_ij), the support
    # function of the inner zonotope in v (its inradius when v is its normal)
    area = (v[:, None, :] @ G.reshape(k, p, K * m)).reshape(k, K, m)  # int of s_j per interval
    h_in = (area * mid[:, None, :] + np.abs(area) * half[:, None, :]).reshape(k, K * m).sum(axis=1)
    gap = _jensen_gap(A, Cw, X, v, area, half, tau, K, inner)
    size = np.sqrt((D * D).sum(axis=1)).sum(axis=1)
    # below REACH_ZERO_RTOL times the generators' length: round-off, 0
    value = np.where(inner > REACH_ZERO_RTOL * size, inner, 0.0)
    upper = np.maximum(h_in + gap, value)
    shift = np.sqrt((center * center).sum(axis=1))
    error = upper - value + ZONOTOPE_BOUND_RTOL * (size + shift)  # round-off of the sums
    bad = ~(np.isfinite(inner) & np.isfinite(error))  # overflow: not resolvable
    return np.where(bad, np.nan, value), np.where(bad, np.inf, error)


def _inradii_and_directions(D, center, group: int):
    """The inradius about 0 of each zonotope ``{c + D s : |s_i| <= 1}``
    (raw: negative when 0 is outside, no round-off floor) and a unit
    direction v in which its support function ``v . c + sum_l |v . d_l|``
    equals it (where it spans R^p; else a direction across its span, where
    the inradius is 0)."""
    k, p, N = D.shape
    if p == 1:
        r = np.abs(D[:, 0]).sum(axis=1) - np.abs(center[:, 0])
        v = np.where(center < 0, 1.0, -1.0)
        return r, v
    from cdpm.analysis._zonotope_kernel import facet_inradii_normals  # numba: loaded on use

    r, v = facet_inradii_normals(
        np.ascontiguousarray(D, dtype=float),
        np.ascontiguousarray(center, dtype=float),
        ZONOTOPE_NORMAL_RTOL,
        group if N % group == 0 else 1,
    )
    flat = np.isposinf(r) | ~np.any(v, axis=1)
    for s in np.flatnonzero(flat & np.all(np.isfinite(D), axis=(1, 2))):
        # no facet found (the generators do not span R^p): across the span
        v[s] = np.linalg.svd(D[s])[0][:, -1]
        r[s] = np.abs(v[s] @ D[s]).sum() - abs(v[s] @ center[s])
    # the facet's side facing 0: there v . c = -|v . c|
    v = np.where((v * center).sum(axis=1)[:, None] > 0, -v, v)
    return r, v


def _jensen_gap(A, Cw, X, v, area, half, tau: float, K: int, value) -> np.ndarray:
    """A bound of ``h(v) - h_in(v)``, shape (k,).

    On interval i = [a, b] and input j, with ``s(t) = v . W C e^{A t} b_j``,
    ``area_ij`` its integral there and P, N the integrals of its positive and
    negative parts (P - N = area_ij), ``int max(upper s, lower s) -
    max(upper area, lower area) = (upper - lower) min(P, N)``: 0 unless s
    changes sign. P and N are bounded by the
    second-order envelopes ``s(a) + s'(a) t +- S2 t^2 / 2`` on the first half
    of the interval and ``s(b) - s'(b) t +- S2 t^2 / 2`` (t from b) on the
    second, with S2 a bound of ``|s''|`` there: ``|s''(t)| <= |s''(a)| + t S3``
    (and from b), S3 a bound of the third derivative: ``|v^T W C A^3 S|
    e^{|S^-1 A S|_F tau} min(|S^-1 x(a)|, |S^-1 x(b)|)`` with S a diagonal
    that balances A (``e^{A t} = S e^{S^-1 A S t} S^-1``), and where that
    leaves a gap above GAP_REFINE_RTOL times ``value`` (a direction v across
    a fast mode: the norms lose the cancellation) the least of it and the
    bound from the modes of A (:func:`_modal_third`).
    """
    k = A.shape[0]
    m = area.shape[2]
    row = v[:, None, :] @ Cw  # (k, 1, n): v^T W C
    rows = [row]
    for _ in range(3):
        rows.append(rows[-1] @ A)  # v^T W C A^d
    s, ds, dds = np.swapaxes((np.concatenate(rows[:3], axis=1) @ X).reshape(k, 3, K + 1, m), 0, 1)
    scale = _balance(A)  # (k, n): S = diag(scale)
    Xs = X / scale[:, :, None]
    x = np.sqrt((Xs * Xs).sum(axis=1)).reshape(k, K + 1, m)
    As = A * scale[:, None, :] / scale[:, :, None]  # S^-1 A S
    grow = np.exp(np.sqrt((As * As).sum(axis=(1, 2))) * tau)  # >= |e^{S^-1 A S t}|, t <= tau
    third = rows[3] * scale[:, None, :]
    third = np.sqrt((third * third).sum(axis=(1, 2))) * grow  # (k,)
    S3 = third[:, None, None] * np.minimum(x[:, :-1], x[:, 1:])
    data = (s, ds, dds, area, np.broadcast_to(half[:, None, :], area.shape))
    gap = _gap(*data, S3, tau)
    loose = np.flatnonzero(~(gap <= GAP_REFINE_RTOL * np.abs(value)))
    if loose.size:
        modal = _modal_third(A[loose], row[loose], X[loose, :, :m], tau, K)
        S3 = np.minimum(S3[loose], modal)
        gap[loose] = np.minimum(gap[loose], _gap(*(d[loose] for d in data), S3, tau))
    return gap


def _gap(s, ds, dds, area, half, S3, tau: float) -> np.ndarray:
    """The sum of the Jensen gap bounds of :func:`_jensen_gap` per system,
    from s and its first two derivatives at the nodes (k, K + 1, m), the
    intervals' integrals (k, K, m), the inputs' half widths (k, K, m) and
    the bounds S3 of the third derivative (k, K, m)."""
    k, K, m = area.shape
    dda, ddb = np.abs(dds[:, :-1]), np.abs(dds[:, 1:])
    S2 = np.minimum((dda + ddb + tau * S3) / 2, np.minimum(dda, ddb) + tau * S3)
    sa, sb, da, db = s[:, :-1], s[:, 1:], ds[:, :-1], ds[:, 1:]
    w = tau / 2
    # s may change sign only where the envelopes reach 0 (few intervals)
    reach = S2 * (w * w / 2)
    may = (sa * sb <= 0) | (np.abs(sa) <= np.abs(da) * w + reach)
    may |= np.abs(sb) <= np.abs(db) * w + reach
    gap = np.zeros((k, K, m))
    if may.any():
        sa, sb, da, db, S2, area = (x[may] for x in (sa, sb, da, db, S2, area))
        positive = _positive_part(sa, da, S2, w) + _positive_part(sb, -db, S2, w)  # >= P
        negative = _positive_part(-sa, -da, S2, w) + _positive_part(-sb, db, S2, w)  # >= N
        least = np.where(
            area >= 0, np.minimum(negative, positive - area), np.minimum(positive, negative + area)
        )
        gap[may] = 2 * half[may] * np.maximum(least, 0.0)
    return gap.reshape(k, K * m).sum(axis=1)


def _modal_third(A, row, B, tau: float, K: int) -> np.ndarray:
    """Bounds of the third derivative of s on ``[t_i, t_i + tau]`` (i < K),
    shape (k, K, m), from the modes of A: with ``A = W diag(lambda) W^-1``
    and ``c = W^-1 b_j``, ``s(t) = sum_l (row w_l) c_l e^{lambda_l t}``, so
    its third derivative is at most ``sum_l |row w_l| |c_l| |lambda_l|^3
    e^{Re lambda_l t_i} max(1, e^{Re lambda_l tau})``. Unlike a norm of A
    this keeps the cancellation in a direction v across a fast mode. inf
    where A has no eigenbasis or an ill-conditioned one (``|W|_F |W^-1|_F >
    1e6``: the eigen-decomposition's round-off could hide a term).
    """
    k, n, m = B.shape
    with np.errstate(all="ignore"):
        lam, W = np.linalg.eig(A)
        try:
            Winv = np.linalg.inv(W)
        except np.linalg.LinAlgError:  # some W singular: one system at a time
            Winv = np.full(W.shape, np.inf, dtype=complex)
            for i in range(k):
                try:
                    Winv[i] = np.linalg.inv(W[i])
                except np.linalg.LinAlgError:
                    continue
        rate = lam.real[:, None, :]  # (k, 1, n)
        times = tau * np.arange(K)[None, :, None]
        weights = (
            np.abs(row @ W) * np.abs(lam[:, None, :]) ** 3 * np.maximum(1.0, np.exp(rate * tau))
        )
        bound = (weights * np.exp(rate * times)) @ np.abs(Winv @ B)  # (k, K, m)
        condition = np.sqrt(
            (np.abs(W) ** 2).sum(axis=(1, 2)) * (np.abs(Winv) ** 2).sum(axis=(1, 2))
        )
    good = (condition <= 1e6)[:, None, None] & np.isfinite(bound)
    return np.where(good, bound, np.inf)


def _balance(A, sweeps: int = 6) -> np.ndarray:
    """Positive diagonals S (k, n) that roughly balance A (Osborne's
    iteration: the off-diagonal parts of row i and column i of S^-1 A S of
    equal length); any positive S keeps the bounds above valid."""
    k, n, _ = A.shape
    off = np.abs(A) * (1 - np.eye(n))
    scale = np.ones((k, n))
    for _ in range(sweeps):
        B = off * scale[:, None, :] / scale[:, :, None]
        rows, cols = B.sum(axis=2), B.sum(axis=1)
        ok = (rows > 0) & (cols > 0)
        scale = np.where(
            ok, scale * np.sqrt(np.where(ok, rows, 1.0) / np.where(ok, cols, 1.0)), scale
        )
    return scale


def _positive_part(c0, c1, c2, width: float):
    """``int_0^width max(0, c0 + c1 t + c2 t^2 / 2) dt`` for c2 >= 0, in
    closed form: the quadratic is negative only between its roots."""

    def primitive(t):
        return t * (c0 + t * (c1 / 2 + t * c2 / 6))

    disc = c1 * c1 - 2 * c2 * c0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = -(c1 + np.copysign(np.sqrt(np.maximum(disc, 0.0)), c1))  # no cancellation
        roots = np.stack([q / c2, 2 * c0 / q])  # c2 = 0: +-inf and the linear root
    roots = np.where(np.isnan(roots), np.inf, roots)
    r1 = np.clip(roots.min(axis=0), 0.0, width)
    r2 = np.clip(roots.max(axis=0), 0.0, width)
    split = primitive(r1) + (primitive(width) - primitive(r2))
    whole = primitive(width + 0.0 * c0)  # no sign change: >= 0 throughout
    return np.maximum(np.where(disc > 0, split, whole), 0.0)


def facet_work(generators: int, p: int) -> float:
    """Work of the facet search of a zonotope with ``generators`` generators
    in R^p: C(N, p-1) candidate normals times (N + p)."""
    return math.comb(generators, max(p - 1, 0)) * float(generators + p)


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
