"""POC regions of a workspace map: connected sets of POC poses.

Seed paper Lemma 1 / Remark 10: a connected set of equilibria whose
linearisations are all positive output controllable (POC) is a POC set.
:func:`label_regions` numbers the connected components of a map's YES
poses: face-adjacent grid poses, wrapping around axes of angles whose
evenly spaced values span a full turn; on sampled maps, samples within a
radius (angles compared modulo 2 pi). docs/maps.md, "Regions and paths",
states the rules in full (which angles wrap, and why that never joins
regions wrongly).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError, float_scalar
from cdpm.maps._store import open_map
from cdpm.maps._store_variables import write_variable
from cdpm.model.robot import load_robot
from cdpm.numerics import (
    REGION_BASE_ATOL,
    REGION_GAP_FACTOR,
    REGION_RADIUS_FACTOR,
    REGION_WRAP_RTOL,
)
from cdpm.verdicts import YES

__all__ = [
    "label_regions",
    "attach_regions",
    "region_of",
    "REGION_VARIABLE",
    "angle_offset",
    "sample_points",
    "sample_distance",
    "default_radius",
    "check_radius",
    "sample_edges",
]

#: name of the region variable in a map
REGION_VARIABLE = "poc_region"
#: most regions listed in the ``regions`` attribute (the largest ones)
REGIONS_LISTED = 1000

_TWO_PI = 2.0 * math.pi


# ------------------------------------------------------------------ layout


# ------------------------------------------------- neighbours among samples
#
# The rule that joins POC samples of a sampled map into regions and paths
# (cdpm.regions.paths), and the distance it uses (angles compared modulo
# 2 pi). docs/maps.md, "Regions and paths".

_TWO_PI = 2.0 * math.pi


def angle_offset(a, b):
    """b - a for angles, in [-pi, pi)."""
    return (np.asarray(b) - np.asarray(a) + math.pi) % _TWO_PI - math.pi


def sample_points(layout: MapLayout) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, d) for a periodic KD-tree and the box sizes (d,): angles
    modulo 2 pi from the axis minimum in a box of 2 pi; other coordinates
    shifted to start at 0 in a box wider than twice their span (no wrap)."""
    cols, box = [], []
    for v, w in zip(layout.values, layout.wrap, strict=True):
        shifted = v - float(v.min())
        cols.append(
            np.where(shifted < _TWO_PI, shifted, np.mod(shifted, _TWO_PI)) if w else shifted
        )
        box.append(_TWO_PI if w else 3.0 * float(shifted.max()) + 1.0)
    return np.stack(cols, axis=1), np.array(box)


