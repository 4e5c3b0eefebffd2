"""Paths of POC poses through a workspace map.

Seed paper Lemma 1 / Remark 10: along a connected set of equilibria whose
linearisations are all positive output controllable (POC), pull-only
cables can drive the output from pose to pose. :func:`poc_path` finds such
a path on a map: a chain of map poses with ``poc == YES``, each the
neighbour of the next (the adjacency of :func:`cdpm.maps.regions.label_regions`:
face-adjacent grid poses, wrapping around axes of angles that span a full
turn, or samples within the neighbourhood radius), from the map pose
nearest the start to the one nearest the goal.

- shortest: fewest steps on a grid, least length (sum of the distances in
  the sampled coordinates) on a sampled map (``scipy.sparse.csgraph``);
- ``maximise_margin=True``: the path whose smallest margin (``reach_margin``,
  else ``poc_margin``) between the start and the goal is largest (the
  bottleneck; the two ends' margins are given, so a start of small margin
  does not make every path tie), shortest among those.
  The bottleneck is found by bisection over the edges' margins (an edge's
  margin is the smaller of its two poses'): the largest threshold t for
  which the edges with margin >= t still join start and goal (connected
  components); then the shortest path on those edges. Steps that may cross
  a NO set thinner than the map's resolution (:func:`suspect_edges`) are
  avoided when a path without them exists.

A map sees the NO set only at its poses: a NO curve of zero area can pass
between two neighbouring YES poses. Where the map has the reach margin r_T
(continuous in the pose, 0 on every NO pose) a step from a to b of length h
can meet such a curve only if r(a) + r(b) <= L h, L a Lipschitz bound of
r_T; :func:`suspect_edges` estimates L from the slopes sampled around each
step and flags those steps (``POCPath.suspect_steps``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cdpm.errors import InputError
from cdpm.maps.regions import (
    as_dataset,
    grid_index,
    map_layout,
    map_robot,
    named_pose,
    nearest_index,
    region_labels,
    sample_distance,
)
from cdpm.printing import TextRepr
from cdpm.regions.graph import (
    MARGIN_VARIABLES,
    NotConnectedError,
    bottleneck,
    connected,
    margin_values,
    neighbour_radius,
    region_graph,
    shortest_route,
    suspect_edges,
    suspect_region_splits,
    suspect_region_steps,
)
from cdpm.verdicts import STATUS_LABELS, VERDICT_LABELS, YES

__all__ = [
    "POCPath",
    "NotConnectedError",
    "poc_path",
    "suspect_edges",
    "suspect_region_steps",
    "suspect_region_splits",
    "MARGIN_VARIABLES",
]


@dataclass(frozen=True)
class POCPath(TextRepr):
    """A path of POC map poses inside one region.

    Printing it gives a short summary; :func:`cdpm.text.path_text` prints it
    in full (the waypoints), :func:`cdpm.text.path_json` gives its JSON
    data.

    Attributes:
        dims: the map's pose dimensions (axis names, or ``("sample",)``).
        axes: the map's axes (coordinate names), the keys of ``coordinates``.
        indices: dataset index of each waypoint, shape (k, len(dims)).
        coordinates: axis -> values along the path (k,) [rad or m]; on a
            closed full-turn axis the seam pose is shown at the end nearer
            the previous waypoint.
        natural: the robot's natural coordinates of each waypoint (k, nv):
            the map's base pose with the axis values filled in.
        natural_names: names of the columns of ``natural``.
        region: the region label (``poc_region``).
        region_size: poses in that region (a pose on a full-turn seam once).
        margins: margin at each waypoint (k,) (NaN when the map has none).
        margin_variable: the map variable ``margins`` come from, or None.
        length: the sum of the step lengths in axis units (angles across a
            seam the short way).
        maximise_margin: the path maximises the smallest margin of its
            waypoints between the start and the goal (theirs are given, so
            ``min_margin`` may be the start's or the goal's).
        units: axis -> unit (``"rad"``, ``"m"``).
        margin_unit: the unit of ``margins`` (the map variable's ``units``;
            "" for the unitless poc_margin).
        seam_crossings: steps i (waypoint i to i+1) that cross the seam of an
            axis that wraps (the coordinates jump there by about a turn).
        suspect_steps: steps i (waypoint i to i+1) that may cross a NO set
            thinner than the map's resolution: r(i) + r(i+1) <= factor L h
            with r the reach margin (:func:`suspect_edges`); None when the
            map has no reach margin computed (not checked).
        start_pose, goal_pose: the map poses nearest the start and the goal
            given, {axis: value} (the first and last waypoints).
    """

    dims: tuple[str, ...]
    axes: tuple[str, ...]
    indices: np.ndarray
    coordinates: dict[str, np.ndarray]
    natural: np.ndarray
    natural_names: tuple[str, ...]
    region: int
    region_size: int
    margins: np.ndarray
    margin_variable: str | None
    length: float
    maximise_margin: bool = False
    units: dict[str, str] = field(default_factory=dict)
    margin_unit: str = ""
    seam_crossings: tuple[int, ...] = ()
    suspect_steps: tuple[int, ...] | None = None
    start_pose: dict[str, float] = field(default_factory=dict)
    goal_pose: dict[str, float] = field(default_factory=dict)

    @property
    def n_waypoints(self) -> int:
        """Number of waypoints k (start and goal included)."""
        return int(self.indices.shape[0])

    @property
    def steps(self) -> int:
        """Number of steps, k - 1."""
        return self.n_waypoints - 1

    @property
    def min_margin(self) -> float:
        """Smallest margin along the path (NaN without margins)."""
        m = self.margins
        return float(np.nanmin(m)) if np.any(np.isfinite(m)) else float("nan")

    def waypoint(self, i: int) -> dict[str, float]:
        """{axis: value} of waypoint i [rad or m]."""
        return {a: float(self.coordinates[a][i]) for a in self.axes}

    def __str__(self) -> str:
        # a summary; cdpm.text.path_text gives the waypoints and warnings
        kind = "largest smallest margin" if self.maximise_margin else "shortest"
        text = (
            f"POC path ({kind}) in region {self.region}: {self.n_waypoints} waypoint(s), "
            f"length {self.length:.4g}"
        )
        if self.margin_variable is not None and np.any(np.isfinite(self.margins)):
            unit = f" {self.margin_unit}" if self.margin_unit else ""
            text += f"; smallest {self.margin_variable} {self.min_margin:.4g}{unit}"
        if self.suspect_steps:
            text += f"; {len(self.suspect_steps)} suspect step(s)"
        return text

    def __repr__(self) -> str:
        return (
            f"POCPath(region={self.region}, waypoints={self.n_waypoints}, "
            f"length={self.length:.4g}, min_margin={self.min_margin:.4g}, "
            f"suspect_steps={self.suspect_steps})"
        )


# ------------------------------------------------------------------ graph


def poc_path(map: Any, start: Any, goal: Any, *, maximise_margin: bool = False) -> Any:
    """A path of POC map poses from the start to the goal, inside one region.

    On a certified map (:class:`cdpm.certify.map.CertifiedMap`) this is
    :func:`cdpm.regions.certified.certified_path`: straight steps, each
    inside one certified YES box, every pose along them proven POC; the
    start and goal are not moved and must lie in YES boxes of one certified
    region; it returns a :class:`~cdpm.regions.certified.CertifiedPath`.

    Args:
        map: a map (``xarray.Dataset``) or the path of its store, or a
            certified map.
        start, goal: poses as for :func:`cdpm.maps.regions.region_of`:
            ``{coordinate: value}``, values in the map's axis order, the
            robot's natural coordinates, or a pose name of the map's spec;
            each is moved to its nearest map pose.
        maximise_margin: maximise the smallest margin (``reach_margin``, else
            ``poc_margin``) of the waypoints between the start and the goal
            (theirs are given), then take the shortest such path;
            default: the shortest path (fewest steps on a grid, least length
            on a sampled map). Suspect steps (:func:`suspect_edges`) are left
            out when start and goal stay joined without them.

    Returns:
        :class:`POCPath`, with the steps that may cross a NO set thinner than
        the map's resolution in ``suspect_steps``.

    Raises:
        NotConnectedError: the start or goal is in no region, or they are in
            different regions (the message names both, with their sizes).
        InputError: a pose off the map, of the wrong length or an unknown
            pose name; a map without margins with ``maximise_margin``.
    """
    # loaded on first use: the certified maps
    from cdpm.certify.map import CertifiedMap

    if isinstance(map, CertifiedMap):
        from cdpm.regions.certified import certified_path

        return certified_path(map, start, goal, maximise_margin=maximise_margin)
    ds = as_dataset(map)
    if isinstance(start, str) or isinstance(goal, str):
        robot = map_robot(ds, "a pose name")
        start, goal = (named_pose(ds, p, robot) if isinstance(p, str) else p for p in (start, goal))
    layout = map_layout(ds)
    labels_da = region_labels(ds)
    labels = np.asarray(labels_da.transpose(*layout.dims).values)
    radius = neighbour_radius(layout, labels_da)
    s_idx = nearest_index(ds, layout, start, radius)
    g_idx = nearest_index(ds, layout, goal, radius)
    s_label, g_label = int(labels[s_idx]), int(labels[g_idx])
    if s_label == 0 or g_label == 0 or s_label != g_label:
        raise _not_connected(ds, layout, labels, s_idx, g_idx)
    margin, margin_name = margin_values(ds, layout.dims)
    graph = region_graph(ds, layout, radius, margin, margin_name)
    yes, edges, lengths, node_margin, suspect = graph
    if layout.mode == "grid":
        index = grid_index(layout)
        s, g = (_distinct_id(index, index.shape, i) for i in (s_idx, g_idx))
    else:
        s, g = int(s_idx[0]), int(g_idx[0])
    n = yes.size
    if maximise_margin:
        if node_margin is None or not np.any(np.isfinite(node_margin[yes])):
            raise InputError(
                "this map has no margins (no reach_margin, or poc_margin all NaN: made with "
                "margin=False / --no-margin); make the map with margins to maximise the margin, "
                "or ask for the shortest path"
            )
        node_margin = np.where(np.isfinite(node_margin), node_margin, -np.inf)
        # the start's and goal's margins are given: the waypoints between them
        # decide (a start of small margin made every path tie, and the
        # shortest of them could hug a low-margin edge)
        node_margin[[s, g]] = np.inf
        if suspect is not None and suspect.any() and connected(n, edges[:, ~suspect], s, g):
            edges, lengths, suspect = edges[:, ~suspect], lengths[~suspect], suspect[~suspect]
        if s != g:
            t = bottleneck(n, edges, node_margin, s, g)
            wide = np.minimum(node_margin[edges[0]], node_margin[edges[1]]) >= t
            edges, lengths = edges[:, wide], lengths[wide]
            suspect = None if suspect is None else suspect[wide]
    route = shortest_route(n, edges, lengths, s, g, layout.mode == "grid")
    if route is None:  # stored labels that disagree with the map's adjacency
        raise _not_connected(ds, layout, labels, s_idx, g_idx, joined=False)
    steps = None if suspect is None else _suspect_steps(n, edges, suspect, route)
    if layout.mode == "grid":
        indices, seams = _grid_indices(layout, index, route, s_idx, g_idx)
    else:
        indices = np.array(route, dtype=np.intp).reshape(-1, 1)
        seams = _seams(layout, [v[indices[:, 0]] for v in layout.values])
    return _make_path(
        ds, layout, indices, (seams, steps), s_label, labels, margin, margin_name, maximise_margin
    )


def _suspect_steps(n: int, edges: np.ndarray, suspect: np.ndarray, route) -> tuple[int, ...]:
    """Steps k (route[k] -> route[k + 1]) along suspect edges."""
    # scipy: loaded on first use
    from scipy.sparse import csr_matrix

    if len(route) < 2:
        return ()
    # 1 + flag, so that csr keeps the edges that are not suspect
    flag = csr_matrix((1.0 + suspect, (edges[0], edges[1])), shape=(n, n))
    flag = flag + flag.T
    a, b = np.array(route[:-1]), np.array(route[1:])
    return tuple(int(k) for k in np.flatnonzero(np.asarray(flag[a, b]).ravel() >= 2))


def _distinct_id(index, shape: tuple[int, ...], dataset_index: tuple) -> int:
    """Flat id on the distinct grid of a dataset index."""
    pos = tuple(int(p[i]) for p, i in zip(index.position, dataset_index, strict=True))
    return int(np.ravel_multi_index(pos, shape))


def _grid_indices(layout, index, route, s_idx, g_idx):
    """Dataset indices (k, d) of a route on the distinct grid, and the steps
    crossing a seam; a closed axis's seam pose takes the copy at the end the
    path comes from (the start's and the goal's as they were given)."""
    pos = np.array(np.unravel_index(np.array(route), index.shape)).T  # (k, d)
    k, d = pos.shape
    out = np.empty((k, d), dtype=np.intp)
    for axis in range(d):
        order = index.order[axis]
        m = order.size
        out[:, axis] = order[pos[:, axis]]
        if layout.wrap[axis] != "closed":
            continue
        last = int(np.argsort(layout.values[axis], kind="stable")[-1])
        at_end = int(s_idx[axis]) == last
        for i in range(k):
            p = int(pos[i, axis])
            if i > 0 and p == 0:
                prev = int(pos[i - 1, axis])
                if prev != 0:
                    at_end = prev > m // 2
            if p == 0:
                out[i, axis] = last if at_end else order[0]
        if pos[-1, axis] == 0:
            out[-1, axis] = g_idx[axis]
    shown = [v[out[:, a]] for a, v in enumerate(layout.values)]
    # a step that stays on a closed axis's seam pose (shown as pi, then as
    # -pi where the goal was given so) does not move along it
    moved = [np.diff(pos[:, a]) != 0 for a in range(d)]
    return out, _seams(layout, shown, moved)


def _seams(layout, shown: list[np.ndarray], moved: list | None = None) -> tuple[int, ...]:
    """Steps i (waypoint i to i + 1) whose shown value of an axis that wraps
    changes by more than half a turn: the step crosses the seam. ``moved``:
    per axis, which steps move along it (k - 1,) bool; default all."""
    seams: set[int] = set()
    for a, (values, w) in enumerate(zip(shown, layout.wrap, strict=True)):
        if w:
            jump = np.abs(np.diff(values)) > math.pi
            if moved is not None:
                jump &= moved[a]
            seams.update(int(j) for j in np.flatnonzero(jump))
    return tuple(sorted(seams))


def _make_path(ds, layout, indices, crossings, label, labels, margin, margin_name, maximise):
    """The :class:`POCPath` of dataset indices (k, d); ``crossings`` is
    (seam crossings, suspect steps or None)."""
    k = indices.shape[0]
    tup = tuple(indices.T)
    if layout.mode == "grid":
        coords = {
            a: layout.values[i][indices[:, i]].astype(float) for i, a in enumerate(layout.axes)
        }
    else:
        coords = {
            a: v[indices[:, 0]].astype(float)
            for a, v in zip(layout.axes, layout.values, strict=True)
        }
    points = np.stack([coords[a] for a in layout.axes], axis=1)
    length = 0.0
    for i in range(k - 1):
        length += float(sample_distance(layout, points[i], points[i + 1]))
    names = tuple(ds.attrs.get("robot_coordinates", []) or [])
    base = list(ds.attrs.get("base", []) or [])
    if names and len(base) == len(names):
        natural = np.tile(np.asarray(base, dtype=float), (k, 1))
        for a in layout.axes:
            natural[:, names.index(a)] = coords[a]
    else:
        names, natural = tuple(layout.axes), points.copy()
    margins = np.full(k, np.nan) if margin is None else margin[tup].astype(float)
    return POCPath(
        dims=tuple(layout.dims),
        axes=tuple(layout.axes),
        indices=indices,
        coordinates=coords,
        natural=natural,
        natural_names=tuple(names),
        region=int(label),
        region_size=int(np.count_nonzero(labels == label)) - _seam_copies(layout, labels, label),
        margins=margins,
        margin_variable=margin_name,
        length=length,
        maximise_margin=bool(maximise),
        units=dict(zip(layout.axes, layout.units, strict=True)),
        margin_unit=str(ds[margin_name].attrs.get("units", "")) if margin_name else "",
        seam_crossings=crossings[0],
        suspect_steps=crossings[1],
        start_pose=map_pose(layout, tuple(indices[0])),
        goal_pose=map_pose(layout, tuple(indices[-1])),
    )


def _seam_copies(layout, labels: np.ndarray, label: int) -> int:
    """Poses of the region counted twice (a closed axis's last value)."""
    if layout.mode != "grid":
        return 0
    mask = labels == label
    count = 0
    for k, w in enumerate(layout.wrap):
        if w == "closed":
            last = int(np.argsort(layout.values[k], kind="stable")[-1])
            idx = [slice(None)] * mask.ndim
            idx[k] = last
            count += int(np.count_nonzero(mask[tuple(idx)]))
            mask = mask.copy()
            mask[tuple(idx)] = False
    return count


def map_pose(layout, index: tuple) -> dict[str, float]:
    """{axis: value} of the map pose at a dataset index."""
    if layout.mode == "sample":
        return {a: float(v[index[0]]) for a, v in zip(layout.axes, layout.values, strict=True)}
    return {a: float(v[i]) for a, v, i in zip(layout.axes, layout.values, index, strict=True)}


def _describe(ds, layout, labels, index, role: str) -> tuple[str, int, dict]:
    pose = map_pose(layout, index)
    where = ", ".join(f"{a}={v:.4g}" for a, v in pose.items())
    label = int(labels[index])
    size = 0
    if label > 0:
        size = int(np.count_nonzero(labels == label)) - _seam_copies(layout, labels, label)
        return f"{role} ({where}) is in POC region {label} ({size} poses)", size, pose
    code = int(np.asarray(ds["poc"].transpose(*layout.dims).values)[index])
    verdict = VERDICT_LABELS.get(code, "not analysed").upper()
    if code == YES:
        reason = (
            "its verdict there is YES, but the same pose at the other end of a full-turn "
            "axis is not"
        )
    else:
        reason = f"its verdict there is {verdict}"
        if "status" in ds.data_vars and code != 0 and code != 2:
            status = int(np.asarray(ds["status"].transpose(*layout.dims).values)[index])
            reason += f" ({STATUS_LABELS.get(status, 'unknown status')})"
    return f"{role} ({where}) is in no POC region: {reason}", size, pose


def _not_connected(ds, layout, labels, s_idx, g_idx, joined: bool = True) -> NotConnectedError:
    start, s_size, s_pose = _describe(ds, layout, labels, s_idx, "start")
    goal, g_size, g_pose = _describe(ds, layout, labels, g_idx, "goal")
    s_label, g_label = int(labels[s_idx]), int(labels[g_idx])
    if s_label > 0 and g_label > 0:
        if s_label != g_label:
            goal = goal.replace("is in POC region", "is in region")
        message = f"{start}; {goal}: no path of POC poses joins them"
        if s_label == g_label and not joined:
            message += " (the map's stored poc_region is stale: attach_regions(ds, store) again)"
    else:
        message = f"{start}; {goal}"
    return NotConnectedError(
        message,
        s_label,
        g_label,
        start_pose=s_pose,
        goal_pose=g_pose,
        start_size=s_size,
        goal_size=g_size,
    )
