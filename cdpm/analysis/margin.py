"""The POC margin: a continuous index of how robustly POC holds.

THEORY section 4:

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
  (planar hull by a monotone chain, spatial hull by Qhull) and bracketed by
  2p small LPs for p >= 4 (:func:`cdpm.analysis.span.cross_polytope_radius`).

The sampled hull lies inside ``H_T`` (its points are curve points), so the
sampled value is a lower bound of mu_T; ``H_T`` lies within ``lip h / 2``
of it (``lip`` a Lipschitz bound of g on the grid, ``h`` the step), which
gives the upper end of the bracket.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm
from scipy.spatial import ConvexHull, QhullError

from cdpm.analysis.span import cross_polytope_radius, min_norm_separator

#: three undamped periods (6 pi / |lambda|, as the search horizon), or
#: 6 pi time constants of a real mode
SEE_PERIODS = 6 * math.pi
#: longest margin horizon, in units of 1/|A|_2
HORIZON_MAX_UNITS = 1e3
#: largest growth e^{Re(lambda) T} of a sampled response per p (1e8 as the
#: modal path for p <= 2; Qhull (p = 3) and the LP bracket (p >= 4) lose
#: the hull's small features next to a larger dynamic range)
LOG_GROWTH = {1: math.log(1e8), 2: math.log(1e8), 3: math.log(1e6)}
LOG_GROWTH_HIGH = math.log(1e4)
#: time samples (grid points t_0 = 0 .. t_N = T, a power of 2) per output dimension
GRID_POINTS = {1: 256, 2: 64, 3: 32}
GRID_POINTS_HIGH = 64


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
    tau = 1.0 / np.maximum(np.sqrt(norm2), np.sqrt(norm))
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
        cap = tau * LOG_GROWTH.get(p, LOG_GROWTH_HIGH) / grow
    Tl = np.where(grow > 0, np.minimum(Tl, cap), Tl)
    T[live] = Tl
    return T


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
    k, n, m = Bw.shape
    # step with e^{A h}, doubling: X <- [X, E X], E <- E^2
    E = expm(A * (T / (points - 1))[:, None, None])
    X = np.empty((k, n, points * m))
    X[:, :, :m] = Bw
    done = m
    while done < X.shape[2]:
        step = min(done, X.shape[2] - done)
        np.matmul(E, X[:, :, :step], out=X[:, :, done : done + step])
        done += step
        if done < X.shape[2]:
            E = E @ E
    G = Cw @ X
    D = (Cw @ A) @ X
    lip = 1.1 * np.sqrt((D * D).sum(axis=1).max(axis=1, initial=0.0))
    return G, lip


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
    if p == 1:
        mu = float(min(P.max(), -P.min()))
        return mu, mu
    if p == 2:
        mu = _planar(P)
        return mu, mu
    if p == 3:
        mu = _spatial(P)
        return mu, mu
    d = _distance(P)
    if d > 0:
        return -d, -d
    r1, hi = cross_polytope_radius(S, S_sym)
    return r1 / math.sqrt(p), hi


# --------------------------------------------------------------------------
# planar: monotone chain on the points outside an inner polygon

_DIRS = np.exp(1j * np.linspace(0.0, 2 * np.pi, 16, endpoint=False))
_DIRS = np.stack([_DIRS.real, _DIRS.imag])  # (2, 16), counter-clockwise


def _planar(P: np.ndarray) -> float:
    """Signed inradius about 0 of conv of the columns of P (2, k)."""
    P = _prefilter(P)
    return _polygon_signed_inradius(_monotone_chain(P[0], P[1]))


def _prefilter(P: np.ndarray) -> np.ndarray:
    """Drop points strictly inside the polygon of the extreme points in 16
    directions of the whitened cloud (Akl-Toussaint); the hull is unchanged.

    Whitening (``z = L^-1 x`` with ``P P^T = L L^T``) keeps the directions
    useful for the long thin hulls of growing systems; the extreme points
    of counter-clockwise directions come in counter-clockwise order. The
    polygon is used only when it is convex and winds once (round-off in
    near-collinear extreme points can break that), and points within a
    round-off band of its edges are kept.
    """
    if P.shape[1] <= 24:
        return P
    (a, b), (_, c) = (P @ P.T).tolist()
    if not a > 0:
        return P
    l11 = math.sqrt(a)
    l21 = b / l11
    d2 = c - l21 * l21
    if not d2 > 1e-24 * c:
        return P
    l22 = math.sqrt(d2)
    # support in direction d of z is support in direction L^-T d of x
    Linv_T = np.array([[1 / l11, -l21 / (l11 * l22)], [0.0, 1 / l22]])
    idx = np.argmax((Linv_T @ _DIRS).T @ P, axis=1).tolist()
    ext = [i for k, i in enumerate(idx) if i != idx[k - 1]]
    if len(ext) < 3:
        return P
    ex, ey = P[0, ext].tolist(), P[1, ext].tolist()
    h = len(ext)
    dx = [ex[(k + 1) % h] - ex[k] for k in range(h)]
    dy = [ey[(k + 1) % h] - ey[k] for k in range(h)]
    ang = [math.atan2(y, x) for x, y in zip(dx, dy, strict=True)]
    turns = [(ang[(k + 1) % h] - ang[k]) % (2 * math.pi) for k in range(h)]
    convex = all(0 < t < math.pi for t in turns) and abs(sum(turns) - 2 * math.pi) < 1e-9
    if not (convex and all(x or y for x, y in zip(dx, dy, strict=True))):
        return P
    # cross(e_{k+1} - e_k, x - e_k) > band for every edge: strictly inside
    scale = 1e-12 * float(np.abs(P).max())
    normals = np.array([[-y for y in dy], dx]).T
    rhs = [
        x * yk - y * xk + scale * math.hypot(x, y)
        for x, y, xk, yk in zip(dx, dy, ex, ey, strict=True)
    ]
    inside = (normals @ P > np.array(rhs)[:, None]).all(axis=0)
    return P[:, ~inside]


def _monotone_chain(x: np.ndarray, y: np.ndarray) -> list[tuple[float, float]]:
    """Counter-clockwise hull vertices of the points (x, y) (Andrew)."""
    order = np.lexsort((y, x))
    pts = list(zip(x[order].tolist(), y[order].tolist(), strict=True))

    def half(seq):
        out = []
        for px, py in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (py - ay) - (by - ay) * (px - ax) > 0:
                    break
                out.pop()
            out.append((px, py))
        return out

    lower, upper = half(pts), half(reversed(pts))
    return (lower[:-1] + upper[:-1]) or pts[:1]


def _polygon_signed_inradius(V: list[tuple[float, float]]) -> float:
    """Signed inradius about 0 of the convex polygon with counter-clockwise
    vertices V (plain floats: a hull has few vertices)."""
    h = len(V)
    edges = [(V[k], V[(k + 1) % h]) for k in range(h)]
    if h >= 3:
        # distance of 0 to each edge line, positive on the inner side
        off = [(ax * by - ay * bx) / math.hypot(bx - ax, by - ay) for (ax, ay), (bx, by) in edges]
        if min(off) > 0:
            return min(off)
    # 0 outside or on the boundary: minus its distance to the edges
    best = math.inf
    for (ax, ay), (bx, by) in edges:
        dx, dy = bx - ax, by - ay
        ll = dx * dx + dy * dy
        s = min(max(-(ax * dx + ay * dy) / ll, 0.0), 1.0) if ll > 0 else 0.0
        best = min(best, math.hypot(ax + s * dx, ay + s * dy))
    return -best


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