def sample_distance(layout: MapLayout, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances between points (..., d) in the map's coordinates, angles
    of axes that wrap compared modulo 2 pi (broadcast over leading dims)."""
    diff = np.asarray(b, dtype=float) - np.asarray(a, dtype=float)
    wrap = np.array([w is not None for w in layout.wrap])
    diff = np.where(wrap, angle_offset(0.0, diff), diff)
    return np.sqrt(np.sum(diff**2, axis=-1))


def default_radius(layout: MapLayout) -> float:
    """The default neighbourhood radius of a sampled map: REGION_RADIUS_FACTOR
    times the mean nearest-neighbour distance of the samples; over one axis,
    REGION_GAP_FACTOR times the largest gap between consecutive samples (the
    seam of an angle not counted)."""
    # scipy: loaded on first use
    from scipy.spatial import cKDTree

    points, box = sample_points(layout)
    if points.shape[0] < 2:
        return 0.0
    if points.shape[1] == 1:
        return float(REGION_GAP_FACTOR * np.max(np.diff(np.sort(points[:, 0]))))
    dist, _ = cKDTree(points, boxsize=box).query(points, k=2)
    return float(REGION_RADIUS_FACTOR * np.mean(dist[:, 1]))


def check_radius(radius: Any) -> float:
    try:
        r = float_scalar(radius)
    except (TypeError, ValueError) as exc:
        raise InputError(f"radius must be a distance >= 0, got {radius!r}") from exc
    if not (math.isfinite(r) and r >= 0):
        raise InputError(f"radius must be a finite distance >= 0, got {radius!r}")
    return r


def sample_edges(layout: MapLayout, yes: np.ndarray, radius: float) -> tuple:
    """Edges (i, j) (sample indices, i < j) between the samples where
    ``yes`` holds (e.g. the YES ones) at most ``radius`` apart, and their
    lengths. Over one axis only consecutive samples (no other sample
    between them; around the turn for an angle) are joined, so that a
    sample where ``yes`` fails always separates."""
    # scipy: loaded on first use
    from scipy.spatial import cKDTree

    points, box = sample_points(layout)
    if points.shape[1] == 1:
        return _consecutive_edges(points[:, 0], float(box[0]), layout.wrap[0], yes, radius)
    nodes = np.flatnonzero(yes)
    if nodes.size < 2:
        return np.zeros((2, 0), dtype=np.intp), np.zeros(0)
    tree = cKDTree(points[nodes], boxsize=box)
    pairs = tree.query_pairs(radius, output_type="ndarray")
    i, j = nodes[pairs[:, 0]], nodes[pairs[:, 1]]
    values = np.stack(layout.values, axis=1)
    return np.stack([i, j]), sample_distance(layout, values[i], values[j])


def _consecutive_edges(
    x: np.ndarray, period: float, wrap: str | None, yes: np.ndarray, radius: float
) -> tuple:
    """:func:`sample_edges` over one axis: samples at ``x`` (n,) [shifted to
    start at 0], an angle (``wrap``) closing the turn after ``period``. On
    an angle, a gap is the arc with no sample in it, and one of more than
    half a turn joins nothing: the step would be taken (and drawn, and
    measured) the other way round, through the other samples."""
    order = np.argsort(x, kind="stable")
    i, j = order[:-1], order[1:]
    gaps = x[j] - x[i]
    if wrap is not None and order.size > 2:  # the seam: the last sample, then the first
        i, j = np.append(i, order[-1]), np.append(j, order[0])
        gaps = np.append(gaps, x[order[0]] + period - x[order[-1]])
    elif wrap is not None:  # two samples: the shorter of their two arcs
        gaps = np.minimum(gaps, period - gaps)
    keep = (gaps <= radius) & yes[i] & yes[j]
    if wrap is not None:
        keep &= gaps <= 0.5 * period
    i, j = i[keep], j[keep]
    return np.stack([np.minimum(i, j), np.maximum(i, j)]), gaps[keep]


# ------------------------------------------------------------ map layout


@dataclass(frozen=True)
class MapLayout:
    """How a map's poses are laid out (read from the dataset).

    Attributes:
        mode: ``"grid"`` or ``"sample"``.
        axes: axis (coordinate) names, in the map's order.
        dims: pose dimensions of the dataset (``axes`` or ``("sample",)``).
        values: per axis, the grid values (n_k,) or per-sample values (n,).
        units: per axis, ``"rad"``, ``"m"`` or ``""`` (unknown: never wraps).
        wrap: per axis, ``None``, ``"closed"`` (first and last values are
            the same pose) or ``"open"`` (last next to first); sampled
            maps: ``"modulo"`` for every angle (compared modulo 2 pi).
        shape: shape of the pose dimensions.
    """

    mode: str
    axes: tuple[str, ...]
    dims: tuple[str, ...]
    values: tuple[np.ndarray, ...]
    units: tuple[str, ...]
    wrap: tuple[str | None, ...]
    shape: tuple[int, ...]

    @property
    def wrapped(self) -> tuple[str, ...]:
        """Names of the axes that wrap around."""
        return tuple(a for a, w in zip(self.axes, self.wrap, strict=True) if w)


def grid_wrap(values: np.ndarray, unit: str) -> str | None:
    """``"closed"``, ``"open"`` or None for a grid axis (see the module doc)."""
    if unit != "rad" or values.size < 2:
        return None
    v = np.sort(values)
    step = (v[-1] - v[0]) / (v.size - 1)
    if step <= 0 or np.max(np.abs(np.diff(v) - step)) > REGION_WRAP_RTOL * step:
        return None
    span = v[-1] - v[0]
    if abs(span - _TWO_PI) <= REGION_WRAP_RTOL * step:
        return "closed"
    if abs(span + step - _TWO_PI) <= REGION_WRAP_RTOL * step:
        return "open"
    return None


def map_layout(ds) -> MapLayout:
    """The :class:`MapLayout` of a map dataset.

    Raises:
        InputError: no ``poc`` variable, or axes the dataset does not hold.
    """
    if "poc" not in getattr(ds, "data_vars", {}):
        raise InputError(
            "not a cdpm map: no 'poc' variable; give a map from cdpm.workspace_map "
            "or `cdpm map ... --out STORE`"
        )
    dims = tuple(ds["poc"].dims)
    sampled = dims == ("sample",)
    axes = ds.attrs.get("axes")
    if isinstance(axes, str):
        axes = [axes]
    if not axes:
        if sampled:
            axes = [n for n, c in ds.coords.items() if c.dims == ("sample",) and n != "sample"]
        else:
            axes = list(dims)
    axes = tuple(str(a) for a in axes)
    missing = [a for a in axes if a not in ds.coords]
    if missing or (not sampled and set(axes) != set(dims)) or not axes:
        raise InputError(
            f"map axes {', '.join(axes) or '(none)'} do not match its dimensions "
            f"{', '.join(dims)}; give a map from cdpm.workspace_map"
        )
    axes = axes if sampled else dims  # grid: array order
    values = tuple(np.asarray(ds[a].values, dtype=float).reshape(-1) for a in axes)
    units = tuple(str(ds[a].attrs.get("units", "")) for a in axes)
    if sampled:
        wrap = tuple("modulo" if u == "rad" else None for u in units)
    else:
        wrap = tuple(grid_wrap(v, u) for v, u in zip(values, units, strict=True))
    mode, shape = "sample" if sampled else "grid", tuple(int(s) for s in ds["poc"].shape)
    return MapLayout(mode, axes, dims, values, units, wrap, shape)


def as_dataset(map_or_path):
    """A map dataset from a Dataset or the path of its store."""
    if isinstance(map_or_path, (str, os.PathLike)):
        return open_map(map_or_path)
    if not hasattr(map_or_path, "data_vars"):
        raise InputError(
            f"expected a map (xarray.Dataset) or the path of its store, got "
            f"{type(map_or_path).__name__}"
        )
    return map_or_path


# ------------------------------------------------------------------- grid


@dataclass(frozen=True)
class GridIndex:
    """The grid of distinct poses: each axis sorted ascending, and a closed
    axis without its last value (a copy of its first).

    Attributes:
        order: per axis, dataset index of each distinct position (m_k,).
        position: per axis, distinct position of each dataset index (n_k,).
        ring: per axis, the distinct positions form a circle.
    """

    order: tuple[np.ndarray, ...]
    position: tuple[np.ndarray, ...]
    ring: tuple[bool, ...]

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(o.size for o in self.order)


def grid_index(layout: MapLayout) -> GridIndex:
    """The :class:`GridIndex` of a grid map."""
    orders, positions, rings = [], [], []
    for v, w in zip(layout.values, layout.wrap, strict=True):
        order = np.argsort(v, kind="stable")
        position = np.empty(v.size, dtype=np.intp)
        position[order] = np.arange(v.size)
        if w == "closed":
            position[order[-1]] = 0
            order = order[:-1]
        orders.append(order)
        positions.append(position)
        rings.append(w is not None)
    return GridIndex(tuple(orders), tuple(positions), tuple(rings))


def distinct(values: np.ndarray, layout: MapLayout, index: GridIndex) -> np.ndarray:
    """Values (a YES mask, margins) on the distinct grid: axes sorted, and a
    closed axis's seam pose taking the smaller of its two copies (for a YES
    mask: YES only when both copies are)."""
    out = np.asarray(values)
    for k, w in enumerate(layout.wrap):
        if w == "closed":
            v = np.argsort(layout.values[k], kind="stable")
            first, last = [slice(None)] * out.ndim, [slice(None)] * out.ndim
            first[k], last[k] = v[0], v[-1]
            out = out.copy()
            out[tuple(first)] = np.minimum(out[tuple(first)], out[tuple(last)])
    return out[np.ix_(*index.order)]


def _grid_components(yes: np.ndarray, rings: tuple[bool, ...]) -> np.ndarray:
    """Component id (>= 1) of each YES pose of the distinct grid, 0 elsewhere:
    face-adjacent components, merged across the seam of each ring axis."""
    # scipy: loaded on first use
    from scipy import ndimage

    structure = ndimage.generate_binary_structure(yes.ndim, 1)
    lab, k = ndimage.label(yes, structure=structure)
    pairs = []
    for axis, ring in enumerate(rings):
        if ring and yes.shape[axis] >= 2:
            a = np.take(lab, 0, axis=axis).reshape(-1)
            b = np.take(lab, yes.shape[axis] - 1, axis=axis).reshape(-1)
            both = (a > 0) & (b > 0)
            pairs.append(np.stack([a[both], b[both]]))
    if not pairs or k == 0:
        return lab
    # scipy: loaded on first use
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    edges = np.concatenate(pairs, axis=1)
    graph = coo_matrix((np.ones(edges.shape[1]), (edges[0], edges[1])), shape=(k + 1, k + 1))
    _, merged = connected_components(graph, directed=False)
    # label 0 (background) is its own component unless merged: keep it 0
    out = merged[lab] + 1
    out[lab == 0] = 0
    return out


def _rank_by_size(component: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(labels like ``component`` numbered 1..K by decreasing size, ties
    first in C order; sizes (K,))."""
    flat = component.reshape(-1)
    ids, first, counts = np.unique(flat, return_index=True, return_counts=True)
    keep = ids > 0
    ids, first, counts = ids[keep], first[keep], counts[keep]
    rank = np.lexsort((first, -counts))
    new = np.zeros(int(flat.max(initial=0)) + 1, dtype=np.int32)
    new[ids[rank]] = np.arange(1, ids.size + 1, dtype=np.int32)
    return new[component], counts[rank]


