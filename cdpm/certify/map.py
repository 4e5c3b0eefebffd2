"""Certified maps: cells of a grid subdivided until each piece is proven
POC YES or NO on the whole piece, or reaches a least size
(:func:`certify_map`), and certified regions: face-adjacent YES boxes.

Each cell of the initial grid (``axes`` maps coordinates to cell edges; the
other coordinates stay at the base pose, as in maps) goes to
:func:`cdpm.certify.box.certify_boxes`. A cell left undecided is bisected
across its widest side (measured in units of its axis' initial cell
width), down to ``min_fraction`` of the initial cell width; what is still
undecided then stays MARGINAL. A robot outside the certified case (under
load, damped, a pinned cable) is MARGINAL everywhere at once, with the
reason.

The cells are certified in chunks of consecutive cells (C order over the
axes' cells), as maps compute poses: in this process, in local worker
processes or on a Dask cluster, and with ``store=`` written chunk by chunk
into a zarr store that a stopped run resumes
(:mod:`cdpm.certify.store`). A cell's boxes do not depend on the other
cells of its chunk, so the map is the same whatever the chunks and
wherever they ran.

Certified YES boxes that share a face (a closed face of positive area;
an axis spanning a full turn [-pi, pi] wraps) form certified regions:
every pose of a region is POC, and the region is connected, so the seed
paper's Lemma 1 applies to it.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from cdpm.certify.box import (
    BoxCertificate,
    CertifiedBoxes,
    _checked_box,
    certified_case,
    concatenate_boxes,
)
from cdpm.certify.subdivide import certify_cells
from cdpm.errors import InputError, is_integer
from cdpm.verdicts import MARGINAL, NO, YES

__all__ = [
    "CertifiedMap",
    "certify_map",
    "open_certified",
    "face_pairs",
    "map_of_boxes",
    "default_chunk_size",
    "CellPlan",
    "CellJob",
    "CellRunInfo",
    "chunk_arrays",
    "boxes_of",
]

#: default least box width, as a fraction of its axis' initial cell width
MIN_FRACTION = 1.0 / 16
#: the least ``min_fraction`` accepted: 2^-12 of a cell (12 bisections per
#: axis). Along a NO curve the boxes double with every bisection, so a
#: smaller one can run for hours and fill the memory
MIN_FRACTION_FLOOR = 2.0**-12


@dataclass(frozen=True)
class CertifiedMap:
    """Boxes of poses, each with a proven verdict or undecided.

    Attributes:
        coordinates: the mapped coordinates, in the axes' order (d of them).
        base: natural coordinates (nv,) of the coordinates not mapped.
        lower, upper: each box's corners over the mapped coordinates (K, d).
        verdict: YES, NO or MARGINAL per box (K,) int8 (cdpm's codes).
        margin_lower: YES boxes: a lower bound of r_T on the box; else NaN (K,).
        wraps: per mapped coordinate, whether its axis spans a full turn
            [-pi, pi] (its two ends are one face).
        boxes: the boxes over all natural coordinates with their proofs
            (:class:`~cdpm.certify.box.CertifiedBoxes`, K of them).
        cell: the initial cell each box was cut from (K,), cells numbered
            in C order over the axes' cells.
        edges: the axes' cell edges, one array per mapped coordinate.
        min_fraction: the least box width, as a fraction of its axis'
            initial cell width.
        units: each mapped coordinate's unit, ``"rad"`` or ``"m"`` (d,).
        provenance: where the map comes from: ``spec`` (path), ``spec_sha256``,
            ``cdpm_version``, ``settings`` (what a resumed store must
            match), ``created`` (UTC, ISO 8601) and, read from a store,
            ``store`` (its path).
    """

    coordinates: tuple[str, ...]
    base: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    verdict: np.ndarray
    margin_lower: np.ndarray
    wraps: tuple[bool, ...]
    boxes: CertifiedBoxes
    cell: np.ndarray
    edges: tuple[np.ndarray, ...]
    min_fraction: float
    units: tuple[str, ...] = ()
    provenance: Mapping[str, Any] = field(default_factory=dict, compare=False)

    @property
    def certificates(self) -> tuple[BoxCertificate, ...]:
        """Each box's :class:`~cdpm.certify.box.BoxCertificate` (built on demand)."""
        return tuple(self.boxes.certificate(k) for k in range(len(self.boxes)))

    @property
    def volumes(self) -> np.ndarray:
        """Each box's volume over the mapped coordinates (K,)."""
        return np.prod(self.upper - self.lower, axis=1)

    def fractions(self) -> dict[str, float]:
        """The fraction of the mapped volume proven YES, proven NO and
        undecided (keys ``yes``, ``no``, ``undecided``)."""
        v = self.volumes
        total = float(v.sum())
        return {
            name: float(v[self.verdict == code].sum() / total) if total > 0 else 0.0
            for name, code in (("yes", YES), ("no", NO), ("undecided", MARGINAL))
        }

    def regions(self) -> np.ndarray:
        """Certified regions: a label per box (K,), 1, 2, ... by decreasing
        volume for YES boxes joined through shared faces, 0 for the others."""
        # scipy: loaded on first use
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        yes = np.flatnonzero(self.verdict == YES)
        labels = np.zeros(self.verdict.shape[0], dtype=np.int64)
        if yes.size == 0:
            return labels
        a, b = face_pairs(self.lower[yes], self.upper[yes], self.wraps)[:2]
        graph = coo_matrix((np.ones(a.size), (a, b)), shape=(yes.size, yes.size))
        _, comp = connected_components(graph, directed=False)
        volume = np.bincount(comp, weights=self.volumes[yes])
        order = np.argsort(-volume, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(1, order.size + 1)
        labels[yes] = rank[comp]
        return labels

    def verify(self, robot: Any) -> bool:
        """Re-check every YES and NO box's certificate from the model (one
        vectorised pass, :meth:`~cdpm.certify.box.CertifiedBoxes.verify`);
        :meth:`unverified` names the boxes that fail."""
        return self.unverified(robot).size == 0

    def unverified(self, robot: Any) -> np.ndarray:
        """The YES and NO boxes whose proof does not re-check from the model
        (indices into the boxes, (F,)); every decided box when the map's
        verdicts and its proofs' disagree."""
        decided = np.isin(self.verdict, (YES, NO))
        if not np.array_equal(self.boxes.verdict, self.verdict):
            return np.flatnonzero(decided | (self.boxes.verdict != self.verdict))
        return np.flatnonzero(decided & ~self.boxes.verify(robot))

    def __str__(self) -> str:
        f = self.fractions()
        n_regions = int(self.regions().max(initial=0))
        return (
            f"certified map over {', '.join(self.coordinates)}: {self.verdict.size} boxes; "
            f"proven YES {100 * f['yes']:.1f}%, proven NO {100 * f['no']:.1f}%, "
            f"undecided {100 * f['undecided']:.1f}% of the volume; "
            f"{n_regions} certified region(s)"
        )


def face_pairs(lower: np.ndarray, upper: np.ndarray, wraps: Sequence[bool]):
    """Pairs of boxes sharing a face of positive area, and the face.

    Two boxes share a face along axis a when the upper side of one equals
    the lower side of the other there (or, on an axis that wraps, one ends
    at +pi and the other starts at -pi), and their sides overlap with
    positive length along every other axis. Per axis, the boxes whose upper
    side and those whose lower side lie on one value are paired (each
    value's two groups at once, vectorised).

    Args:
        lower, upper: the boxes' corners (K, d).
        wraps: per axis, whether it spans a full turn [-pi, pi].

    Returns:
        (a, b, axis, face_lo, face_hi): box ids a and b (E,) with a's upper
        side on the face, the face's axis (E,), and the face's corners (E, d)
        in a's coordinates (equal along ``axis``); in b's coordinates the
        face is the same but at b's lower side along ``axis``.
    """
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    d = lo.shape[1]
    pairs_a, pairs_b, pairs_axis = [], [], []
    for axis in range(d):
        top, bottom = hi[:, axis].copy(), lo[:, axis].copy()
        if wraps[axis]:  # the two ends of a full turn are one value
            top[np.isclose(top, np.pi, rtol=0, atol=1e-12)] = -np.pi
            bottom[np.isclose(bottom, -np.pi, rtol=0, atol=1e-12)] = -np.pi
        i, j = _equal_pairs(top, bottom)
        overlap = np.ones(i.size, dtype=bool)
        for k in range(d):
            if k != axis:
                overlap &= np.minimum(hi[i, k], hi[j, k]) > np.maximum(lo[i, k], lo[j, k])
        pairs_a.append(i[overlap])
        pairs_b.append(j[overlap])
        pairs_axis.append(np.full(int(overlap.sum()), axis))
    a = np.concatenate(pairs_a).astype(np.intp) if d else np.zeros(0, dtype=np.intp)
    b = np.concatenate(pairs_b).astype(np.intp) if d else np.zeros(0, dtype=np.intp)
    axis = np.concatenate(pairs_axis).astype(np.intp) if d else np.zeros(0, dtype=np.intp)
    face_lo = np.maximum(lo[a], lo[b])
    face_hi = np.minimum(hi[a], hi[b])
    rows = np.arange(a.size)
    face_lo[rows, axis] = hi[a, axis]
    face_hi[rows, axis] = hi[a, axis]
    return a, b, axis, face_lo, face_hi


def _equal_pairs(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (i, j) with x[i] == y[j] (each value's groups crossed)."""
    order_x = np.argsort(x, kind="stable")
    order_y = np.argsort(y, kind="stable")
    xs, ys = x[order_x], y[order_y]
    values, start_x, count_x = np.unique(xs, return_index=True, return_counts=True)
    first_y = np.searchsorted(ys, values, side="left")
    count_y = np.searchsorted(ys, values, side="right") - first_y
    keep = count_y > 0
    start_x, count_x, first_y, count_y = start_x[keep], count_x[keep], first_y[keep], count_y[keep]
    n = count_x * count_y  # pairs per value
    total = int(n.sum())
    if total == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    group = np.repeat(np.arange(n.size), n)
    within = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    i = order_x[start_x[group] + within // count_y[group]]
    j = order_y[first_y[group] + within % count_y[group]]
    return i, j


def _axes(robot: Any, axes: Mapping[str, Any]) -> tuple[list[int], list[np.ndarray]]:
    names = list(robot.coordinate_names)
    if not isinstance(axes, Mapping) or not axes:
        raise InputError(
            "axes must map coordinate names to increasing cell edges, e.g. "
            "{'q1': np.linspace(-np.pi, np.pi, 62)}"
        )
    index, edges = [], []
    for name, values in axes.items():
        if name not in names:
            raise InputError(f"unknown coordinate {name!r}; the robot has {', '.join(names)}")
        try:
            e = np.array(values, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"the edges of {name} must be numbers") from None
        if e.size < 2 or not np.all(np.isfinite(e)) or not np.all(np.diff(e) > 0):
            raise InputError(f"the edges of {name} must be at least two finite, increasing numbers")
        index.append(names.index(name))
        edges.append(e)
    if len(set(index)) != len(index):
        raise InputError("a coordinate is given twice in axes")
    return index, edges


#: most cells in one chunk by default: a chunk's boxes are certified in
#: vectorised passes (:func:`~cdpm.certify.subdivide.certify_cells`), which
#: gain little beyond a few hundred cells, while smaller chunks spread a
#: map evenly over worker processes and lose less to an interrupt
MAX_DEFAULT_CHUNK_CELLS = 256

#: fewest cells in one chunk by default (smaller chunks spend their time on
#: the passes' fixed costs)
MIN_DEFAULT_CHUNK_CELLS = 32

#: most cells one certified map may have
MAX_MAP_CELLS = 10**8


def default_chunk_size(n_cells: int) -> int:
    """Cells per chunk by default: a thirty-second of the map, within
    MIN_DEFAULT_CHUNK_CELLS and MAX_DEFAULT_CHUNK_CELLS (a function of the
    map alone, so that the same command resumes the same store whatever
    the workers)."""
    share = -(-int(n_cells) // 32)
    return int(min(MAX_DEFAULT_CHUNK_CELLS, max(MIN_DEFAULT_CHUNK_CELLS, share)))


@dataclass(frozen=True)
class CellPlan:
    """The cells of a certified map and their chunks.

    Attributes:
        edges: each mapped axis' cell edges (d arrays; n_i + 1 edges make
            n_i cells).
        cells_per_chunk: consecutive cells (C order over the axes' cells)
            per chunk; the last chunk may have fewer.
    """

    edges: tuple[np.ndarray, ...]
    cells_per_chunk: int

    @property
    def shape(self) -> tuple[int, ...]:
        """Cells along each axis."""
        return tuple(e.size - 1 for e in self.edges)

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.shape))

    #: what the chunk runner counts (its progress is in cells here)
    n_poses = n_cells

    @property
    def n_chunks(self) -> int:
        return -(-self.n_cells // self.cells_per_chunk)

    def cells(self, k: int) -> np.ndarray:
        """The cell numbers of chunk ``k`` (C order over the axes' cells)."""
        start = k * self.cells_per_chunk
        return np.arange(start, min(start + self.cells_per_chunk, self.n_cells), dtype=np.int64)

    def chunk_size(self, k: int) -> int:
        """Cells in chunk ``k``."""
        return int(self.cells(k).size)

    def bounds(self, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cells' corners over the mapped coordinates, (n, d) each."""
        index = np.unravel_index(cells, self.shape)
        lower = np.stack([e[i] for e, i in zip(self.edges, index, strict=True)], axis=1)
        upper = np.stack([e[i + 1] for e, i in zip(self.edges, index, strict=True)], axis=1)
        return lower, upper

    def natural(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Chunk ``k``'s input: (its cell numbers (n,), their lower and upper
        corners over the mapped coordinates (n, d) each)."""
        cells = self.cells(k)
        return (cells, *self.bounds(cells))


@dataclass(frozen=True)
class CellJob:
    """What every chunk of a certified map runs (:meth:`evaluate`).

    Attributes:
        base: the pose of the coordinates not mapped, natural coordinates (nv,).
        index: the mapped coordinates' positions in ``base`` (d,).
        widths: each axis' initial cell width (d,) [rad or m].
        min_fraction: least box width, as a fraction of its axis' initial
            cell width.
        reach: the :class:`~cdpm.dynamics.reach.ReachSettings` of the
            margin bounds.
        tension: the equilibrium of the certified case, f* = 0 (the chunk
            runner loads no compiled kernels for it).
    """

    base: np.ndarray
    index: tuple[int, ...]
    widths: np.ndarray
    min_fraction: float
    reach: Any
    tension: str = "zero"

    def evaluate(self, robot: Any, chunk: tuple) -> dict[str, np.ndarray]:
        """Certify one chunk's cells: :func:`chunk_arrays` of their boxes."""
        cells, lower, upper = chunk
        boxes, row = certify_cells(
            robot,
            self.base,
            list(self.index),
            lower,
            upper,
            self.widths,
            self.min_fraction,
            self.reach,
        )
        return chunk_arrays(boxes, np.asarray(cells)[row])


#: the arrays of one chunk's boxes (:func:`chunk_arrays`), in the order of
#: :class:`~cdpm.certify.box.CertifiedBoxes`' fields, and their cells
CHUNK_ARRAYS = (
    "lower",
    "upper",
    "verdict",
    "reason",
    "margin_lower",
    "horizon",
    "tension_budget",
    "margin_unit",
    "patch_start",
    "faces",
    "patches",
    "columns",
    "separator",
    "cell",
)


def chunk_arrays(boxes: CertifiedBoxes, cell: np.ndarray) -> dict[str, np.ndarray]:
    """A chunk's boxes as plain arrays {name: array} (picklable, storable):
    every field of ``boxes`` (the scalars as 0-d arrays, the reasons as
    str), and each box's cell number (K,)."""
    data = {
        "lower": np.asarray(boxes.lower, dtype=float),
        "upper": np.asarray(boxes.upper, dtype=float),
        "verdict": np.asarray(boxes.verdict, dtype=np.int8),
        "reason": np.asarray(boxes.reason).astype(str),
        "margin_lower": np.asarray(boxes.margin_lower, dtype=float),
        "horizon": np.array(float(boxes.horizon)),
        "tension_budget": np.array(float(boxes.tension_budget)),
        "margin_unit": np.array(str(boxes.margin_unit)),
        "patch_start": np.asarray(boxes.patch_start, dtype=np.int64),
        "faces": np.asarray(boxes.faces, dtype=np.int64),
        "patches": np.asarray(boxes.patches, dtype=float),
        "columns": np.asarray(boxes.columns, dtype=np.int64),
        "separator": np.asarray(boxes.separator, dtype=float),
        "cell": np.asarray(cell, dtype=np.int64),
    }
    return data


def boxes_of(data: Mapping[str, np.ndarray]) -> CertifiedBoxes:
    """The :class:`~cdpm.certify.box.CertifiedBoxes` of :func:`chunk_arrays`."""
    return CertifiedBoxes(
        data["lower"],
        data["upper"],
        data["verdict"],
        data["reason"],
        data["margin_lower"],
        float(data["horizon"]),
        float(data["tension_budget"]),
        str(data["margin_unit"]),
        data["patch_start"],
        data["faces"],
        data["patches"],
        data["columns"],
        data["separator"],
    )


class _MemorySink:
    """Chunks kept in memory, {index: arrays}."""

    path = None
    writer = None

    def __init__(self):
        self.parts: dict[int, dict] = {}

    def done(self) -> set[int]:
        return set()

    def write(self, index: int, data: dict) -> None:
        self.parts[index] = data

    def read(self, index: int) -> dict:
        return self.parts[index]

    def close(self) -> None:
        """Nothing to wait for."""


# --------------------------------------------------------------------------
# what a run tells its user


@dataclass(frozen=True)
class CellRunInfo:
    """What a certified map's run computes and where, in words (:meth:`lines`).

    Attributes:
        n_chunks, n_cells: chunks and cells of the whole map.
        done_chunks, done_cells: those already in the store (resumed).
        store: the store's path, or None for a map in memory.
        executor: ``"none"`` (nothing to compute), ``"this process"``,
            ``"local"`` (worker processes and this one) or ``"dask"``.
        processes: local processes certifying chunks, this one included.
        scheduler, dask_workers: the Dask scheduler's address and workers.
    """

    n_chunks: int
    n_cells: int
    done_chunks: int = 0
    done_cells: int = 0
    store: str | None = None
    executor: str = "none"
    processes: int = 0
    scheduler: str | None = None
    dask_workers: int = 0

    @classmethod
    def of(cls, info: Any) -> CellRunInfo:
        """From the chunk runner's :class:`~cdpm.maps.runtime.MapRunInfo`
        (whose poses are cells here)."""
        return cls(
            info.n_chunks,
            info.n_poses,
            info.done_chunks,
            info.done_poses,
            info.store,
            info.executor,
            info.processes,
            info.scheduler,
            info.dask_workers,
        )

    @property
    def todo_chunks(self) -> int:
        return self.n_chunks - self.done_chunks

    def lines(self) -> list[str]:
        """What is resumed and where the chunks run, in words."""
        if self.todo_chunks == 0:
            return [
                f"the store {self.store} already holds the whole certified map "
                f"({self.n_chunks} chunk(s), {self.n_cells} cells); nothing to compute"
            ]
        lines = []
        if self.done_chunks:
            lines.append(
                f"resuming {self.store}: {self.done_chunks} of {self.n_chunks} chunks done "
                f"({self.done_cells} of {self.n_cells} cells)"
            )
        todo = self.n_cells - self.done_cells
        what = f"certifying {todo} cells in {self.todo_chunks} chunk(s)"
        if self.executor == "dask":
            where = f"on the Dask scheduler {self.scheduler} ({self.dask_workers} worker(s))"
        elif self.executor == "local":
            where = f"in {self.processes} local processes (this one and {self.processes - 1} more)"
        else:
            where = "in this process"
        return lines + [f"{what} {where}"]


# --------------------------------------------------------------------------
# the map


def certify_map(
    robot: Any,
    axes: Mapping[str, Any],
    base: Any = None,
    *,
    min_fraction: float = MIN_FRACTION,
    horizon: Any = None,
    tension_budget: Any = None,
    store: str | os.PathLike | None = None,
    overwrite: bool = False,
    workers: int | None = None,
    scheduler: Any = None,
    progress: bool | Callable[[int, int, int], None] = False,
    chunk_size: int | None = None,
    announce: Callable[[CellRunInfo], None] | None = None,
) -> CertifiedMap:
    """Certify every cell of a grid, subdividing undecided ones (module
    docstring).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` or a spec path.
        axes: coordinate name -> increasing cell edges [rad or m] (n + 1
            edges make n cells), within the joint limits.
        base: the pose of the coordinates not mapped (a pose name or
            natural coordinates; default the spec's first named pose).
        min_fraction: least box width, as a fraction of its axis' initial
            cell width (default 1/16: four bisections per axis).
        horizon, tension_budget: of the reach-margin bound, as
            :func:`~cdpm.certify.box.certify_box`.
        store: path of a zarr store (a directory, ``*.zarr`` by convention)
            to write chunk by chunk; an existing store made with the same
            settings is resumed (only chunks not yet done are certified),
            one made with others is refused. None keeps the map in memory.
        overwrite: replace an existing ``store`` instead of resuming it.
        workers: local processes certifying chunks, this one included;
            default one per CPU this process may use, at most 16 (and at
            most one per chunk); 1 runs in this process only. As for
            :func:`cdpm.workspace_map`, a script calling this outside
            ``if __name__ == "__main__":`` runs in this process only, with a
            warning saying so.
        scheduler: address ``"tcp://host:port"`` of a Dask distributed
            scheduler (or a ``distributed.Client``) whose workers certify
            the chunks (give no ``workers`` with it).
        progress: True prints what runs where and a progress bar (cells)
            on stderr; a callable is called as
            ``progress(done_cells, total_cells, chunk_index)``.
        chunk_size: cells per chunk (default :func:`default_chunk_size`:
            a thirty-second of the map, within 32 and 256). The map does not
            depend on it; a resumed store keeps its own.
        announce: called once before the chunks run with a
            :class:`CellRunInfo` (chunks resumed, to compute, and where).

    Returns:
        :class:`CertifiedMap`, its boxes in the order of their cells (and
        within a cell in the order the subdivision finished them), the same
        whatever the workers and chunks.

    Raises:
        InputError: bad axes or base, cells beyond the joint limits, a joint
            type certified boxes do not support, ``workers`` with
            ``scheduler``, or a ``store`` named like an image or other file.
        StoreSettingsError: ``store`` holds a certified map made with other
            settings (an InputError naming each difference), or a map of
            another kind.
    """
    # loaded on first use: the model, the reach settings, the run machinery
    from cdpm.dynamics.reach import reach_settings
    from cdpm.maps import runtime
    from cdpm.model.coordinates import coordinate_units
    from cdpm.model.robot import load_robot

    _refuse_in_worker_bootstrap()
    if scheduler is not None and workers is not None:
        raise InputError(
            f"workers={workers!r} counts local processes, and with scheduler= the Dask "
            "cluster's workers certify the chunks: leave out workers, or leave out scheduler "
            "to run locally"
        )
    if isinstance(scheduler, str):
        runtime.check_scheduler_address(scheduler)
    if isinstance(progress, np.bool_) or progress is None:
        progress = bool(progress)
    if not (isinstance(progress, bool) or callable(progress)):
        raise InputError(
            "progress must be True (a progress bar on stderr), False or a callable "
            f"progress(done_cells, total_cells, chunk_index), got {progress!r}"
        )
    if announce is not None and not callable(announce):
        raise InputError(f"announce must be a callable announce(info) or None, got {announce!r}")
    if store is not None and runtime.store_path_problem(store):
        name = os.fspath(store)
        raise InputError(
            f"store {name!r} is named like {runtime.store_path_problem(store)}, but a certified "
            f"map store is a zarr directory: name it e.g. {os.path.splitext(name)[0]}.zarr"
        )
    with runtime.interrupts_held():  # set-up: the model and its imports
        if not hasattr(robot, "spec"):
            robot = load_robot(robot)
        index, edges = _axes(robot, axes)
        if not (
            isinstance(min_fraction, (int, float, np.floating))
            and not isinstance(min_fraction, bool)
            and MIN_FRACTION_FLOOR <= min_fraction <= 1
        ):
            raise InputError(
                f"min_fraction must be a number in [2^-12 = {MIN_FRACTION_FLOOR:.3g}, 1]; got "
                f"{min_fraction!r} (boxes double along a NO curve with every bisection: a "
                "smaller least box may never finish)"
            )
        min_fraction = float(min_fraction)
        if base is None:  # the spec's first named pose, else the neutral configuration
            q = next(iter(robot.poses.values())) if robot.poses else robot.neutral()
        else:
            q = robot.as_q(base)
        natural = np.asarray(robot.to_natural(q), dtype=float)
        n_cells = int(np.prod([e.size - 1 for e in edges]))
        if n_cells > MAX_MAP_CELLS:
            raise InputError(
                f"a certified map of {n_cells:,} cells is more than the {MAX_MAP_CELLS:,} one "
                "map may have; use fewer cells per axis"
            )
        # the whole grid within the joint limits, and joints certified boxes support
        whole_lo, whole_hi = natural.copy(), natural.copy()
        whole_lo[index] = [e[0] for e in edges]
        whole_hi[index] = [e[-1] for e in edges]
        _checked_box(robot, whole_lo, whole_hi)
        _supported_joints(robot, whole_lo)
        if chunk_size is None:
            chunk_size = default_chunk_size(n_cells)
        if not is_integer(chunk_size) or chunk_size < 1:
            raise InputError(f"chunk_size must be a positive integer, got {chunk_size!r}")
        if workers is None:
            workers = runtime.default_workers()
        if not is_integer(workers) or workers < 1:
            raise InputError(f"workers must be a positive integer, got {workers!r}")
        workers = int(workers)
        # the reach settings once for every box (the default horizon may need
        # a linearisation of the robot)
        reach = reach_settings(robot, horizon, tension_budget)
        structural = certified_case(robot)[1]
        source = runtime.RobotSource.from_robot(robot)
        plan = CellPlan(tuple(edges), int(chunk_size))
        widths = np.array([float(np.min(np.diff(e))) for e in edges])
        job = CellJob(natural, tuple(index), widths, min_fraction, reach)
        names = tuple(robot.coordinate_names[i] for i in index)
        all_units = coordinate_units(robot.model)
        units = tuple(all_units[i] for i in index)
        settings = _settings(robot, source, names, edges, natural, min_fraction, reach, plan)
        if structural:
            # every box MARGINAL at once: nothing worth other processes
            workers, scheduler = 1, None
        if scheduler is None and workers > 1 and (why := runtime.unimportable_main()) is not None:
            warnings.warn(f"certify_map runs with workers=1, not {workers}: {why}", stacklevel=2)
            workers = 1
    owner = nullcontext() if store is None else runtime.store_lock(store)
    with owner:
        sink = None
        printer = None
        try:
            with runtime.interrupts_held():
                if store is None:
                    sink = _MemorySink()
                else:
                    # zarr: loaded on first use
                    from cdpm.certify.store import CertifiedStore

                    sink = CertifiedStore(store, settings, overwrite)
            done = sink.done()
            todo = [k for k in range(plan.n_chunks) if k not in done]
            if progress is True:
                announce = announce or _print_to_stderr
                printer = (
                    runtime.ProgressPrinter(
                        sum(plan.chunk_size(k) for k in todo),
                        label="certify",
                        unit="cells",
                        decimals=1,
                    )
                    if todo
                    else None
                )
                progress = printer
            elif progress is False:
                progress = None
            if scheduler is None and workers > 1 and len(todo) > 1:
                runtime.prestart_workers(kernels=False)

            def announced(info) -> None:
                if announce is not None:
                    announce(CellRunInfo.of(info))

            runtime.run_chunks(
                robot, plan, job, todo, sink, workers, scheduler, progress, announced, source
            )
            provenance = _provenance(robot, settings)
            if store is None:
                parts = [sink.read(k) for k in range(plan.n_chunks)]
                return replace(_assemble(parts, job, names, edges, units), provenance=provenance)
            if not sink.complete:
                parts = [sink.read(k) for k in range(plan.n_chunks)]
                with runtime.interrupts_held():
                    sink.finish(_assemble(parts, job, names, edges, units), provenance)
            # the map as stored: with its provenance and the store's path
            return open_certified(sink.path)
        except KeyboardInterrupt as exc:
            if printer is not None:
                printer.stopped()
            if store is not None and sink is not None:
                exc.certified_store = str(sink.path)
            raise
        finally:
            if sink is not None:
                sink.close()


def _print_to_stderr(info: CellRunInfo) -> None:
    for line in info.lines():
        print(line, file=sys.stderr)


def _refuse_in_worker_bootstrap() -> None:
    """Refuse to run while a worker process imports the main script (as
    :func:`cdpm.workspace_map` does: local workers import the script)."""
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise InputError(
            "certify_map was called while a worker process was importing the main script: "
            'with workers > 1, put the script\'s call under `if __name__ == "__main__":` '
            "(local workers import the script), or pass workers=1"
        )


def _supported_joints(robot: Any, natural: np.ndarray) -> None:
    """Raise the InputError of a joint type certified boxes do not
    support, before any chunk runs (the enclosures at one pose)."""
    from cdpm.certify.kinematics import box_kinematics

    box_kinematics(robot, natural[None], natural[None])


def _settings(robot, source, names, edges, natural, min_fraction, reach, plan) -> dict:
    """What a resumed store must match (JSON-able; the axes as maps record
    them: size, range and a hash of their values)."""
    import hashlib

    from cdpm._version import __version__

    def digest(values: np.ndarray) -> str:
        data = np.ascontiguousarray(values, dtype="<f8").tobytes()
        return hashlib.sha256(data).hexdigest()[:16]

    settings = {
        "kind": "certified_map",
        "cdpm_version": __version__,
        "spec_sha256": robot.spec.sha256,
        "coordinates": list(robot.coordinate_names),
        "axes": {
            n: {"size": int(e.size), "min": float(e[0]), "max": float(e[-1]), "sha256": digest(e)}
            for n, e in zip(names, edges, strict=True)
        },
        "base": [float(x) for x in natural],
        "min_fraction": float(min_fraction),
        "reach_horizon": float(reach.horizon),
        "tension_budget": float(reach.tension_budget),
        "chunk_size": int(plan.cells_per_chunk),
    }
    if source.overrides:
        settings["overrides"] = dict(source.overrides)
    return json.loads(json.dumps(settings))


def _provenance(robot: Any, settings: dict) -> dict:
    """Where a map comes from: spec path and hash, cdpm version, the
    settings, and the date it was made (UTC, ISO 8601)."""
    import datetime

    return {
        "spec": str(robot.spec.path),
        "spec_sha256": settings["spec_sha256"],
        "cdpm_version": settings["cdpm_version"],
        "settings": settings,
        "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }


def _assemble(
    parts: list[dict],
    job: CellJob,
    names: tuple[str, ...],
    edges: list[np.ndarray],
    units: tuple[str, ...],
) -> CertifiedMap:
    """The map of its chunks' arrays (:func:`chunk_arrays`), in chunk order."""
    boxes = concatenate_boxes([boxes_of(p) for p in parts])
    boxes = replace(boxes, reason=np.asarray(boxes.reason).astype(str))
    cell = np.concatenate([p["cell"] for p in parts]).astype(np.int64)
    return map_of_boxes(boxes, cell, names, job.base, job.index, edges, job.min_fraction, units)


def map_of_boxes(
    boxes: CertifiedBoxes,
    cell: np.ndarray,
    names: tuple[str, ...],
    base: np.ndarray,
    index: tuple[int, ...],
    edges: Any,
    min_fraction: float,
    units: tuple[str, ...] = (),
    provenance: Mapping[str, Any] | None = None,
) -> CertifiedMap:
    """The :class:`CertifiedMap` of its boxes: the mapped coordinates
    ``names`` at positions ``index`` of the natural coordinates, the axes'
    cell ``edges`` (an axis spanning [-pi, pi] wraps)."""
    edges = tuple(np.asarray(e, dtype=float) for e in edges)
    index = list(index)
    return CertifiedMap(
        tuple(names),
        np.asarray(base, dtype=float),
        boxes.lower[:, index],
        boxes.upper[:, index],
        boxes.verdict.copy(),
        boxes.margin_lower.copy(),
        tuple(_wraps(e) for e in edges),
        boxes,
        np.asarray(cell, dtype=np.int64),
        edges,
        float(min_fraction),
        tuple(units),
        dict(provenance or {}),
    )


def _wraps(edges: np.ndarray) -> bool:
    """Whether an axis' edges span a full turn [-pi, pi]."""
    return bool(
        np.isclose(edges[0], -np.pi, atol=1e-12) and np.isclose(edges[-1], np.pi, atol=1e-12)
    )


def open_certified(path: str | os.PathLike) -> CertifiedMap:
    """Read a certified map store written by :func:`certify_map` (``store=``)
    or ``cdpm certify ... --out STORE``: the same map, boxes, proofs and
    provenance (its ``provenance["store"]`` is the store's path).

    Raises:
        InputError: ``path`` is missing, not a certified map store (a
            sampled map from ``cdpm map`` is refused, naming
            :func:`cdpm.open_map`), unfinished (the message says how to
            finish it) or damaged.
    """
    # zarr: loaded on first use
    from cdpm.certify.store import read_certified

    arrays, attrs = read_certified(path)
    try:
        names = tuple(attrs["coordinates"])
        robot_names = list(attrs["robot_coordinates"])
        index = tuple(robot_names.index(n) for n in names)
        boxes = CertifiedBoxes(
            arrays["lower"],
            arrays["upper"],
            arrays["verdict"],
            arrays["reason"],
            arrays["margin_lower"],
            float(attrs["horizon"]),
            float(attrs["tension_budget"]),
            str(attrs["margin_unit"]),
            arrays["patch_start"],
            arrays["faces"],
            arrays["patches"],
            arrays["columns"],
            arrays["separator"],
        )
        edges = tuple(arrays[f"edges_{n}"] for n in names)
        settings = json.loads(attrs["cdpm_certified_settings"])
        provenance = {
            "spec": attrs["spec"],
            "spec_sha256": attrs["spec_sha256"],
            "cdpm_version": attrs["cdpm_version"],
            "settings": settings,
            "created": attrs["created"],
            "store": os.path.abspath(os.fspath(path)),
        }
        cmap = map_of_boxes(
            boxes,
            arrays["cell"],
            names,
            arrays["base"],
            index,
            edges,
            float(attrs["min_fraction"]),
            tuple(attrs.get("units", ())),
            provenance,
        )
    except (KeyError, ValueError, TypeError) as exc:
        raise InputError(
            f"certified map store {path} is damaged ({type(exc).__name__}: {exc}); make it "
            "again with --overwrite (overwrite=True)"
        ) from None
    if tuple(bool(w) for w in attrs.get("wraps", cmap.wraps)) != cmap.wraps:
        raise InputError(
            f"certified map store {path} is damaged (its wraps disagree with its edges)"
        )
    return cmap
