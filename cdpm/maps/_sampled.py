"""Neighbours among the samples of a sampled map: the rule that joins
POC samples into regions (:func:`cdpm.maps.regions.label_regions`) and
paths (:func:`cdpm.paths.poc_path`), and the distance it uses (angles
compared modulo 2 pi). docs/maps.md, "Regions and paths".
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.errors import InputError, float_scalar
from cdpm.numerics import REGION_GAP_FACTOR, REGION_RADIUS_FACTOR

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.maps.regions import MapLayout

__all__ = [
    "angle_offset",
    "sample_points",
    "sample_distance",
    "default_radius",
    "check_radius",
    "sample_edges",
]

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