def _circular_extent(positions: np.ndarray, period: float) -> tuple[float, float] | None:
    """(lo, hi) positions on a circle of length ``period`` covering
    ``positions`` with the largest gap left out, when that gap is not the
    seam's (then lo > hi); None when the seam's gap is the largest."""
    p = np.unique(positions)
    if p.size < 2:
        return None
    gaps = np.diff(p)
    seam = p[0] + period - p[-1]
    i = int(np.argmax(gaps))
    if gaps[i] <= seam:
        return None
    return float(p[i + 1]), float(p[i])


def _grid_regions(labels: np.ndarray, sizes, layout: MapLayout, index: GridIndex) -> list:
    """The ``regions`` entries of a grid map (labels on the distinct grid)."""
    # scipy: loaded on first use
    from scipy import ndimage

    boxes = ndimage.find_objects(labels, max_label=min(len(sizes), REGIONS_LISTED))
    sorted_values = [v[o] for v, o in zip(layout.values, index.order, strict=True)]
    out = []
    for k, box in enumerate(boxes):
        if box is None:  # pragma: no cover - every label 1..K is used
            continue
        bbox, wraps = {}, []
        member = labels[box] == k + 1
        for axis, name in enumerate(layout.axes):
            vals = sorted_values[axis]
            lo, hi = vals[box[axis].start], vals[box[axis].stop - 1]
            if index.ring[axis]:
                other = tuple(a for a in range(labels.ndim) if a != axis)
                used = np.flatnonzero(member.any(axis=other)) + box[axis].start
                extent = _circular_extent(used, vals.size)
                if extent is not None and extent[1] == 0 and layout.wrap[axis] == "closed":
                    # ends at the seam pose, which is also the axis's last value
                    lo, hi = vals[int(extent[0])], float(layout.values[axis].max())
                elif extent is not None:
                    lo, hi = vals[int(extent[0])], vals[int(extent[1])]
                    wraps.append(name)
            bbox[name] = [float(lo), float(hi)]
        out.append({"label": k + 1, "size": int(sizes[k]), "bbox": bbox, "wraps": wraps})
    return out


