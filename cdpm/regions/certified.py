"""Paths through a certified region: every point proven POC.

A certified map (:func:`cdpm.certify.map.certify_map`) covers its mapped
coordinates with boxes, each proven POC YES on the whole closed box, proven
NO, or undecided; YES boxes sharing a face form certified regions
(:meth:`~cdpm.certify.map.CertifiedMap.regions`; an axis spanning a full
turn wraps). :func:`certified_path` joins two poses of one region by
straight steps, each inside one YES box of the region, so every point of
the path is POC (boxes are convex: a segment between two points of a box
stays in it), and the seed paper's Lemma 1 applies along it with no
sampling gap: no step can cross a NO set, however thin.

How the path is made:

1. The box route: a shortest route over the region's boxes (Dijkstra, each
   step from a box's centre to the centre of the face it shares with the
   next box and on to that box's centre), from a YES box holding the start
   to one holding the goal. With ``maximise_margin`` the route first keeps
   only boxes whose margin lower bound (``margin_lower``, a lower bound of
   the reach margin r_T over the box) is at least the largest threshold
   that still joins start and goal (the bottleneck; the start's and goal's
   boxes are given), then takes the shortest such route.
2. The polyline: start, the centres of the shared faces in route order,
   goal; consecutive points lie in one box of the route.
3. Shortcuts: a corner of the polyline is dropped when the straight
   segment replacing it is covered by the route's allowed boxes
   (:func:`segment_cover`, exact interval arithmetic on the segment's
   parameter; the boxes' shared faces are the same floating-point numbers,
   so covering pieces meet exactly and a gap is never bridged).
4. The steps: each straight segment is cut where it passes from one box to
   the next, so that every step lies in one box (``CertifiedPath.boxes``).
   Steering along the path (``cdpm path --steer``) takes one leg per step:
   both ends of every leg lie in one certified box.

Coordinates on an axis that wraps are continuous along the path: a step
that ends at +pi on one box goes on from -pi in the next box (the same
pose); ``CertifiedPath.steps`` gives each step in its box's coordinates.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from cdpm.certify.map import face_pairs
from cdpm.errors import InputError
from cdpm.maps.regions import map_robot
from cdpm.printing import TextRepr
from cdpm.regions.graph import NotConnectedError, bottleneck, connected, shortest_route
from cdpm.verdicts import MARGINAL, NO, YES

__all__ = [
    "CertifiedPath",
    "certified_path",
    "certified_map_robot",
    "locate",
    "segment_cover",
]

TWO_PI = 2.0 * math.pi
#: steps shorter than this [rad or m] are dropped from a certified path (a
#: segment crossing a corner clips a neighbouring box over a rounding's length)
CERTIFIED_PATH_MIN_STEP = 1e-12


@dataclass(frozen=True)
class CertifiedPath(TextRepr):
    """A path of straight steps inside one certified region: every point of
    every step lies in a certified YES box, so every pose along it is POC.

    Printing it gives a short summary; :func:`cdpm.text.regions.certified_path_text`
    prints it in full, :func:`cdpm.text.regions.certified_path_json` gives
    its JSON data.

    Attributes:
        coordinates: the mapped coordinates (d names), the columns of the
            point arrays.
        units: the unit of each ("rad" or "m"; "" when the map has none).
        waypoints: the ends of the steps, shape (k, d) [rad or m], as the
            path runs: continuous along an axis that wraps (a value may leave
            [-pi, pi] after a seam crossing).
        map_waypoints: the same in the map's coordinates (k, d): each the
            end of its step, inside its box (angles within [-pi, pi]).
        steps: each step's two ends in the coordinates of its box, shape
            (k - 1, 2, d): inside ``[lower, upper]`` of box ``boxes[i]``.
        boxes: the map's box (index into ``lower``/``upper``) holding each
            step, shape (k - 1,).
        natural: the robot's natural coordinates of each waypoint (k, nv):
            the map's base pose with the mapped values filled in.
        natural_names: names of the columns of ``natural`` (empty when the
            map does not name them: then the mapped coordinates' order).
        margins: the margin lower bound of each step's box (k - 1,) [the
            outputs' unit]: r_T is at least this everywhere along the step.
        margin_unit: the unit of ``margins``.
        region: the certified region's label (:meth:`CertifiedMap.regions`).
        region_boxes: YES boxes in that region.
        region_volume: their volume, as a fraction of the mapped volume.
        route: the boxes of the route before shortcuts, in order.
        maximise_margin: whether the route maximises the smallest margin.
        threshold: with ``maximise_margin``, the bottleneck: every box of
            the route other than the start's and the goal's has a margin
            lower bound at least this [the outputs' unit]; else NaN.
        seam_crossings: waypoints i where the path crosses the seam of an
            axis that wraps (step i - 1 ends at +-pi, step i goes on from the
            other end).
        start, goal: the poses given, over the mapped coordinates (d,).
    """

    coordinates: tuple[str, ...]
    units: tuple[str, ...]
    waypoints: np.ndarray
    map_waypoints: np.ndarray
    steps: np.ndarray
    boxes: np.ndarray
    natural: np.ndarray
    natural_names: tuple[str, ...]
    margins: np.ndarray
    margin_unit: str
    region: int
    region_boxes: int
    region_volume: float
    route: np.ndarray
    maximise_margin: bool
    threshold: float
    seam_crossings: tuple[int, ...]
    start: np.ndarray
    goal: np.ndarray

    @property
    def n_waypoints(self) -> int:
        return int(self.waypoints.shape[0])

    @property
    def n_steps(self) -> int:
        return int(self.steps.shape[0])

    @property
    def length(self) -> float:
        """Sum of the steps' lengths [axis units; rad and m counted alike]."""
        if self.n_steps == 0:
            return 0.0
        return float(np.linalg.norm(self.steps[:, 1] - self.steps[:, 0], axis=1).sum())

    @property
    def min_margin(self) -> float:
        """The smallest margin lower bound along the path (NaN without steps)."""
        return float(self.margins.min()) if self.margins.size else float("nan")

    def __str__(self) -> str:
        # a summary; cdpm.text.regions.certified_path_text gives the waypoints
        kind = "largest smallest margin" if self.maximise_margin else "shortest"
        text = (
            f"certified POC path ({kind}) in certified region {self.region}: "
            f"{self.n_steps} step(s) through {np.unique(self.boxes).size} YES box(es), "
            f"length {self.length:.4g}"
        )
        if self.n_steps:
            text += f"; r_T >= {self.min_margin:.4g} {self.margin_unit} along it"
        return text

    def __repr__(self) -> str:
        return (
            f"CertifiedPath(region={self.region}, steps={self.n_steps}, "
            f"length={self.length:.4g}, min_margin={self.min_margin:.4g})"
        )


def certified_map_robot(cmap: Any, why: str) -> Any:
    """The robot of a certified map, loaded from the spec its provenance
    records (``provenance["spec"]``) and checked against the spec's hash
    (:func:`cdpm.maps.regions.map_robot`); ``why`` says what needs it.

    Raises:
        InputError: the spec is not recorded, not found or changed since.
    """
    provenance = getattr(cmap, "provenance", None) or {}
    attrs = {"spec": provenance.get("spec"), "spec_sha256": provenance.get("spec_sha256")}
    return map_robot(SimpleNamespace(attrs=attrs), why)


# ------------------------------------------------------------------ geometry


def _wrapped(x: np.ndarray, wraps: Sequence[bool]) -> np.ndarray:
    """Values of axes that wrap moved into [-pi, pi) (..., d)."""
    out = np.array(x, dtype=float)
    for k, w in enumerate(wraps):
        if w:
            out[..., k] = (out[..., k] + math.pi) % TWO_PI - math.pi
    return out


def _shifts(wraps: Sequence[bool], low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Offsets (S, d) of whole turns along axes that wrap, enough to bring
    every box next to any point with coordinates in [low, high]."""
    ranges = []
    for k, w in enumerate(wraps):
        if w:
            n_lo = math.floor((low[k] + math.pi) / TWO_PI) - 1
            n_hi = math.floor((high[k] + math.pi) / TWO_PI) + 1
            ranges.append(np.arange(n_lo, n_hi + 1) * TWO_PI)
        else:
            ranges.append(np.zeros(1))
    grid = np.meshgrid(*ranges, indexing="ij")
    return np.stack([g.reshape(-1) for g in grid], axis=1)


def locate(lower: np.ndarray, upper: np.ndarray, wraps: Sequence[bool], x: Any) -> np.ndarray:
    """Ids of the (closed) boxes that hold the point x (d,): on an axis that
    wraps, x and x +- 2 pi are the same pose."""
    x = np.asarray(x, dtype=float)
    inside = np.zeros(lower.shape[0], dtype=bool)
    for s in _shifts(wraps, x, x):
        y = x + s
        inside |= np.all((lower <= y) & (y <= upper), axis=1)
    return np.flatnonzero(inside)


def segment_cover(a: Any, b: Any, lower: np.ndarray, upper: np.ndarray):
    """Cover the straight segment from a to b (d,) by closed boxes.

    For each box the parameters t in [0, 1] with ``a + t (b - a)`` inside
    it form one interval (boxes are convex); the segment is covered when
    the intervals, taken greedily from t = 0 (the one reaching furthest
    among those starting at or before the point reached), reach t = 1 with
    no gap. A gap as small as one rounding is a gap: the segment is then
    not covered (boxes cut from one grid share their faces' numbers, so
    covering boxes meet exactly).

    Args:
        a, b: the segment's ends (d,) in the boxes' coordinates.
        lower, upper: the boxes (N, d).

    Returns:
        (box ids, t0, t1) of the pieces in order, each piece
        ``[t0, t1]`` of positive length inside its box, or None when the
        boxes do not cover the segment.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    delta = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lower - a) / delta
        t2 = (upper - a) / delta
    moving = delta != 0
    enter = np.where(moving, np.minimum(t1, t2), -np.inf)
    leave = np.where(moving, np.maximum(t1, t2), np.inf)
    still = ~moving & ((lower > a) | (upper < a))  # a fixed axis outside the box
    t_in = np.max(enter, axis=1)
    t_out = np.min(leave, axis=1)
    ok = ~np.any(still, axis=1) & (t_in <= t_out) & (t_out >= 0) & (t_in <= 1)
    ids = np.flatnonzero(ok)
    t_in, t_out = np.maximum(t_in[ids], 0.0), np.minimum(t_out[ids], 1.0)
    order = np.argsort(t_in, kind="stable")
    ids, t_in, t_out = ids[order], t_in[order], t_out[order]
    pieces, starts, ends = [], [], []
    reached, i, n = 0.0, 0, ids.size
    while reached < 1.0:
        # of the boxes entered at or before the point reached, the one
        # reaching furthest (those passed over never reach further later)
        best, best_out = -1, reached
        while i < n and t_in[i] <= reached:
            if t_out[i] > best_out:
                best, best_out = i, float(t_out[i])
            i += 1
        if best < 0:
            return None  # a gap at t = reached
        pieces.append(int(ids[best]))
        starts.append(reached)
        ends.append(best_out)
        reached = best_out
    return np.array(pieces, dtype=np.intp), np.array(starts), np.array(ends)


# ---------------------------------------------------------------- the path


def _map_arrays(cmap: Any):
    """(coordinates, lower, upper, verdict, margin_lower, wraps, base) of a
    :class:`~cdpm.certify.map.CertifiedMap`, checked."""
    try:
        names = tuple(cmap.coordinates)
        lower = np.asarray(cmap.lower, dtype=float)
        upper = np.asarray(cmap.upper, dtype=float)
        verdict = np.asarray(cmap.verdict)
        margin = np.asarray(cmap.margin_lower, dtype=float)
        wraps = tuple(bool(w) for w in cmap.wraps)
    except (AttributeError, TypeError, ValueError):
        raise InputError(
            "expected a certified map (cdpm.certify_map(...) or cdpm.open_certified(store))"
        ) from None
    return names, lower, upper, verdict, margin, wraps


def _natural_names(cmap: Any) -> tuple[str, ...]:
    prov = getattr(cmap, "provenance", None) or {}
    settings = prov.get("settings", {}) if isinstance(prov, Mapping) else {}
    names = settings.get("coordinates") if isinstance(settings, Mapping) else None
    if names:
        return tuple(str(n) for n in names)
    boxes = getattr(cmap, "boxes", None)
    nv = None if boxes is None else np.asarray(boxes.lower).shape[1]
    coords = tuple(cmap.coordinates)
    base = np.asarray(getattr(cmap, "base", np.zeros(0)), dtype=float).reshape(-1)
    if nv is not None and nv == len(coords) and base.size == nv:
        return coords
    return ()


def _mapped_index(cmap: Any, robot: Any) -> list[int] | None:
    """Columns of the mapped coordinates among the natural ones, or None
    when the map does not say."""
    if robot is not None:
        names = list(robot.coordinate_names)
        return [names.index(c) for c in cmap.coordinates]
    boxes = getattr(cmap, "boxes", None)
    if boxes is None:
        return None
    lo, hi = np.asarray(boxes.lower, dtype=float), np.asarray(boxes.upper, dtype=float)
    # the mapped columns are those along which the boxes differ from the base
    varying = [k for k in range(lo.shape[1]) if np.any(lo[:, k] != hi[:, k])]
    return varying if len(varying) == len(cmap.coordinates) else None


def _pose_point(cmap: Any, pose: Any, role: str, robot: Any, base: np.ndarray) -> np.ndarray:
    """The pose over the mapped coordinates (d,): from {coordinate: value},
    values in the map's coordinate order, natural coordinates (nv,) whose
    other coordinates are the map's base pose, or a pose name (with the
    robot)."""
    names = tuple(cmap.coordinates)
    d = len(names)
    index = _mapped_index(cmap, robot)
    if isinstance(pose, str):
        if robot is None:
            robot = certified_map_robot(cmap, f"{role} {pose!r} (a pose name)")
        try:
            pose = np.asarray(robot.to_natural(robot.as_q(pose)), dtype=float)
        except (KeyError, ValueError) as exc:
            raise InputError(f"{role} {pose!r}: {exc}") from exc
    if isinstance(pose, Mapping):
        unknown = [k for k in pose if k not in names]
        missing = [n for n in names if n not in pose]
        if unknown or missing:
            raise InputError(
                f"{role} must give every mapped coordinate ({', '.join(names)})"
                + (f"; unknown: {', '.join(map(str, unknown))}" if unknown else "")
                + (f"; missing: {', '.join(missing)}" if missing else "")
            )
        pose = [pose[n] for n in names]
    try:
        x = np.array(pose, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(
            f"{role} must be numbers (values of {', '.join(names)}), got {pose!r}"
        ) from None
    if not np.all(np.isfinite(x)):
        raise InputError(f"{role} must be finite numbers, got {pose!r}")
    if x.size == d:
        return x
    if index is not None and x.size == base.size:
        others = [k for k in range(base.size) if k not in index]
        off = [k for k in others if not math.isclose(x[k], base[k], rel_tol=0, abs_tol=1e-9)]
        if off:
            raise InputError(
                f"{role}: natural coordinate(s) {', '.join(map(str, off))} are not at the map's "
                f"base pose ({', '.join(f'{base[k]:.4g}' for k in off)}): the map covers "
                f"{', '.join(names)} only"
            )
        return x[index]
    raise InputError(
        f"{role} has {x.size} values; give {d} (the map's {', '.join(names)})"
        + (f" or {base.size} (natural coordinates)" if base.size and base.size != d else "")
    )


def _check_on_map(x: np.ndarray, cmap: Any, wraps, role: str) -> np.ndarray:
    """x with wrapping axes moved into [-pi, pi), or an InputError when off
    the map along an axis that does not wrap."""
    x = _wrapped(x, wraps)
    for k, (name, e) in enumerate(zip(cmap.coordinates, cmap.edges, strict=True)):
        if not wraps[k] and not (e[0] <= x[k] <= e[-1]):
            raise InputError(
                f"{role}: {name} = {x[k]:.6g} is off the map ({name} from {e[0]:.6g} to "
                f"{e[-1]:.6g})"
            )
    return x


def _nearest_yes(x: np.ndarray, lower, upper, yes_ids: np.ndarray, wraps) -> tuple[int, float]:
    """The YES box nearest x (Euclidean, across wraps) and the distance."""
    if yes_ids.size == 0:
        return -1, math.inf
    lo, hi = lower[yes_ids], upper[yes_ids]
    best = np.full(yes_ids.size, np.inf)
    for s in _shifts(wraps, x, x):
        y = x + s
        gap = np.maximum(lo - y, 0.0) + np.maximum(y - hi, 0.0)
        best = np.minimum(best, np.linalg.norm(gap, axis=1))
    j = int(np.argmin(best))
    return int(yes_ids[j]), float(best[j])


def _where(names, x) -> str:
    return ", ".join(f"{n}={v:.4g}" for n, v in zip(names, x, strict=True))


def _describe_point(cmap, x, role, lower, upper, verdict, labels, volumes, wraps, prefer=()):
    """(box id or -1, label, words) for a start or goal; of the YES boxes
    holding x, one of a region in ``prefer`` if any (a point on the faces
    of boxes of two regions meeting at a corner), else the one of largest
    margin."""
    names = tuple(cmap.coordinates)
    held = locate(lower, upper, wraps, x)
    yes = held[verdict[held] == YES]
    preferred = yes[np.isin(labels[yes], list(prefer))]
    yes = preferred if preferred.size else yes
    if yes.size:
        # several YES boxes hold a point on their shared faces: the largest margin
        margins = np.nan_to_num(np.asarray(cmap.margin_lower, dtype=float)[yes], nan=-np.inf)
        box = int(yes[np.argmax(margins)])
        label = int(labels[box])
        size = int(np.count_nonzero(labels == label))
        share = float(volumes[labels == label].sum() / volumes.sum())
        words = (
            f"{role} ({_where(names, x)}) is in certified region {label} ({size} YES boxes, "
            f"{100 * share:.1f}% of the mapped volume)"
        )
        return box, label, words
    if held.size:
        k = int(held[np.argmax(verdict[held] == NO)])  # a proven NO box first
        verdict_word = {NO: "proven NO", MARGINAL: "undecided"}.get(int(verdict[k]), "undecided")
        reason = ""
        boxes = getattr(cmap, "boxes", None)
        if boxes is not None and hasattr(boxes, "reason"):
            reason = f" ({np.asarray(boxes.reason)[k]})"
        box = ", ".join(
            f"{n} [{a:.4g}, {b:.4g}]" for n, a, b in zip(names, lower[k], upper[k], strict=True)
        )
        why = f"the box holding it ({box}) is {verdict_word}{reason}"
    else:
        why = "no box of the map holds it"
    near, dist = _nearest_yes(x, lower, upper, np.flatnonzero(verdict == YES), wraps)
    if near < 0:
        nearest = "the map has no certified YES box"
    else:
        # the box's point nearest x, across a seam where that is nearer
        shifted = x + _shifts(wraps, x, x)
        inside = np.clip(shifted, lower[near], upper[near])
        corner = inside[int(np.argmin(np.linalg.norm(inside - shifted, axis=1)))]
        nearest = (
            f"nearest certified region: {int(labels[near])}, {dist:.4g} away (its box "
            + ", ".join(
                f"{n} [{a:.4g}, {b:.4g}]"
                for n, a, b in zip(names, lower[near], upper[near], strict=True)
            )
            + f", nearest point {_where(names, corner)})"
        )
    return -1, 0, f"{role} ({_where(names, x)}) is in no certified YES box: {why}; {nearest}"


def _route_graph(lower, upper, wraps, nodes: np.ndarray):
    """Face pairs among ``nodes`` (box ids): (a, b, axis, face centre in a's
    coordinates, in b's), as box ids of the map."""
    a, b, axis, face_lo, face_hi = face_pairs(lower[nodes], upper[nodes], wraps)
    centre_a = 0.5 * (face_lo + face_hi)
    centre_a[np.arange(a.size), axis] = face_lo[np.arange(a.size), axis]
    centre_b = centre_a.copy()
    rows = np.arange(a.size)
    centre_b[rows, axis] = lower[nodes[b], axis]
    return nodes[a], nodes[b], centre_a, centre_b


def certified_path(
    cmap: Any,
    start: Any,
    goal: Any,
    *,
    maximise_margin: bool = False,
    robot: Any = None,
    shortcuts: bool = True,
) -> CertifiedPath:
    """A path of straight steps from the start to the goal inside one
    certified region, every point proven POC (module docstring).

    Args:
        cmap: a :class:`~cdpm.certify.map.CertifiedMap`.
        start, goal: poses: ``{coordinate: value}``, values of the mapped
            coordinates in the map's order, the robot's natural coordinates
            (those not mapped at the map's base pose), or a pose name (with
            ``robot``). Unlike a sampled map's path, the ends are not moved:
            each must lie in a certified YES box.
        maximise_margin: maximise the smallest margin lower bound of the
            route's boxes between the start's and the goal's (bottleneck),
            then take the shortest such route; default the shortest route.
        robot: the map's robot, for pose names (default: loaded from the
            spec the map's provenance records) and the natural coordinates'
            names.
        shortcuts: straighten the route where the allowed boxes cover the
            straight segment (default True).

    Returns:
        :class:`CertifiedPath`.

    Raises:
        NotConnectedError: the start or the goal lies in no certified YES
            box (the message names the box holding it, its verdict and the
            nearest certified region), or they lie in different regions.
        InputError: a pose off the map, of the wrong length, or a pose name
            without the robot.
    """
    names, lower, upper, verdict, margin_lower, wraps = _map_arrays(cmap)
    base = np.asarray(getattr(cmap, "base", np.zeros(0)), dtype=float).reshape(-1)
    s_x = _check_on_map(_pose_point(cmap, start, "start", robot, base), cmap, wraps, "start")
    g_x = _check_on_map(_pose_point(cmap, goal, "goal", robot, base), cmap, wraps, "goal")
    labels = np.asarray(cmap.regions())
    volumes = np.prod(upper - lower, axis=1)
    info = (lower, upper, verdict, labels, volumes, wraps)
    s_box, s_label, s_words = _describe_point(cmap, s_x, "start", *info)
    g_box, g_label, g_words = _describe_point(cmap, g_x, "goal", *info)
    if s_box >= 0 and g_box >= 0 and s_label != g_label:
        # an end on the corner of two regions' boxes: the region the other end is in
        held = locate(lower, upper, wraps, g_x)
        goal_labels = set(labels[held[verdict[held] == YES]].tolist())
        s_box, s_label, s_words = _describe_point(cmap, s_x, "start", *info, goal_labels)
        g_box, g_label, g_words = _describe_point(cmap, g_x, "goal", *info, {s_label})
    if s_box < 0 or g_box < 0 or s_label != g_label:
        if s_box >= 0 and g_box >= 0:
            message = f"{s_words}; {g_words}: no certified path joins them"
        else:
            message = f"{s_words}; {g_words}"
        raise NotConnectedError(
            message,
            s_label,
            g_label,
            start_pose=dict(zip(names, map(float, s_x), strict=True)),
            goal_pose=dict(zip(names, map(float, g_x), strict=True)),
            start_size=int(np.count_nonzero(labels == s_label)) if s_label else 0,
            goal_size=int(np.count_nonzero(labels == g_label)) if g_label else 0,
        )
    region = np.flatnonzero(labels == s_label)
    margin = np.where(np.isfinite(margin_lower), margin_lower, -np.inf)
    route, threshold = _box_route(
        lower, upper, wraps, region, margin, s_box, g_box, maximise_margin
    )
    allowed = region
    if maximise_margin and math.isfinite(threshold):
        keep = (margin[region] >= threshold) | np.isin(region, (s_box, g_box))
        allowed = region[keep]
    points, _ = _polyline(lower, upper, wraps, route, s_x, g_x)
    if shortcuts:
        points = _shortcut(points, lower[allowed], upper[allowed], wraps)
    steps, boxes, seams = _cut_steps(points, lower, upper, allowed, wraps)
    if steps.size:
        # the steps' own ends (inside their boxes), and whole turns added
        # along the path where it crosses a seam, so that it runs on continuously
        mapped = np.concatenate([steps[:1, 0], steps[:, 1]])
        turns = np.zeros_like(mapped)
        jump = np.round((steps[:-1, 1] - steps[1:, 0]) / TWO_PI) * TWO_PI
        turns[2:] = np.cumsum(jump, axis=0)
        waypoints = mapped + turns
    else:
        mapped, waypoints = s_x[None].copy(), s_x[None].copy()
    natural_names = _natural_names(cmap)
    if robot is not None:
        natural_names = tuple(robot.coordinate_names)
    index = _mapped_index(cmap, robot)
    if index is not None and base.size:
        natural = np.tile(base, (waypoints.shape[0], 1))
        natural[:, index] = mapped
        if not natural_names:
            natural_names = tuple(
                names[index.index(k)] if k in index else f"q{k}" for k in range(base.size)
            )
    else:
        natural, natural_names = mapped, names
    units = tuple(getattr(cmap, "units", ()) or ())
    if len(units) != len(names):
        units = tuple("rad" if w else "" for w in wraps)
    boxes_obj = getattr(cmap, "boxes", None)
    unit = str(getattr(boxes_obj, "margin_unit", "m")) if boxes_obj is not None else "m"
    return CertifiedPath(
        coordinates=names,
        units=units,
        waypoints=waypoints,
        map_waypoints=mapped,
        steps=steps,
        boxes=boxes,
        natural=natural,
        natural_names=tuple(natural_names),
        margins=margin_lower[boxes].astype(float) if boxes.size else np.zeros(0),
        margin_unit=unit,
        region=int(s_label),
        region_boxes=int(region.size),
        region_volume=float(volumes[region].sum() / volumes.sum()),
        route=np.asarray(route, dtype=np.intp),
        maximise_margin=bool(maximise_margin),
        threshold=float(threshold) if maximise_margin else float("nan"),
        seam_crossings=seams,
        start=s_x,
        goal=g_x,
    )


def _box_route(lower, upper, wraps, region, margin, s_box, g_box, maximise):
    """Box ids from s_box to g_box over face-sharing boxes of the region,
    and the bottleneck threshold (NaN unless ``maximise``)."""
    if s_box == g_box:
        return [s_box], (float(margin[s_box]) if maximise else float("nan"))
    a, b, ca, cb = _route_graph(lower, upper, wraps, region)
    local = np.full(lower.shape[0], -1, dtype=np.intp)
    local[region] = np.arange(region.size)
    edges = np.stack([local[a], local[b]])
    centre = 0.5 * (lower + upper)
    lengths = np.linalg.norm(ca - centre[a], axis=1) + np.linalg.norm(cb - centre[b], axis=1)
    n = region.size
    s, g = int(local[s_box]), int(local[g_box])
    threshold = float("nan")
    if maximise:
        node_margin = margin[region].copy()
        node_margin[[s, g]] = np.inf
        threshold = bottleneck(n, edges, node_margin, s, g)
        wide = np.minimum(node_margin[edges[0]], node_margin[edges[1]]) >= threshold
        edges, lengths = edges[:, wide], lengths[wide]
    if not connected(n, edges, s, g):  # pragma: no cover - the labels join them
        raise InputError("the certified region's boxes do not join the start and the goal")
    route = shortest_route(n, edges, lengths, s, g, False)
    return [int(region[i]) for i in route], threshold


def _face_between(lower, upper, wraps, i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    """The centre of the face boxes i and j share, in i's and in j's
    coordinates."""
    a, b, ca, cb = _route_graph(lower, upper, wraps, np.array([i, j]))
    k = int(np.flatnonzero(a == i)[0]) if np.any(a == i) else -1
    if k >= 0:
        return ca[k], cb[k]
    k = int(np.flatnonzero(a == j)[0])
    return cb[k], ca[k]


def _polyline(lower, upper, wraps, route, s_x, g_x):
    """Start, the centres of the faces between consecutive route boxes,
    goal, as one continuous chain (P, d); and per segment the route box
    holding it (P - 1,)."""
    d = s_x.size
    pieces = [(_in_box(s_x, lower[route[0]], upper[route[0]], wraps), route[0])]
    ends = []
    for i, j in zip(route[:-1], route[1:], strict=True):
        fi, fj = _face_between(lower, upper, wraps, i, j)
        ends.append(fi)
        pieces.append((fj, j))
    ends.append(_in_box(g_x, lower[route[-1]], upper[route[-1]], wraps))
    # chain: each segment from pieces[k][0] to ends[k] inside box pieces[k][1]
    points = np.empty((len(ends) + 1, d))
    points[0] = pieces[0][0]
    for k, ((p0, _), p1) in enumerate(zip(pieces, ends, strict=True)):
        points[k + 1] = points[k] + (p1 - p0)
    return points, np.array([box for _, box in pieces], dtype=np.intp)


def _in_box(x, lo, hi, wraps) -> np.ndarray:
    """x moved by whole turns along axes that wrap into the box [lo, hi]."""
    for s in _shifts(wraps, x, x):
        y = x + s
        if np.all((lo <= y) & (y <= hi)):
            return y
    raise InputError("a point is not in its box")  # pragma: no cover - located before


def _covered(a, b, lower, upper, wraps):
    """:func:`segment_cover` of a -> b over the boxes and their copies a
    whole turn away along axes that wrap: (box ids, t0, t1, shifts) or None."""
    shifts = _shifts(wraps, np.minimum(a, b), np.maximum(a, b))
    N, d = lower.shape
    lo = (lower[None] + shifts[:, None]).reshape(-1, d)
    hi = (upper[None] + shifts[:, None]).reshape(-1, d)
    # only the boxes meeting the segment's bounding box can cover it
    near = np.flatnonzero(np.all((lo <= np.maximum(a, b)) & (hi >= np.minimum(a, b)), axis=1))
    cover = segment_cover(a, b, lo[near], hi[near])
    if cover is None:
        return None
    ids, t0, t1 = cover
    ids = near[ids]
    return ids % N, t0, t1, shifts[ids // N]


def _shortcut(points: np.ndarray, lower, upper, wraps) -> np.ndarray:
    """Drop corners of the polyline while the straight segment that
    replaces them is covered by the boxes (greedy from the start: from each
    kept point, on to the furthest point reached by a run of covered
    segments)."""
    out, i, n = [points[0]], 0, points.shape[0]
    while i < n - 1:
        j = i + 1
        while j + 1 < n and _covered(points[i], points[j + 1], lower, upper, wraps) is not None:
            j += 1
        out.append(points[j])
        i = j
    return np.array(out)


def _cut_steps(points, lower, upper, allowed, wraps):
    """Cut every segment of the polyline where it passes from box to box:
    steps (k - 1, 2, d) in their box's coordinates, the boxes (k - 1,), and
    the waypoints where a seam is crossed."""
    steps, boxes = [], []
    lo, hi = lower[allowed], upper[allowed]
    for p, q in zip(points[:-1], points[1:], strict=True):
        if np.array_equal(p, q):
            continue
        cover = _covered(p, q, lo, hi, wraps)
        if cover is None:  # pragma: no cover - each segment lies in a box by construction
            raise InputError("a segment of the certified path is not covered by its boxes")
        ids, t0, t1, shifts = cover
        for box, u0, u1, s in zip(ids, t0, t1, shifts, strict=True):
            if u1 <= u0:
                continue
            x0 = p + u0 * (q - p) - s
            x1 = p + u1 * (q - p) - s
            if u1 == 1.0:
                x1 = q - s
            k = int(allowed[box])
            # rounding may leave an end a hair outside its box: clip to it
            steps.append(
                np.stack([np.clip(x0, lower[k], upper[k]), np.clip(x1, lower[k], upper[k])])
            )
            boxes.append(k)
    if not steps:
        d = points.shape[1]
        return np.zeros((0, 2, d)), np.zeros(0, dtype=np.intp), ()
    steps_arr = np.array(steps)
    # a segment through a box's corner can clip a piece of a neighbour of no
    # length to speak of: dropped (the steps either side meet within it)
    length = np.linalg.norm(steps_arr[:, 1] - steps_arr[:, 0], axis=1)
    keep = length > CERTIFIED_PATH_MIN_STEP
    if keep.any() and not keep.all():
        steps_arr, boxes = steps_arr[keep], [b for b, k in zip(boxes, keep, strict=True) if k]
    # a step ending a whole turn away from where the next one starts: a seam
    jumps = np.abs(steps_arr[1:, 0] - steps_arr[:-1, 1]) > math.pi
    seams = tuple(int(i) + 1 for i in np.flatnonzero(np.any(jumps, axis=1)))
    return steps_arr, np.array(boxes, dtype=np.intp), seams
