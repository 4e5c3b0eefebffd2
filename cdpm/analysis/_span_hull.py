"""The convex hull of a vector set about 0: the min-norm point (a
separator and the distance from 0 to the hull), and the margin index of a
positive-span decision, bounds of ``mu = min_{|v|=1} max_i v^T s_i`` (the
inradius about 0 of conv(S) when the vectors positively span, minus the
distance from 0 to conv(S) when not), read by
:attr:`cdpm.analysis.span.SpanResult.margin_bracket` and by the POC margin
(:mod:`cdpm.analysis.margin`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linprog, nnls
from scipy.spatial import ConvexHull, QhullError

from cdpm.analysis._common import in_norm_range
from cdpm.numerics import HULL_ZERO_RTOL, LDP_ZERO_ATOL, POLAR_LP_PRIMAL_TOL

__all__ = ["min_norm_separator", "span_margin", "span_margin_bracket", "cross_polytope_radius"]


def min_norm_separator(S: np.ndarray):
    """Unit v maximising min_i (-v^T s_i), i.e. -(the min-norm point of
    conv S) normalised (least-distance programming by NNLS, Lawson-Hanson
    ch. 23). Returns (v, dist) with dist = distance from 0 to conv S, or
    None if 0 is in conv S."""
    p, k = S.shape
    E = np.vstack([S, np.ones((1, k))])
    f = np.zeros(p + 1)
    f[p] = 1.0
    u, _ = nnls(E, f, maxiter=50 * k + 100)
    r = E @ u - f
    if abs(r[p]) < LDP_ZERO_ATOL or np.linalg.norm(r[:p]) < LDP_ZERO_ATOL:
        return None
    x = -r[:p] / r[p]
    nx = float(np.linalg.norm(x))
    return -x / nx, 1.0 / nx


def span_margin(S: np.ndarray, yes: bool) -> float:
    """The margin index of :class:`SpanResult` (lower end of the bracket)."""
    return span_margin_bracket(S, yes)[0]


def span_margin_bracket(
    S: np.ndarray, yes: bool, S_sym: np.ndarray | None = None
) -> tuple[float, float]:
    """(lower, upper) bounds of ``mu = min_{|v|=1} max_i v^T s_i``.

    ``S_sym`` (p, k2), optional: vectors that count with both signs (free
    inputs), given once; the LPs then use two-sided constraints instead of
    duplicated opposite ones (which make the active-set solver cycle).

    NO: ``-dist(0, conv S)`` exactly (one NNLS). YES with p <= 3: exactly
    mu, the smallest facet offset of conv(S) (a convex hull in the plane or
    in space costs O(k log k)). YES with p >= 4: ``(r1 / sqrt(p), hi)`` with
    ``r1`` the cross-polytope radius (:func:`cross_polytope_radius`) and
    ``hi <= r1`` the best support value ``max_i v^T s_i / |v|`` among the LP
    solutions (a hull in R^p has up to k^(p/2) facets: never built).
    """
    c = in_norm_range(S if S_sym is None else np.hstack([S, S_sym]))[1]
    if c != 1.0:  # mu scales with the vectors: computed where squares do not under- or overflow
        scaled = span_margin_bracket(S * c, yes, None if S_sym is None else S_sym * c)
        return scaled[0] / c, scaled[1] / c
    p = S.shape[0]
    if S_sym is None:
        S_sym = np.zeros((p, 0))
    full = np.hstack([S, S_sym, -S_sym]) if S_sym.shape[1] else S
    k = full.shape[1]
    if p == 0:
        return math.inf, math.inf
    if k == 0:
        return 0.0, 0.0
    if p == 1:
        mu = float(min(full.max(), -full.min()))
        return mu, mu
    if not yes:
        sep = min_norm_separator(full)
        mu = 0.0 if sep is None else -float(sep[1])
        return mu, mu
    if p <= 3:
        norms = np.linalg.norm(full, axis=0)
        try:
            hull = ConvexHull(full[:, norms > HULL_ZERO_RTOL * norms.max()].T)
            mu = float(max(np.min(-hull.equations[:, -1]), 0.0))
            return mu, mu
        except QhullError:  # degenerate input: the LP bracket below
            pass
    r1, hi = cross_polytope_radius(S, S_sym)
    return r1 / math.sqrt(p), hi


def cross_polytope_radius(S: np.ndarray, S_sym: np.ndarray | None = None) -> tuple[float, float]:
    """Largest r with ``{y : |y|_1 <= r}`` inside conv(S), and an upper bound
    of the inradius ``mu``.

    Polar duality: the cross-polytope of radius r lies in conv(S) iff the
    polar ``P = {v : S^T v <= 1}`` lies in the cube ``|v|_inf <= 1/r``, so
    ``r = 1 / max_{v in P} |v|_inf``: 2p LPs in p variables with k
    constraints (DAQP, dual active set; HiGHS if it fails). Every LP solution
    v also gives ``mu <= max_i v^T s_i / |v|``. Since ``r e_i`` lies in
    conv(S), ``mu <= r``, and the Euclidean ball of radius ``r / sqrt(p)``
    lies in the cross-polytope, so ``r / sqrt(p) <= mu``.

    ``S_sym`` columns count with both signs (``|s^T v| <= 1``).

    Returns:
        (r, hi); (0, 0) when 0 is not interior to conv(S).
    """
    p = S.shape[0]
    if S_sym is None:
        S_sym = np.zeros((p, 0))
    both = np.hstack([S, S_sym])
    norms = np.linalg.norm(both, axis=0)
    scale = float(norms.max()) if norms.size else 0.0
    if scale == 0:
        return 0.0, 0.0
    # zero vectors add only 0 <= 1 constraints
    keep = norms > HULL_ZERO_RTOL * scale
    G = np.ascontiguousarray(both[:, keep].T / scale)  # (k, p)
    lower = np.where(np.arange(both.shape[1]) >= S.shape[1], -1.0, -1e30)[keep]
    vmax, hi = 0.0, math.inf
    for i in range(p):
        for sign in (1.0, -1.0):
            x = _polar_lp(G, lower, i, sign)
            if x is None:
                return 0.0, 0.0
            val = sign * x[i]
            if not val > 0:
                return 0.0, 0.0
            # the solver meets S^T x <= 1 to ~1e-9: rescale to feasible first
            gx = G @ x
            support = float(
                max(np.max(gx), np.max(np.where(lower > -1.0 - POLAR_LP_PRIMAL_TOL, -gx, -np.inf)))
            )
            x = x / max(support, 1.0)
            vmax = max(vmax, sign * x[i])
            hi = min(hi, support / float(np.linalg.norm(x)) / max(support, 1.0))
    r = 1.0 / vmax
    return r * scale, min(hi, r) * scale


def _polar_lp(G: np.ndarray, lower: np.ndarray, i: int, sign: float):
    """argmax sign * v_i subject to lower <= G v <= 1 (G (k, p)), or None if
    unbounded (``lower`` is -1 on two-sided rows, -1e30 elsewhere)."""
    k, p = G.shape
    f = np.zeros(p)
    f[i] = -sign
    try:
        # daqp: loaded on first use
        import daqp
    except ImportError:  # pragma: no cover - daqp is a core dependency
        daqp = None
    if daqp is not None:
        H, lo, up = np.zeros((p, p)), lower, np.ones(k)
        # default proximal step first; a larger one when degenerate
        # (duplicate or near-parallel constraints) makes it cycle
        for eps in (-1e-6, 1e-3):
            x, _, flag, _ = daqp.solve(
                H, f, G, up, lo, primal_tol=POLAR_LP_PRIMAL_TOL, fval_bound=1e12, eps_prox=eps
            )
            if flag >= 1 and np.all(np.isfinite(x)):
                return np.asarray(x, dtype=float)
            if flag in (-1, -3):
                # v = 0 is feasible, so this reports a (nearly) unbounded
                # polar; near-degenerate hulls are told apart by HiGHS
                break
    two = lower > -1e29
    res = linprog(
        f,
        A_ub=np.vstack([G, -G[two]]),
        b_ub=np.ones(k + int(two.sum())),
        bounds=[(None, None)] * p,
        method="highs",
    )
    return res.x if res.status == 0 else None
