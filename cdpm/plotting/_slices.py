"""Which slices of a grid map of more than two axes a plot draws, and
which poses of a path lie in each: along an angle axis over a full turn,
values compare modulo 2 pi, and on a closed one (both ends, the same pose)
the upper end is read as the lower."""

from __future__ import annotations

import math

import numpy as np

from cdpm.maps.regions import grid_wrap

__all__ = [
    "axis_wrap",
    "distinct_poses",
    "margin_slice",
    "near_slice",
    "slice_index",
    "slice_key",
    "slice_picks",
]


def slice_index(ds, third: str, values: np.ndarray) -> np.ndarray:
    """The index of the map value of ``third`` nearest each of ``values``;
    along an axis that wraps, angles compare modulo 2 pi, and on a full
    turn with both ends (closed) the two ends' pose is its lower end's
    index (:func:`slice_key`)."""
    grid = np.asarray(ds[third].values, dtype=float)
    diff = np.asarray(values, dtype=float)[:, None] - grid[None, :]
    if axis_wrap(ds, third) is not None:
        diff = np.remainder(diff + math.pi, 2.0 * math.pi) - math.pi
    return slice_key(ds, third, np.argmin(np.abs(diff), axis=1))


def axis_wrap(ds, axis: str) -> str | None:
    """How the grid axis ``axis`` wraps: ``"closed"``, ``"open"`` or None
    (:func:`cdpm.maps.regions.grid_wrap` of its values and unit)."""

    values = np.asarray(ds[axis].values, dtype=float)
    return grid_wrap(values, ds[axis].attrs.get("units", ""))


def slice_key(ds, third: str, index):
    """Slice indices of ``third``, the upper end of a closed axis (the same
    pose as its lower end) read as the lower end."""
    if axis_wrap(ds, third) != "closed":
        return index
    values = np.asarray(ds[third].values, dtype=float)
    return np.where(np.asarray(index) == np.argmax(values), np.argmin(values), index)


def distinct_poses(ds, third: str) -> np.ndarray:
    """Indices of the values of ``third`` in ascending order, one per pose:
    a closed axis's upper end (its lower end's pose) left out."""
    values = np.asarray(ds[third].values, dtype=float)
    order = np.argsort(values, kind="stable")
    return order[:-1] if axis_wrap(ds, third) == "closed" else order


def slice_picks(ds, third: str, max_slices: int, path) -> np.ndarray:
    """Indices of the values of ``third`` drawn as slices: at most
    ``max_slices`` of its distinct poses, evenly spread (round the turn on
    an angle axis that wraps, whose upper end, on a closed axis, is the
    lower end's pose and left out; else from end to end), each of the
    slices of a path's start and goal (when ``path`` gives ``third``) in
    place of the spread's nearest (both drawn, whatever ``max_slices``)."""
    order = distinct_poses(ds, third)
    n, ring = order.size, axis_wrap(ds, third) is not None
    k = min(int(max_slices), n)
    spread = np.linspace(0, n if ring else n - 1, k, endpoint=not ring).round().astype(int) % n
    picks = [int(p) for p in dict.fromkeys(spread.tolist())]
    if path is not None and third in path:
        rank = np.empty(ds.sizes[third], dtype=int)
        rank[order] = np.arange(n)
        ends = dict.fromkeys(int(rank[i]) for i in slice_index(ds, third, path[third][[0, -1]]))
        free = [p for p in picks if p not in ends]
        for end in (e for e in ends if e not in picks):
            apart = np.abs(np.array(free) - end)
            if ring:
                apart = np.minimum(apart, n - apart)
            if free:  # the spread's slice nearest the end makes way for it
                free.pop(int(np.argmin(apart)))
        picks = [*free, *ends]
    return np.sort(order[picks])


def margin_slice(ds, third: str | None, slices: list[dict], path) -> int:
    """The slice the margin panel shows: the path's start's, when the path
    gives the third axis (its goal's, when the start's is not drawn), else
    the middle one."""
    if third is not None and path is not None and third in path:
        at = slice_index(ds, third, path[third][[0, -1]])
        keys = [int(slice_key(ds, third, s[third])) for s in slices]
        for end in at:
            if int(end) in keys:
                return keys.index(int(end))
    return len(slices) // 2


def near_slice(ds, third: str, values: np.ndarray, slices: list[dict], k: int) -> np.ndarray:
    """Which path poses lie in slice ``k`` (their nearest value of
    ``third`` is the slice's); the others are drawn dashed there."""
    return slice_index(ds, third, values) == slice_key(ds, third, slices[k][third])
