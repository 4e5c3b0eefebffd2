"""The graph of a map's POC poses that regions and paths are made of:
neighbouring YES poses (face-adjacent grid poses, wrapping around full
turns; samples within the neighbourhood radius), the steps among them that
may cross a NO set thinner than the map's resolution, and the searches
over it (connectivity, bottleneck, shortest route) that
:func:`cdpm.regions.paths.poc_path` runs. docs/maps.md, "Regions and paths".
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cdpm.errors import InputError
from cdpm.maps.regions import (
    as_dataset,
    default_radius,
    distinct,
    grid_index,
    map_layout,
    region_labels,
    sample_edges,
)
from cdpm.numerics import SUSPECT_LIPSCHITZ_SAFETY
from cdpm.verdicts import YES

__all__ = [
    "MARGIN_VARIABLES",
    "NotConnectedError",
    "bottleneck",
    "connected",
    "grid_graph",
    "margin_values",
    "neighbour_radius",
    "region_graph",
    "shortest_route",
    "suspect_edges",
    "suspect_region_steps",
    "suspect_region_splits",
]


class NotConnectedError(InputError):
    """No path of POC poses joins the start and the goal.

    Attributes:
        start_region, goal_region: labels of the map poses nearest the start
            and the goal (0: in no region).
        start_pose, goal_pose: those map poses, {axis: value}.
        start_size, goal_size: their regions' sizes [poses] (0 for none).
    """

    def __init__(self, message: str, start_region: int, goal_region: int, **info: Any):
        super().__init__(message)
        self.start_region, self.goal_region = int(start_region), int(goal_region)
        self.start_pose = info.get("start_pose", {})
        self.goal_pose = info.get("goal_pose", {})
        self.start_size = int(info.get("start_size", 0))
        self.goal_size = int(info.get("goal_size", 0))


#: margin variables a path reads, in order of preference
MARGIN_VARIABLES = ("reach_margin", "poc_margin")


def margin_values(ds, dims: tuple[str, ...]) -> tuple[np.ndarray | None, str | None]:
    """The map's margin over the pose dims (reach_margin, else poc_margin)."""
    for name in MARGIN_VARIABLES:
        if name in ds.data_vars and tuple(ds[name].dims) and set(ds[name].dims) == set(dims):
            return np.asarray(ds[name].transpose(*dims).values, dtype=float), name
    return None, None


def grid_graph(layout, index):
    """Edges (2, E) between face-adjacent poses of the distinct grid (flat
    C-order ids), wrap edges included, and their lengths (E,)."""
    shape = index.shape
    ids = np.arange(int(np.prod(shape))).reshape(shape)
    edges, lengths = [], []
    for axis, m in enumerate(shape):
        vals = layout.values[axis][index.order[axis]]
        if m >= 2:
            a = np.take(ids, np.arange(m - 1), axis=axis)
            b = np.take(ids, np.arange(1, m), axis=axis)
            step = np.diff(vals).reshape([-1 if k == axis else 1 for k in range(len(shape))])
            edges.append(np.stack([a.reshape(-1), b.reshape(-1)]))
            lengths.append(np.broadcast_to(step, a.shape).reshape(-1))
        if index.ring[axis] and m >= 3:
            a = np.take(ids, m - 1, axis=axis).reshape(-1)
            b = np.take(ids, 0, axis=axis).reshape(-1)
            edges.append(np.stack([a, b]))
            lengths.append(np.full(a.size, 2 * math.pi - (vals[-1] - vals[0])))
    if not edges:
        return np.zeros((2, 0), dtype=np.intp), np.zeros(0)
    return np.concatenate(edges, axis=1), np.concatenate(lengths)


def neighbour_radius(layout, labels) -> float | None:
    """The neighbourhood radius of a sampled map: the one its region labels
    ``labels`` (``poc_region``) were made with, else the default; None on a
    grid."""
    if layout.mode != "sample":
        return None
    radius = labels.attrs.get("radius")
    return default_radius(layout) if radius is None else radius


def region_graph(ds, layout, radius: float | None, margin, margin_name) -> tuple:
    """The graph of the map's POC poses, as regions and paths join them:
    (yes (n,) bool per node, edges (2, E) between YES neighbours, their
    lengths (E,), the margin at each node (n,) or None, which edges may
    cross a NO set thinner than the map's resolution (E,) bool, or None
    without reach_margin). Nodes are the distinct poses of a grid
    (:func:`~cdpm.maps.regions.distinct`) or the samples (neighbours within
    ``radius``). ``margin``, ``margin_name``: :func:`margin_values`' (read
    once by the caller, which needs them too)."""
    poc = np.asarray(ds["poc"].transpose(*layout.dims).values)
    # r_T decides the suspect steps; a map made without margins has none
    computed = margin_name == "reach_margin" and bool(np.isfinite(margin).any())
    reach = margin if computed else None
    if layout.mode == "grid":
        index = grid_index(layout)
        yes = distinct(poc == YES, layout, index).reshape(-1)
        edges, lengths = grid_graph(layout, index)
        node_margin = None if margin is None else distinct(margin, layout, index).reshape(-1)
    else:
        yes = poc == YES
        # the edges to NO samples with an r_T enter the slope estimate
        sampled = yes if reach is None else yes | np.isfinite(reach)
        edges, lengths = sample_edges(layout, sampled, float(radius))
        node_margin = margin
    keep = yes[edges[0]] & yes[edges[1]]
    suspect = None
    if reach is not None:  # the node margins are r_T (distinct on a grid)
        suspect = suspect_edges(edges, lengths, node_margin, keep)[keep]
    return yes, edges[:, keep], lengths[keep], node_margin, suspect


