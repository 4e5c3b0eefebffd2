"""The POC margin: a continuous index of how robustly POC holds.

docs/analysis.md, the margin:

    mu_T = min_{|v|=1} max_{t in [0, T], j} v^T W C e^{At} b_j s_j

(``s`` input scales, ``W`` output weights, free inputs with both signs):
the inradius about 0 of ``H_T = conv{g_j(t) : t in [0, T], j}`` when 0 is
interior to it, minus the distance from 0 to ``H_T`` otherwise (0 on its
boundary). ``H_T`` is the set of outputs reachable at T with unit total
input impulse.

Everything here is a continuous function of (A, B, C, s, W):

- the horizon (:func:`margin_horizon`) is a continuous function of the
  spectrum and of ``|A|_2`` (no sampled search, no pivoting);
- the curve is sampled on a fixed grid ``t_k = k T / N`` (N fixed per p) by
  stepping with ``e^{A T / N}`` (doubling: ``[X, E X]``, ``E <- E^2``);
- the signed inradius of the sampled hull is computed exactly for p <= 3
  (planar hulls by a quickhull over many clouds at once, spatial hulls by
  Qhull) and bracketed by
  2p small LPs for p >= 4 (:func:`cdpm.analysis._span_hull.cross_polytope_radius`).

The sampled hull lies inside ``H_T`` (its points are curve points), so the
sampled value is a lower bound of mu_T; ``H_T`` lies within ``lip h / 2``
of it (``lip`` a Lipschitz bound of g on the grid, ``h`` the step), which
gives the upper end of the bracket.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from cdpm.analysis._common import expm_batch
from cdpm.analysis._span_hull import cross_polytope_radius, min_norm_separator
from cdpm.numerics import (
    GRID_POINTS,
    GRID_POINTS_HIGH,
    HORIZON_GIVEN_MAX_UNITS,
    HORIZON_MAX_UNITS,
    LOG_GROWTH,
    LOG_GROWTH_HIGH,
    SEE_PERIODS,
    WHITEN_REGULAR_RTOL,
)

# SEE_PERIODS: three undamped periods (6 pi / |lambda|, as the search
# horizon), or 6 pi time constants of a real mode; HORIZON_MAX_UNITS: the
# longest margin horizon, in units of 1/|A|_2; LOG_GROWTH: the largest growth
# e^{Re(lambda) T} of a sampled response per p (1e8 as the modal path for
# p <= 2; Qhull (p = 3) and the LP bracket (p >= 4) lose the hull's small
# features next to a larger dynamic range); GRID_POINTS: time samples (grid
# points t_0 = 0 .. t_N = T, a power of 2) per output dimension


def margin_horizon(
    A: np.ndarray, B: np.ndarray | None = None, C: np.ndarray | None = None
) -> float:
    """Default horizon T of the margin, a continuous function of (A, B, C) [time].

    Two time units: ``T0 = 1 / |A|_2`` (the least horizon; 1 for the
    zero-tension mechanical ``A = [[0, I], [0, 0]]``) and
    ``tau = 1 / s`` with ``s = max(|A^2|_2^(1/2), |A|_2^(1/2))``, the scale
    of the dynamics (``s >= rho(A)``; for ``A = [[0, I], [K, 0]]``,
    ``s = max(1, |K|^(1/2))``: a stiff mode's rate, where ``|A|_2 = |K|``
    would make tau far too short). With ``mu_i = lambda_i tau``
    (``|mu_i| <= 1``):

    - each mode asks for ``x = 6 pi / |mu_i|`` units of tau (three periods
      of an undamped oscillation, as the search horizon; 6 pi time constants
      of a real mode);
    - each input asks for ``x = 2 |C b_j| / |C A b_j|`` (the time at which
      the drift of ``g_j(t) = C b_j + t C A b_j + ...`` has turned it past 0);
    - a request x beyond ``R = 1000`` units cannot be seen: it tapers as
      ``R (2R / x - 1)`` to 0 at 2R (a mode that slow is polynomial over the
      horizon, like an integrator, whose directions appear at any t > 0), so
      the rule is continuous through ``lambda -> 0`` and ``C A b_j -> 0``;

    then ``T = min(max(T0, tau x_i), tau R, ln(1e8) / max_i Re lambda_i)``,
    the last term (growing systems only) keeping the growth of the sampled
    responses below 1e8 (1e6 for p = 3 and 1e4 for p >= 4: Qhull and the
    LP bracket lose the hull's small features next to a larger dynamic
    range). For A = [[0, I], [0, 0]] with C B = 0 (a mechanical system at
    zero tension) T = 1.

    Args:
        A: state matrix, shape (n, n), finite.
        B: input matrix (n, m), optional (with C).
        C: output matrix (p, n), optional (with B).

    Returns:
        T > 0 in the time unit of A (1 when A = 0).
    """
    B = None if B is None or C is None else B[None]
    C = None if B is None else C[None]
    return float(margin_horizons(A[None], B, C)[0])


def margin_horizons(
    A: np.ndarray, B: np.ndarray | None = None, C: np.ndarray | None = None
) -> np.ndarray:
    """:func:`margin_horizon` of k systems at once.

    Args:
        A: state matrices, shape (k, n, n), finite.
        B: input matrices (k, n, m), optional (with C).
        C: output matrices (k, p, n), optional (with B).

    Returns:
        T, shape (k,).
    """
    k, n = A.shape[0], A.shape[-1]
    T = np.ones(k)
    if n == 0 or k == 0:
        return T
    norm = _norms2(A)
    AA = A @ A
    norm2 = _norms2(AA)
    live = norm > 0
    if not live.all():
        A, norm, norm2 = A[live], norm[live], norm2[live]
        B = None if B is None else B[live]
        C = None if C is None else C[live]
    tau = _time_units(norm, norm2)
    lam = np.linalg.eigvals(A * tau[:, None, None])  # (k, n)
    r = np.abs(lam)
    with np.errstate(divide="ignore"):
        units = _tapers(np.where(r > 0, SEE_PERIODS / r, np.inf)).max(axis=1)
    grow = np.maximum(lam.real.max(axis=1), 0.0)
    if B is not None and C is not None and B.shape[-1] and C.shape[-2]:
        CB = C @ B
        CAB = (C @ (A * tau[:, None, None])) @ B
        c0 = np.sqrt((CB * CB).sum(axis=1))  # (k, m)
        c1 = np.sqrt((CAB * CAB).sum(axis=1))
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.where(c1 > 0, 2 * c0 / c1, np.where(c0 > 0, np.inf, 0.0))
        units = np.maximum(units, _tapers(x).max(axis=1))
    Tl = np.maximum(1.0 / norm, tau * units)
    Tl = np.minimum(Tl, tau * HORIZON_MAX_UNITS)
    p = 2 if C is None else C.shape[-2]
    with np.errstate(divide="ignore"):
        cap = tau * log_growth_allowed(p) / grow
    Tl = np.where(grow > 0, np.minimum(Tl, cap), Tl)
    T[live] = Tl
    return T


def log_growth_allowed(p: int) -> float:
    """ln of the largest growth e^{Re(lambda) T} of the sampled responses
    that the margin resolves with ``p`` outputs (LOG_GROWTH, LOG_GROWTH_HIGH)."""
    return LOG_GROWTH.get(p, LOG_GROWTH_HIGH)


def longest_horizon(
    A: np.ndarray, p: int, log_growth: float | None = None
) -> tuple[float, float, float]:
    """The longest margin horizon a caller may give for a system with
    state matrix ``A`` (n, n) and ``p`` outputs [time of A], as two bounds:
    (HORIZON_GIVEN_MAX_UNITS time units tau of :func:`margin_horizon`, inf
    when A = 0; the time in which the fastest-growing mode grows by
    e^{log_growth} (default log_growth_allowed(p)), inf when no mode grows;
    that mode's rate max Re(lambda) [1/time], 0 if none grows)."""
    if not A.size or not A.any():
        return math.inf, math.inf, 0.0
    if log_growth is None:
        log_growth = log_growth_allowed(p)
    A = A[None]
    units = float(_time_units(_norms2(A), _norms2(A @ A))[0]) * HORIZON_GIVEN_MAX_UNITS
    rate = float(np.linalg.eigvals(A[0]).real.max(initial=0.0))
    return units, (log_growth / rate if rate > 0 else math.inf), rate


def _time_units(norm: np.ndarray, norm2: np.ndarray) -> np.ndarray:
    """tau = 1 / max(|A^2|_2^(1/2), |A|_2^(1/2)) from |A|_2 and |A^2|_2
    (each (k,), |A|_2 > 0): the time unit of :func:`margin_horizon`."""
    return 1.0 / np.maximum(np.sqrt(norm2), np.sqrt(norm))


def _norms2(X: np.ndarray) -> np.ndarray:
    """Spectral norms of the matrices X (k, r, c), shape (k,)."""
    if X.shape[-1] == 1 or X.shape[-2] == 1:
        return np.sqrt((X * X).sum(axis=(-2, -1)))
    return np.linalg.svd(X, compute_uv=False)[:, 0]


def _tapers(x: np.ndarray) -> np.ndarray:
    """Seeing times x (units of tau), elementwise: x if at most R, else
    tapered to 0 at 2R as ``R (2R / x - 1)`` (continuous; what cannot be
    seen within R is ignored)."""
    R = HORIZON_MAX_UNITS
    with np.errstate(divide="ignore", invalid="ignore"):
        tapered = np.where(x < 2 * R, R * (2 * R / x - 1.0), 0.0)
    return np.where(x <= R, x, tapered)


def grid_points(p: int) -> int:
    """Number of grid times (t_0 = 0 .. t_N = T) for p outputs."""
    return GRID_POINTS.get(p, GRID_POINTS_HIGH)


def sample_curve(A, Bw, Cw, T: float, points: int, square_zero: bool = False):
    """g(t_k) = Cw e^{A t_k} Bw at ``t_k = k T / (points - 1)``.

    Returns:
        (G, lip): G (p, points * m) with column ``k * m + j`` = g_j(t_k), and a
        Lipschitz bound of g on [0, T] (the largest ``|Cw A e^{At} b_j|``
        on the grid, times 1.1; 0 when A^2 = 0, where only the end points are
        returned: the curve is then a segment per input, points = 2).
    """
    if square_zero:
        X = np.hstack([Bw, Bw + T * (A @ Bw)])
        return Cw @ X, 0.0
    G, lip = sample_curves(A[None], Bw[None], Cw[None], np.array([T]), points)
    return G[0], float(lip[0])


def sample_curves(A, Bw, Cw, T: np.ndarray, points: int):
    """:func:`sample_curve` of k systems at once (none with A^2 = 0).

    Args:
        A: (k, n, n); Bw: (k, n, m); Cw: (k, p, n); T: horizons, shape (k,).
        points: grid times per system, t_0 = 0 .. t_{points-1} = T.

    Returns:
        (G (k, p, points * m), lip (k,)).
    """
    X = state_samples(A, Bw, T, points)
    G = Cw @ X
    D = (Cw @ A) @ X
    lip = 1.1 * np.sqrt((D * D).sum(axis=1).max(axis=1, initial=0.0))
    return G, lip


def state_samples(A: np.ndarray, Bw: np.ndarray, T: np.ndarray, points: int) -> np.ndarray:
    """x_j(t_k) = e^{A t_k} b_j at ``t_k = k T / (points - 1)`` for k systems.

    Steps with ``E = e^{A h}`` by doubling (``X <- [X, E X]``, ``E <- E^2``).

    Args:
        A: (k, n, n); Bw: (k, n, m); T: horizons, shape (k,).
        points: grid times per system, t_0 = 0 .. t_{points-1} = T (>= 2).

    Returns:
        X, shape (k, n, points * m), column ``k * m + j`` = x_j(t_k).
    """
    E = expm_batch(A * (T / (points - 1))[:, None, None])
    return stepped_samples(E, Bw, points)


def stepped_samples(E: np.ndarray, B: np.ndarray, points: int) -> np.ndarray:
    """``E^i b_j`` for i < points (``e^{A t_i} b_j`` at ``t_i = i h`` when
    ``E = e^{A h}``), by doubling (``X <- [X, E X]``, ``E <- E^2``).

    Args:
        E: (k, n, n); B: (k, n, m); points: how many powers (>= 1).

    Returns:
        X, shape (k, n, points * m), column ``i * m + j`` = E^i b_j.
    """
    k, n, m = B.shape
    X = np.empty((k, n, points * m))
    X[:, :, :m] = B
    done = m
    while done < X.shape[2]:
        step = min(done, X.shape[2] - done)
        np.matmul(E, X[:, :, :step], out=X[:, :, done : done + step])
        done += step
        if done < X.shape[2]:
            E = E @ E
    return X


def signed_inradius(S: np.ndarray, S_sym: np.ndarray | None = None) -> tuple[float, float]:
    """(lower, upper) bounds of ``mu = min_{|v|=1} max_i v^T s_i`` over the
    columns of S (p, k) and of +-S_sym (p, k2).

    mu is the inradius about 0 of the convex hull when 0 is interior, minus
    the distance from 0 to the hull otherwise. Exact (lower == upper) for
    p <= 3; for p >= 4 ``r1 / sqrt(p) <= mu <= upper`` with the
    cross-polytope radius r1 (2p LPs) when 0 is interior, exact otherwise.
    """
    p = S.shape[0]
    if S_sym is not None and S_sym.shape[1]:
        P = np.hstack([S, S_sym, -S_sym])
    else:
        P = S
        S_sym = None
    if p == 0:
        return math.inf, math.inf
    if P.shape[1] == 0:
        return 0.0, 0.0
    if p <= 2:
        mu = float(signed_inradii(P[None], P[None, :, :0])[0])
        return mu, mu
    if p == 3:
        mu = _spatial(P)
        return mu, mu
    d = _distance(P)
    if d > 0:
        return -d, -d
    r1, hi = cross_polytope_radius(S, S_sym)
    return r1 / math.sqrt(p), hi


def signed_inradii(S: np.ndarray, S_sym: np.ndarray) -> np.ndarray:
    """Lower bounds of :func:`signed_inradius` of k clouds at once.

    Args:
        S: points, shape (k, p, N1); S_sym: points used with both signs,
            shape (k, p, N2).

    Returns:
        Shape (k,); vectorised for p <= 2, one cloud at a time otherwise.
    """
    k, p = S.shape[0], S.shape[1]
    P = np.concatenate([S, S_sym, -S_sym], axis=2)
    if p == 0:
        return np.full(k, math.inf)
    if P.shape[2] == 0:
        return np.zeros(k)
    if p == 1:
        return np.minimum(P[:, 0].max(axis=1), -P[:, 0].min(axis=1))
    if p == 2:
        return planar_signed_inradii(P)
    return np.array([signed_inradius(S[i], S_sym[i])[0] for i in range(k)])


# --------------------------------------------------------------------------
# planar: quickhull from the extreme points in 16 directions, all clouds at once

#: 16 unit directions, counter-clockwise, shape (2, 16)
_DIRS = np.stack([np.cos(np.arange(16) * np.pi / 8), np.sin(np.arange(16) * np.pi / 8)])
#: clouds per block of :func:`planar_signed_inradii` (bounds its memory)
_PLANAR_BLOCK = 128


def planar_signed_inradii(P: np.ndarray) -> np.ndarray:
    """Signed inradius about 0 of the convex hull of each point cloud.

    Args:
        P: clouds of points in the plane, shape (k, 2, N), finite.

    Returns:
        Shape (k,): the distance from 0 to the nearest hull edge line when 0
        is interior to the hull, else minus the distance from 0 to the hull.
    """
    out = np.empty(P.shape[0])
    for start in range(0, P.shape[0], _PLANAR_BLOCK):
        block = P[start : start + _PLANAR_BLOCK]
        pose, pa, pb = _hull_edges(block)
        out[start : start + block.shape[0]] = _edges_signed_inradius(block, pose, pa, pb)
    return out


def _hull_edges(P: np.ndarray):
    """Counter-clockwise hull edges of each cloud of P (k, 2, N), as flat
    arrays (cloud (E,), start point (E, 2), end point (E, 2)).

    Quickhull for all clouds at once: the extreme points in 16 directions of
    each whitened cloud are hull vertices in counter-clockwise order; a
    point outside their polygon is assigned to the edge it lies farthest
    outside of (the others are inside the hull); then every edge with
    points assigned is split at the farthest one and its points are handed
    to the two new edges, until no edge has any. Points on an edge line
    are not vertices. Every round makes at least one candidate a vertex and
    drops it (its side of both new edges is exactly 0), so the loop ends.
    A cloud whose hull is a point has no edge.
    """
    k = P.shape[0]
    s = np.argmax(np.swapaxes(_whitened_directions(P), 1, 2) @ P, axis=2)  # (k, D) extreme points
    pa = np.take_along_axis(P, s[:, None, :], axis=2).transpose(0, 2, 1)  # (k, D, 2)
    pb = np.roll(pa, -1, axis=1)
    normal = np.stack([pa[..., 1] - pb[..., 1], pb[..., 0] - pa[..., 0]], axis=2)
    # cross(b - a, p - a) = normal . (p - a): positive on the inner side
    side = normal @ P - np.einsum("kdi,kdi->kd", normal, pa)[..., None]  # (k, D, N)
    # repeated extreme points (equal coordinates) make no edge
    point_edge = np.all(pa == pb, axis=2)  # (k, D)
    side[np.broadcast_to(point_edge[..., None], side.shape)] = np.inf
    edge = np.argmin(side, axis=1)  # (k, N): the edge each point is farthest outside of
    outside = np.take_along_axis(side, edge[:, None], axis=1)[:, 0] < 0
    cloud, point = np.nonzero(outside)
    D = s.shape[1]
    ids = np.full(k * D, -1)
    flat = ~point_edge.reshape(-1)
    ids[flat] = np.arange(int(flat.sum()))
    pose = np.repeat(np.arange(k), D)[flat]
    pa, pb = pa.reshape(-1, 2)[flat], pb.reshape(-1, 2)[flat]
    owner = ids[cloud * D + edge[cloud, point]]  # (M,) candidate -> edge
    pts = P[cloud, :, point]  # (M, 2)
    done = [(pose[:0], pa[:0], pb[:0])]
    while pose.size:
        side = _sides(pa[owner], pb[owner], pts)
        out = side < 0  # (the first assignment's sides are computed otherwise)
        owner, pts, side = owner[out], pts[out], side[out]
        best = np.full(pose.size, np.inf)
        np.minimum.at(best, owner, side)
        has = np.isfinite(best)  # edges with points outside: split
        done.append((pose[~has], pa[~has], pb[~has]))
        # the farthest point of each split edge (the first one on ties)
        hit = np.flatnonzero(side == best[owner])
        first = hit[np.unique(owner[hit], return_index=True)[1]]
        pc = np.empty((pose.size, 2))
        pc[owner[first]] = pts[first]
        # split edge e (new index j) -> (a, c) as j and (c, b) as n_split + j
        split = np.flatnonzero(has)
        new = np.full(pose.size, -1)
        new[split] = np.arange(split.size)
        pose = np.concatenate([pose[split], pose[split]])
        pa, pb = np.concatenate([pa[split], pc[split]]), np.concatenate([pc[split], pb[split]])
        # hand each point to the new edge it lies outside of
        j = new[owner]
        left = _sides(pa[j], pb[j], pts) < 0
        go = left | (_sides(pa[j + split.size], pb[j + split.size], pts) < 0)
        owner = np.where(left, j, j + split.size)[go]
        pts = pts[go]
    return tuple(np.concatenate(parts) for parts in zip(*done, strict=True))


def _sides(pa: np.ndarray, pb: np.ndarray, p: np.ndarray) -> np.ndarray:
    """cross(b - a, p - a) of points a, b, p (M, 2): positive on the left
    (inner) side of a -> b."""
    ex, ey = pb[:, 0] - pa[:, 0], pb[:, 1] - pa[:, 1]
    return ex * (p[:, 1] - pa[:, 1]) - ey * (p[:, 0] - pa[:, 0])


def _whitened_directions(P: np.ndarray) -> np.ndarray:
    """The 16 directions of each cloud in its whitened coordinates, mapped
    back (support in direction d of ``z = L^-1 x``, ``P P^T = L L^T``, is
    support in direction ``L^-T d`` of x), shape (k, 2, 16): long thin
    clouds (growing systems) still get 16 distinct extreme points. Clouds
    without a regular second moment keep the plain directions."""
    a = np.einsum("kn,kn->k", P[:, 0], P[:, 0])
    b = np.einsum("kn,kn->k", P[:, 0], P[:, 1])
    c = np.einsum("kn,kn->k", P[:, 1], P[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        l11 = np.sqrt(a)
        l21 = b / l11
        d2 = c - l21 * l21
        l22 = np.sqrt(d2)
        regular = (a > 0) & (d2 > WHITEN_REGULAR_RTOL * c)
        one = np.ones_like(a)
        m11 = np.where(regular, 1 / l11, one)
        m12 = np.where(regular, -l21 / (l11 * l22), 0.0)
        m22 = np.where(regular, 1 / l22, one)
    dx, dy = _DIRS
    return np.stack([m11[:, None] * dx + m12[:, None] * dy, m22[:, None] * dy + 0 * dx], axis=1)


def _edges_signed_inradius(P: np.ndarray, pose, pa, pb) -> np.ndarray:
    """Signed inradius about 0 of each cloud of P (k, 2, N) from its
    counter-clockwise hull edges (flat arrays cloud, start, end)."""
    k = P.shape[0]
    (ax, ay), (dx, dy) = pa.T, (pb - pa).T
    length = np.hypot(dx, dy)
    # distance of 0 to each edge line, positive on the inner side
    offset = (ax * dy - ay * dx) / length
    inner = np.full(k, np.inf)
    np.minimum.at(inner, pose, offset)
    edges = np.bincount(pose, minlength=k)
    # 0 outside or on the boundary: minus its distance to the edges
    t = np.clip(-(ax * dx + ay * dy) / length**2, 0.0, 1.0)
    gap = np.full(k, np.inf)
    np.minimum.at(gap, pose, np.hypot(ax + t * dx, ay + t * dy))
    point = edges == 0  # the hull is a point
    gap[point] = np.hypot(P[point, 0, 0], P[point, 1, 0])
    return np.where((edges >= 3) & (inner > 0), inner, -gap)


# --------------------------------------------------------------------------
# spatial: Qhull


def _spatial(P: np.ndarray) -> float:
    """Signed inradius about 0 of conv of the columns of P (3, k)."""
    try:
        hull = ConvexHull(P.T)
    except QhullError:  # flat or degenerate: 0 is never interior
        return -_distance(P)
    off = hull.equations[:, -1]  # unit outward normals: n.x + off <= 0 inside
    if np.all(off < 0):
        return float(-off.max())
    return -_distance(P[:, hull.vertices])


def _distance(P: np.ndarray) -> float:
    """Distance from 0 to conv of the columns of P (least-distance
    programming by NNLS on the points scaled to unit size)."""
    scale = float(np.abs(P).max())
    if not scale > 0:
        return 0.0
    sep = min_norm_separator(P / scale)
    return 0.0 if sep is None else float(sep[1]) * scale