def _label_grid(ds, layout: MapLayout) -> tuple[np.ndarray, list]:
    index = grid_index(layout)
    poc = np.asarray(ds["poc"].transpose(*layout.axes).values)
    yes = distinct(poc == YES, layout, index)
    labels, sizes = _rank_by_size(_grid_components(yes, index.ring))
    regions = _grid_regions(labels, sizes, layout, index)
    # back to dataset order; a closed axis's last value copies its first
    take = tuple(np.asarray(p) for p in index.position)
    return labels[np.ix_(*take)], regions


# ---------------------------------------------------------------- samples


def _label_samples(ds, layout: MapLayout, radius: float) -> tuple[np.ndarray, list]:
    # scipy: loaded on first use
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    yes = np.asarray(ds["poc"].values) == YES
    n = yes.size
    edges, _ = sample_edges(layout, yes, radius)
    graph = coo_matrix((np.ones(edges.shape[1]), (edges[0], edges[1])), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    component = np.where(yes, comp + 1, 0)
    labels, sizes = _rank_by_size(component)
    regions = []
    order = np.argsort(labels, kind="stable")
    starts = np.searchsorted(labels[order], np.arange(1, sizes.size + 2))
    for k in range(min(sizes.size, REGIONS_LISTED)):
        members = order[starts[k] : starts[k + 1]]
        bbox, wraps = {}, []
        for name, v, w in zip(layout.axes, layout.values, layout.wrap, strict=True):
            vals = v[members]
            lo, hi = float(vals.min()), float(vals.max())
            if w:
                base = float(v.min())
                extent = _circular_extent(np.mod(vals - base, _TWO_PI), _TWO_PI)
                if extent is not None:
                    lo, hi = base + extent[0], base + extent[1]
                    wraps.append(name)
            bbox[name] = [lo, hi]
        regions.append({"label": k + 1, "size": int(sizes[k]), "bbox": bbox, "wraps": wraps})
    return labels, regions


# ------------------------------------------------------------------ public


def label_regions(ds, *, radius: float | None = None):
    """Number the connected regions of POC (``poc == YES``) poses of a map.

    Args:
        ds: a map (``xarray.Dataset`` from :func:`cdpm.workspace_map` or
            :func:`cdpm.open_map`).
        radius: sampled maps only: the neighbourhood radius, in the sampled
            coordinates [rad or m, as numbers]; default :data:`REGION_RADIUS_FACTOR`
            times the mean nearest-neighbour distance of the samples (over
            one axis, :data:`REGION_GAP_FACTOR` times the largest gap between
            consecutive samples, which alone are neighbours there).

    Returns:
        ``xarray.DataArray`` ``poc_region`` (int32) over the map's pose
        dimensions: 0 for a pose in no region, 1..K by decreasing size.
        Attributes: ``long_name``, ``description`` (the adjacency rule, the
        axes that wrap, the radius, how sizes count), ``adjacency`` (``"face"``,
        ``"radius"``, or ``"consecutive"`` for samples over one axis: only
        samples with no other between them, within the radius),
        ``wrapped_axes`` (comma separated), ``radius`` (sampled maps),
        ``n_regions`` (K) and ``regions``: JSON of a list (the REGIONS_LISTED
        largest) of ``{"label", "size", "bbox": {axis: [lo,
        hi]}, "wraps": [axes]}``; ``size`` counts distinct poses (a pose on a
        full-turn seam once); along an axis in ``wraps`` lo > hi: the region
        runs from lo to the end of the turn and on from its start to hi.

    Raises:
        InputError: not a map, a radius on a grid map, or a bad radius.
    """
    # xarray: loaded on first use
    import xarray as xr

    layout = map_layout(ds)
    wrapped = ", ".join(layout.wrapped) or "none"
    attrs: dict[str, Any] = {"long_name": "POC region", "flag_meaning_0": "in no POC region"}
    if layout.mode == "grid":
        if radius is not None:
            raise InputError(
                "radius applies to sampled maps only; grid maps join face-adjacent poses"
            )
        labels, regions = _label_grid(ds, layout)
        rule = (
            "poses adjacent when their indices differ by one along one axis (face "
            f"adjacency); axes spanning a full turn wrap around: {wrapped}"
        )
        attrs["adjacency"] = "face"
    else:
        r = default_radius(layout) if radius is None else check_radius(radius)
        one_axis = len(layout.axes) == 1
        if radius is not None:
            how = "given"
        elif one_axis:
            how = f"{REGION_GAP_FACTOR:g} times the largest gap between consecutive samples"
        else:
            how = f"{REGION_RADIUS_FACTOR:g} times the mean nearest-neighbour distance"
        labels, regions = _label_samples(ds, layout, r)
        rule = (
            f"samples adjacent when their distance in ({', '.join(layout.axes)}) is at "
            f"most radius = {r:.6g} ({how})"
            + (" and no other sample lies between them" if one_axis else "")
            + f"; angles compared modulo 2 pi: {wrapped}"
        )
        attrs["adjacency"] = "consecutive" if one_axis else "radius"
        attrs["radius"] = r
    attrs["description"] = (
        "connected components of the POC poses (poc = yes; marginal, no and not analysed "
        f"poses are in no region, label 0), numbered 1..K by decreasing size; {rule}"
    )
    if "closed" in layout.wrap:
        attrs["description"] += (
            "; sizes count distinct poses: a pose on a full-turn seam (the first and last "
            "value of an axis from -pi to pi) is counted once, so they can sum to fewer than "
            "the YES poses"
        )
    n = int(labels.max(initial=0))
    if n > REGIONS_LISTED:
        attrs["description"] += f"; regions lists the {REGIONS_LISTED} largest of {n}"
    attrs["n_regions"] = n
    attrs["wrapped_axes"] = ",".join(layout.wrapped)
    attrs["regions"] = json.dumps(regions)
    return xr.DataArray(
        labels.astype(np.int32), dims=layout.dims, name=REGION_VARIABLE, attrs=attrs
    )


def region_labels(ds):
    """The map's ``poc_region`` (as stored, else computed on the fly)."""
    if REGION_VARIABLE in ds.data_vars:
        return ds[REGION_VARIABLE]
    return label_regions(ds)


def attach_regions(ds, store: str | os.PathLike | None = None):
    """The map with its POC regions (``poc_region``, :func:`label_regions`)
    added; with ``store``, also written into that zarr store, so that
    :func:`cdpm.open_map` returns them. Idempotent: the labels are computed
    again from ``poc`` and replace any stored ones (safe after a resumed map).

    Args:
        ds: the map (a finished :func:`cdpm.workspace_map` dataset).
        store: the map's zarr store, or None (in memory only).

    Returns:
        ``ds`` with the variable ``poc_region`` (a new Dataset; ``ds`` unchanged).
    """
    return attach_new_regions(ds, store, None)


def attach_new_regions(ds, store, group, read_from_store: bool = False):
    """:func:`attach_regions`, at the end of the run that wrote the map:
    ``group`` is the store's zarr group if that run created the store, and
    the regions are written through it without opening the store again
    (:func:`cdpm.maps._store_variables.write_variable`); None opens the
    store. With ``read_from_store`` (``ds`` was just read from ``store``),
    regions the store holds already, equal to the labels computed now
    (values and attributes), are not written again: a finished map's store
    may be read-only."""
    labels = label_regions(ds)
    stored = ds.get(REGION_VARIABLE) if read_from_store else None
    if store is not None and stored is not None and stored.attrs == labels.attrs:
        if np.array_equal(stored.values, labels.values):
            return ds
    out = ds.drop_vars(REGION_VARIABLE, errors="ignore").assign({REGION_VARIABLE: labels})
    if store is not None:
        write_variable(Path(store).expanduser(), labels, group)
        out = out[sorted(out.data_vars)]  # as open_map lists them
    return out


# -------------------------------------------------------------- locating


def map_robot(ds, why: str):
    """The map's robot, loaded from the spec the map records (``spec``) and
    checked against its hash (``spec_sha256``); InputError when the spec is
    not found or changed since the map was made."""

    spec = ds.attrs.get("spec")
    if not spec or not Path(spec).is_file():
        raise InputError(
            f"{why} needs the map's robot, but its spec {spec or '(not recorded)'} is not "
            "found; run where the spec is, or give axis values instead of pose names"
        )
    robot = load_robot(spec)
    stored = ds.attrs.get("spec_sha256")
    if stored and stored != robot.spec.sha256:
        raise InputError(
            f"{why}: the map was made from an earlier version of {spec} or its URDF "
            f"(sha256 {stored[:12]}, now {robot.spec.sha256[:12]}); make the map again "
            f"(`cdpm map {spec} ... --out STORE --overwrite`)"
        )
    return robot


def named_pose(ds, name: str, robot=None) -> dict[str, float]:
    """Natural coordinates {coordinate: value} [rad or m] of a pose name of
    the map's spec; ``robot``: the map's robot if loaded already."""
    robot = map_robot(ds, f"pose name {name!r}") if robot is None else robot
    natural = robot.to_natural(robot.configuration(name))
    return dict(zip(robot.coordinate_names, map(float, natural), strict=True))


def natural_pose(ds, layout: MapLayout, pose: Any) -> dict[str, float]:
    """The axis values {axis: value} of a pose given as {coordinate: value},
    a sequence in the map's axis order, the robot's natural coordinates
    (one per ``robot_coordinates``) or a pose name of the map's spec;
    coordinates off the axes must equal the map's base pose.

    Raises:
        InputError: unknown or missing coordinates, wrong length, values
            that are not finite numbers, a pose off the map's base, or an
            unknown pose name.
    """
    if isinstance(pose, str):
        pose = named_pose(ds, pose)
    coords = list(ds.attrs.get("robot_coordinates", []) or [])
    base = list(ds.attrs.get("base", []) or [])
    axes = list(layout.axes)
    if isinstance(pose, Mapping):
        given = dict(pose)
        unknown = [k for k in given if k not in axes and k not in coords]
        if unknown:
            raise InputError(
                f"pose coordinate(s) {', '.join(map(str, unknown))} not on this map; its axes: "
                f"{', '.join(axes)}"
            )
        missing = [a for a in axes if a not in given]
        if missing:
            raise InputError(
                f"pose lacks the map axis/axes {', '.join(missing)}; give a value for each of "
                f"{', '.join(axes)}"
            )
    elif isinstance(pose, (Sequence, np.ndarray)) and not isinstance(pose, str):
        values = list(np.asarray(pose, dtype=object).reshape(-1))
        if len(values) == len(axes):
            given = dict(zip(axes, values, strict=True))
        elif coords and len(values) == len(coords):
            given = dict(zip(coords, values, strict=True))
        else:
            full = ""
            if coords and len(coords) != len(axes):
                full = f", or {len(coords)} natural coordinates ({', '.join(coords)})"
            raise InputError(
                f"pose has {len(values)} value(s); give {len(axes)}, one per map axis in the "
                f"map's order ({', '.join(axes)}){full}"
            )
    else:
        raise InputError(
            f"pose must be {{coordinate: value}} or a sequence of numbers, got "
            f"{type(pose).__name__}"
        )
    clean = {}
    for name, value in given.items():
        try:
            x = float(value)
        except (TypeError, ValueError) as exc:
            raise InputError(f"pose coordinate {name!r}: {value!r} is not a number") from exc
        if not math.isfinite(x):
            raise InputError(f"pose coordinate {name!r} must be finite, got {value!r}")
        clean[name] = x
    for name, x in clean.items():
        if name in axes or name not in coords or len(base) != len(coords):
            continue
        b = float(base[coords.index(name)])
        if abs(x - b) > REGION_BASE_ATOL:
            raise InputError(
                f"pose has {name} = {x:.6g}, but this map holds {name} at its base value "
                f"{b:.6g}: the pose is off the map"
            )
    return {a: clean[a] for a in axes}


def nearest_index(ds, layout: MapLayout, pose: Any, radius: float | None = None) -> tuple:
    """Dataset index (one per pose dimension) of the map pose nearest a pose.

    Grid: the nearest value per axis (modulo 2 pi on an axis that wraps;
    off the map beyond half a step outside the range of any other axis).
    Sampled: the nearest sample (off the map beyond ``radius``). Raises
    InputError (:func:`natural_pose`) or for a pose off the map.
    """
    values = natural_pose(ds, layout, pose)
    if layout.mode == "sample":
        samples = np.stack(layout.values, axis=1)
        point = np.array([values[a] for a in layout.axes])
        dist = sample_distance(layout, point, samples)
        i = int(np.argmin(dist))
        limit = default_radius(layout) if radius is None else radius
        if dist[i] > limit * (1 + 1e-9):
            where = ", ".join(f"{k}={v:.4g}" for k, v in values.items())
            raise InputError(
                f"pose ({where}) is off the map: its nearest sample is {dist[i]:.4g} away, "
                f"beyond the neighbourhood radius {limit:.4g}"
            )
        return (i,)
    index = []
    for name, v, w in zip(layout.axes, layout.values, layout.wrap, strict=True):
        x = values[name]
        if w:
            d = np.abs(angle_offset(v, x))
            near = np.flatnonzero(d <= d.min() + 1e-12)
            index.append(int(near[np.argmin(np.abs(v[near] - x))]))
            continue
        lo, hi = float(v.min()), float(v.max())
        s = np.sort(v)
        below = (s[1] - s[0]) / 2 if v.size > 1 else REGION_BASE_ATOL
        above = (s[-1] - s[-2]) / 2 if v.size > 1 else REGION_BASE_ATOL
        if x < lo - below * (1 + 1e-9) or x > hi + above * (1 + 1e-9):
            raise InputError(
                f"pose {name} = {x:.6g} is off the map: axis {name} covers [{lo:.6g}, {hi:.6g}] "
                "(half a step beyond either end at most)"
            )
        index.append(int(np.argmin(np.abs(v - x))))
    return tuple(index)


def region_of(map: Any, pose: Any) -> int:
    """The POC region of the map pose nearest a pose.

    Args:
        map: a map (``xarray.Dataset``) or the path of its store.
        pose: ``{coordinate: value}`` (every map axis), a sequence of values
            in the map's axis order (``ds.attrs["axes"]``), the robot's
            natural coordinates (nv values), angles [rad], translations [m];
            or a pose name of the map's spec (e.g. ``"nominal"``).

    Returns:
        The label of ``poc_region`` there (stored, else computed): 0 when the
        nearest map pose is in no region (its verdict is not YES).

    Raises:
        InputError: a pose off the map (beyond half a step outside a grid
            axis that does not wrap; beyond the neighbourhood radius of
            every sample; coordinates off the axes not at the map's base
            pose), of the wrong length, with unknown coordinates, or an
            unknown pose name (or a spec not found).
    """
    ds = as_dataset(map)
    layout = map_layout(ds)
    labels = region_labels(ds)
    radius = labels.attrs.get("radius") if layout.mode == "sample" else None
    index = nearest_index(ds, layout, pose, radius)
    return int(np.asarray(labels.transpose(*layout.dims).values)[index])