def suspect_region_steps(map: Any) -> int | None:
    """How many steps between neighbouring POC poses of a map (the steps
    its regions and paths are made of) may cross a NO set thinner than the
    map's resolution (:func:`suspect_edges`): where its regions may really
    be split; None for a map without the reach margin r_T."""
    splits = suspect_region_splits(map)
    return None if splits is None else splits[0]


def suspect_region_splits(map: Any) -> tuple[int, int] | None:
    """(suspect steps, regions they could add): how many steps between
    neighbouring POC poses may cross a NO set thinner than the map's
    resolution (:func:`suspect_region_steps`), and how many more connected
    regions the YES poses would form without those steps. A thin NO set
    can split a region only by crossing every step between its parts, so
    when removing every suspect step splits nothing (0), the regions hold
    whatever the suspect steps hide. None for a map without r_T."""
    # scipy: loaded on first use
    from scipy.sparse.csgraph import connected_components

    ds = as_dataset(map)
    layout = map_layout(ds)
    radius = neighbour_radius(layout, region_labels(ds)) if layout.mode == "sample" else None
    yes, edges, _, _, suspect = region_graph(ds, layout, radius, *margin_values(ds, layout.dims))
    if suspect is None:
        return None
    n = yes.shape[0]

    def regions(kept: np.ndarray) -> int:
        graph = _csgraph(n, kept, np.ones(kept.shape[1]))
        _, comp = connected_components(graph, directed=False)
        return int(np.unique(comp[yes]).size)

    steps = int(np.count_nonzero(suspect))
    extra = regions(edges[:, ~suspect]) - regions(edges) if steps else 0
    return steps, extra


def suspect_edges(
    edges: np.ndarray, lengths: np.ndarray, margins: np.ndarray, candidates: np.ndarray
) -> np.ndarray:
    """Edges between neighbouring samples that a NO set thinner than the
    samples may cross, judged by the reach margin r_T.

    r_T is continuous in the pose and 0 on every NO pose, so along an edge
    of length h from a to b it can reach 0 only if r(a) + r(b) <= L h, L a
    Lipschitz bound of r_T on the edge. L is estimated from the samples:
    SUSPECT_LIPSCHITZ_SAFETY times the largest slope |r(x) - r(y)| / |x - y|
    over the edges (x, y) at a or at b (the edge itself included). A bound
    over the whole map would be set by its steepest place (a cable of nearly
    zero length turns fast) and flag every edge; this local one is a
    heuristic: it can miss a NO set where r_T bends more sharply than the
    samples show, and flags valleys of r_T that do not reach 0.

    Args:
        edges: node ids (2, E) of every sampled edge, candidates or not
            (their slopes enter the estimate).
        lengths: edge lengths h (E,) [the samples' units].
        margins: r_T at each node (n,) [m]; NaN where unknown (not used).
        candidates: the edges to judge (E,) bool, e.g. those between YES poses.

    Returns:
        (E,) bool: candidate edges with r(a) + r(b) <= factor L h.
    """
    a, b = edges
    ra, rb = margins[a], margins[b]
    known = np.isfinite(ra) & np.isfinite(rb) & (lengths > 0)
    slope = np.zeros(margins.size)
    s = np.abs(ra - rb)[known] / lengths[known]
    np.maximum.at(slope, a[known], s)
    np.maximum.at(slope, b[known], s)
    bound = SUSPECT_LIPSCHITZ_SAFETY * np.maximum(slope[a], slope[b]) * lengths
    return np.asarray(candidates, dtype=bool) & known & (ra + rb <= bound)


def _csgraph(n: int, edges: np.ndarray, weights: np.ndarray):
    # scipy: loaded on first use
    from scipy.sparse import csr_matrix

    # csgraph drops zero weights: duplicate samples keep a tiny positive one
    w = np.maximum(weights, 1e-300)
    return csr_matrix((w, (edges[0], edges[1])), shape=(n, n))


def connected(n: int, edges: np.ndarray, s: int, g: int) -> bool:
    # scipy: loaded on first use
    from scipy.sparse.csgraph import connected_components

    if s == g:
        return True
    graph = _csgraph(n, edges, np.ones(edges.shape[1]))
    _, comp = connected_components(graph, directed=False)
    return bool(comp[s] == comp[g])


def bottleneck(n: int, edges: np.ndarray, node_margin: np.ndarray, s: int, g: int) -> float:
    """The largest t such that the edges whose smaller end margin is >= t
    join s and g (bisection over the distinct edge margins)."""
    w = np.minimum(node_margin[edges[0]], node_margin[edges[1]])
    if w.size == 0:  # no edge: nothing joins them (the route then says so)
        return -np.inf
    levels = np.unique(w)
    lo, hi = 0, levels.size - 1  # levels[lo] joins them (all edges)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if connected(n, edges[:, w >= levels[mid]], s, g):
            lo = mid
        else:
            hi = mid - 1
    return float(levels[lo])


def shortest_route(
    n: int, edges: np.ndarray, lengths: np.ndarray, s: int, g: int, unweighted: bool
):
    """Node ids of a shortest path s -> g, or None."""
    # scipy: loaded on first use
    from scipy.sparse.csgraph import dijkstra

    if s == g:
        return [s]
    graph = _csgraph(n, edges, lengths)
    _, pred = dijkstra(
        graph, directed=False, indices=s, return_predecessors=True, unweighted=unweighted
    )
    if pred[g] < 0:
        return None
    path = [g]
    while path[-1] != s:
        path.append(int(pred[path[-1]]))
    return path[::-1]


# ------------------------------------------------------------------ public
