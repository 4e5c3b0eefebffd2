"""What map pictures draw over a verdict panel: the outlines and numbers of
the POC regions (``poc_region``) and a path of map poses.
"""

from __future__ import annotations

import json
from collections.abc import Mapping

import numpy as np

from cdpm.errors import InputError
from cdpm.plotting._common import halo
from cdpm.regions.paths import POCPath

#: most regions numbered on a panel (the largest ones)
MAX_NUMBERED_REGIONS = 15
#: smallest region numbered, as a fraction of the panel's poses (the
#: largest region on a panel is always numbered)
MIN_NUMBERED_FRACTION = 0.005
#: most pieces of one region numbered on a panel (a region across the seams
#: of two full turns shows as up to four)
MAX_NUMBERED_PIECES = 4
#: resolution of the nearest-sample raster behind the outlines of sampled maps
_SAMPLE_RASTER = 200
#: region outlines follow a region's outer boundary and its holes, but not
#: thin or small pieces of poses outside every region, so that a thin NO
#: line (the paper's arm's diagonal NO lines, met at isolated poses; the
#: folded arm's q2 = 0 row) reads as a red line, not as a row of black
#: rings: an edge is outlined only when the pose outside the region is in a
#: 2 x 2 block of such poses and in a face-connected piece of more than
#: SMALL_HOLE_POSES poses
SMALL_HOLE_POSES = 4

OUTLINE_COLOR = "black"
OUTLINE_WIDTH = 0.7
PATH_COLOR = "#1f3fd6"
#: steps of a path that may cross a NO set thinner than the map's resolution
#: (POCPath.suspect_steps): magenta, apart from the verdicts' and margins' colours
SUSPECT_COLOR = "#d000c8"


# ------------------------------------------------------------------ regions


def region_count(ds) -> int:
    """Number K of POC regions of the map (0 without ``poc_region``): the
    length of its ``regions`` attribute, else the largest region id."""
    if "poc_region" not in ds:
        return 0
    table = ds["poc_region"].attrs.get("regions")
    try:
        return len(json.loads(table)) if isinstance(table, str) else len(table)
    except (TypeError, ValueError):
        ids = np.asarray(ds["poc_region"].values)
        return int(ids.max()) if ids.size else 0


def _not_outlined(ids: np.ndarray, owners: np.ndarray | None = None) -> np.ndarray:
    """Cells outside every region whose edges are not outlined: those in
    a small piece (a face-connected piece of such cells holding at most
    :data:`SMALL_HOLE_POSES` poses; ``owners``: the pose of each cell, shape
    of ``ids``, None: each cell is a pose) and those in a piece with no 2 x 2
    block of such cells anywhere (a line one cell thin). A piece with a
    block is outlined all round, its thin parts too (the outline broke off
    where a wide area narrowed to one cell). Shape of ``ids``, bool."""
    # scipy: loaded on first use
    from scipy import ndimage

    outside = ids <= 0
    pieces, n = ndimage.label(outside)
    if n == 0:
        return outside
    if owners is None:
        poses = np.bincount(pieces.ravel(), minlength=n + 1)
    else:  # distinct poses per piece
        pairs = np.unique(np.column_stack([pieces.ravel(), np.ravel(owners)]), axis=0)
        poses = np.bincount(pairs[:, 0], minlength=n + 1)
    small = poses <= SMALL_HOLE_POSES
    small[0] = False  # label 0: the cells inside regions
    block = outside[:-1, :-1] & outside[1:, :-1] & outside[:-1, 1:] & outside[1:, 1:]
    in_block = np.zeros_like(outside)
    for di in (0, 1):
        for dj in (0, 1):
            in_block[di : di + block.shape[0], dj : dj + block.shape[1]] |= block
    thick = np.bincount(pieces[in_block].ravel(), minlength=n + 1) > 0
    return small[pieces] | (outside & ~thick[pieces])


def _outline_segments(
    ids: np.ndarray, x_edges: np.ndarray, y_edges: np.ndarray, owners: np.ndarray | None = None
) -> list:
    """Cell-edge segments between cells of different regions (one side in
    a region), for ids of shape (nx, ny), the first index along x; edges
    next to a thin or small piece outside the regions
    (:func:`_not_outlined`) are left out."""
    segments = []
    inside = ids > 0
    drawn = ~_not_outlined(ids, owners)  # cells whose edges may be outlined
    a, b = ids[:-1, :], ids[1:, :]  # neighbours along x: a vertical edge
    edge = (a != b) & (inside[:-1, :] | inside[1:, :]) & drawn[:-1, :] & drawn[1:, :]
    for i, j in zip(*np.nonzero(edge), strict=True):
        x = x_edges[i + 1]
        segments.append([(x, y_edges[j]), (x, y_edges[j + 1])])
    a, b = ids[:, :-1], ids[:, 1:]  # neighbours along y: a horizontal edge
    edge = (a != b) & (inside[:, :-1] | inside[:, 1:]) & drawn[:, :-1] & drawn[:, 1:]
    for i, j in zip(*np.nonzero(edge), strict=True):
        y = y_edges[j + 1]
        segments.append([(x_edges[i], y), (x_edges[i + 1], y)])
    return segments


def _label_cells(mask: np.ndarray, smallest: float) -> list[tuple[int, int]]:
    """Where a region's number reads best on each of its pieces on the
    panel (the connected pieces of ``mask``, 2-D bool; a region that wraps
    around a full turn shows as several): the cell deepest inside each
    piece of at least ``smallest`` cells, largest first (the largest piece
    always), at most MAX_NUMBERED_PIECES."""
    # scipy: loaded on first use
    from scipy import ndimage

    pieces, n = ndimage.label(mask)
    sizes = ndimage.sum_labels(mask, pieces, index=np.arange(1, n + 1))
    order = np.argsort(-sizes, kind="stable")
    chosen = [k for k in order if sizes[k] >= smallest] or list(order[:1])
    cells = []
    for k in chosen[:MAX_NUMBERED_PIECES]:
        piece = pieces == k + 1
        depth = ndimage.distance_transform_edt(np.pad(piece, 1))[1:-1, 1:-1]
        i, j = np.unravel_index(int(np.argmax(depth)), piece.shape)
        cells.append((int(i), int(j)))
    return cells


def _numbered(ids: np.ndarray) -> tuple[list[int], list[int]]:
    """(regions present in ``ids``, those to number): the largest ones on
    the panel, at most :data:`MAX_NUMBERED_REGIONS`, each with at least
    :data:`MIN_NUMBERED_FRACTION` of the poses (the largest one always)."""
    values, counts = np.unique(np.asarray(ids), return_counts=True)
    keep = values > 0
    values, counts = values[keep], counts[keep]
    by_size = np.argsort(-counts, kind="stable")
    large = [int(values[i]) for i in by_size if counts[i] >= MIN_NUMBERED_FRACTION * np.size(ids)]
    numbered = (large or [int(values[i]) for i in by_size[:1]])[:MAX_NUMBERED_REGIONS]
    return [int(k) for k in values], numbered


def _number(ax, x: float, y: float, k: int, fontsize: float = 9.0) -> None:
    ax.text(
        x,
        y,
        str(k),
        ha="center",
        va="center",
        fontsize=fontsize,
        fontweight="bold",
        color="black",
        path_effects=halo(3.0),
        zorder=6,
        gid="region number",
    )


def _outline(ax, ids: np.ndarray, x_edges, y_edges, owners: np.ndarray | None = None) -> None:
    # optional: cdpm[viz/maps]
    from matplotlib.collections import LineCollection

    segments = _outline_segments(ids, x_edges, y_edges, owners)
    if segments:
        ax.add_collection(
            LineCollection(
                segments,
                colors=OUTLINE_COLOR,
                linewidths=OUTLINE_WIDTH,
                zorder=4,
                gid="region outlines",
            ),
            autolim=False,
        )


def _number_cells(ax, ids: np.ndarray, numbered: list[int], x_edges, y_edges) -> None:
    """Each numbered region's number at the cell deepest inside each of
    its pieces on the grid ``ids`` (nx, ny) of at least
    MIN_NUMBERED_FRACTION of the panel's cells (its largest piece always)."""
    xc = 0.5 * (x_edges[1:] + x_edges[:-1])
    yc = 0.5 * (y_edges[1:] + y_edges[:-1])
    for k in numbered:
        if np.any(ids == k):
            for i, j in _label_cells(ids == k, MIN_NUMBERED_FRACTION * ids.size):
                _number(ax, xc[i], yc[j], k)


def draw_regions_grid(ax, ids: np.ndarray, x_edges, y_edges) -> tuple[int, bool]:
    """Outline every region of a grid slice (its outer boundary and its
    holes, but not thin or small pieces outside it: :data:`SMALL_HOLE_POSES`)
    and number the largest ones near their largest area.

    Args:
        ids: ``poc_region`` ids, shape (nx, ny), the first index along x;
            0 outside every region.
        x_edges, y_edges: cell edges, shapes (nx + 1,), (ny + 1,).

    Returns:
        (number of regions on the panel, whether all of them are numbered).
    """
    ids = np.asarray(ids)
    x_edges, y_edges = np.asarray(x_edges, dtype=float), np.asarray(y_edges, dtype=float)
    _outline(ax, ids, x_edges, y_edges)
    present, numbered = _numbered(ids)
    _number_cells(ax, ids, numbered, x_edges, y_edges)
    return len(present), len(numbered) == len(present)


def draw_regions_samples(ax, ids, x, y, outline: bool) -> tuple[int, bool]:
    """Regions of sampled poses at (x, y) (all shape (N,)): the outlines of
    a raster of the nearest sample (when ``outline``) and the numbers of the
    largest regions near their largest area. Returns what
    :func:`draw_regions_grid` returns."""
    # scipy: loaded on first use
    from scipy.spatial import cKDTree

    ids = np.asarray(ids).reshape(-1)
    keep = np.isfinite(x) & np.isfinite(y)
    ids, x, y = ids[keep], x[keep], y[keep]
    present, numbered = _numbered(ids)
    if not present:
        return 0, True
    x_edges = np.linspace(x.min(), x.max(), _SAMPLE_RASTER + 1)
    y_edges = np.linspace(y.min(), y.max(), _SAMPLE_RASTER + 1)
    span_x, span_y = max(np.ptp(x), 1e-300), max(np.ptp(y), 1e-300)
    tree = cKDTree(np.column_stack([x / span_x, y / span_y]))
    xc, yc = 0.5 * (x_edges[1:] + x_edges[:-1]), 0.5 * (y_edges[1:] + y_edges[:-1])
    X, Y = np.meshgrid(xc / span_x, yc / span_y, indexing="ij")
    _, nearest = tree.query(np.column_stack([X.ravel(), Y.ravel()]))
    raster = ids[nearest].reshape(X.shape)
    if outline:
        _outline(ax, raster, x_edges, y_edges, nearest.reshape(X.shape))
    _number_cells(ax, raster, numbered, x_edges, y_edges)
    return len(present), len(numbered) == len(present)


def draw_regions_band(ax, ids: np.ndarray, edges: np.ndarray) -> tuple[int, bool]:
    """Regions along one coordinate (ids sorted along it, shape (N,); edges
    (N + 1,)) on a band spanning y in [0, 1]: a bar at each region boundary
    and each numbered region's number at the middle of its longest run.
    Returns what :func:`draw_regions_grid` returns."""
    ids = np.asarray(ids).reshape(-1)
    change = np.flatnonzero((ids[1:] != ids[:-1]) & (np.maximum(ids[1:], ids[:-1]) > 0))
    for c in change:
        ax.axvline(edges[c + 1], color=OUTLINE_COLOR, lw=1.4, zorder=4, gid="region outlines")
    present, numbered = _numbered(ids)
    for k in numbered:
        mask = np.concatenate([[False], ids == k, [False]]).astype(np.int8)
        starts = np.flatnonzero(np.diff(mask) == 1)
        ends = np.flatnonzero(np.diff(mask) == -1)
        longest = int(np.argmax(ends - starts))
        middle = 0.5 * (edges[starts[longest]] + edges[ends[longest]])
        _number(ax, middle, 0.5, k, fontsize=8)
    return len(present), len(numbered) == len(present)


def region_handle(count: int, all_numbered: bool = True):
    """Legend entry of the outlines: how many regions, which are numbered."""
    # optional: cdpm[viz/maps]
    from matplotlib.lines import Line2D

    label = f"POC regions ({count}), numbered by size"
    if not all_numbered:
        label += "\n(small ones not numbered)"
    return Line2D([], [], color=OUTLINE_COLOR, lw=1.2, label=label)


# --------------------------------------------------------------------- path


class PathCoordinates(dict):
    """:func:`check_path`'s path: coordinate name -> values (k,), and
    ``suspect``: the steps i (waypoint i to i + 1) to mark as possibly
    crossing a thin NO set."""

    suspect: tuple[int, ...] = ()


def check_path(path, available: list[str], required: list[str]) -> PathCoordinates:
    """A path as float arrays of equal length (k,), by coordinate name.

    Args:
        path: mapping coordinate name -> (k,) values along the path, or a
            :class:`cdpm.regions.paths.POCPath` (its coordinates, and its suspect
            steps marked).
        available: the map's coordinates (pose dims or sampled axes).
        required: the coordinates the picture plots (must be in the path).

    Raises:
        InputError: not a mapping, a name that is not a map coordinate, a
            plotted coordinate missing, values not 1-D finite numbers of one
            length.
    """

    suspect: tuple[int, ...] = ()
    if isinstance(path, POCPath):
        path, suspect = path.coordinates, tuple(path.suspect_steps or ())
    if not isinstance(path, Mapping):
        raise InputError(
            "path must map coordinate names to values along the path (or be a POCPath), got "
            f"{type(path).__name__}"
        )
    unknown = [str(name) for name in path if name not in available]
    if unknown:
        raise InputError(
            f"path coordinates {unknown} are not coordinates of this map; "
            f"its coordinates: {', '.join(available)}"
        )
    missing = [name for name in required if name not in path]
    if missing:
        raise InputError(
            f"path lacks {', '.join(missing)}: the picture plots {', '.join(required)}, "
            "so the path needs values along them"
        )
    out = PathCoordinates()
    out.suspect = suspect
    for name, values in path.items():
        try:
            array = np.asarray(values, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"path[{name!r}] must be numbers") from exc
        if array.ndim != 1 or array.size == 0 or not np.isfinite(array).all():
            raise InputError(
                f"path[{name!r}] must be a non-empty 1-D array of finite numbers, "
                f"got shape {array.shape}"
            )
        out[str(name)] = array
    lengths = {name: a.size for name, a in out.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"path arrays differ in length: {lengths}")
    return out


def _seams(x, y, periods) -> tuple[np.ndarray, np.ndarray]:
    """Steps that cross the seam of an angle axis (a jump of more than half
    a period), shape (k - 1,) bool, and every step the short way round,
    shape (k - 1, 2)."""
    steps = np.column_stack([np.diff(x), np.diff(y)])
    crossing = np.zeros(len(steps), dtype=bool)
    for axis, period in enumerate(periods):
        if period:
            far = np.abs(steps[:, axis]) > 0.5 * period
            steps[far, axis] -= np.round(steps[far, axis] / period) * period
            crossing |= far
    return crossing, steps


#: opacity of a path's start or goal marker on a slice the end is away from
AWAY_ALPHA = 0.35


def draw_path(ax, x, y, near=None, periods=(None, None), suspect=()) -> None:
    """The path through (x, y) (shape (k,)): a line from a start circle to a
    goal star.

    Args:
        suspect: steps i (waypoint i to i + 1) drawn over in SUSPECT_COLOR
            (where both ends are drawn solid).
        near: bool (k,): the poses near the panel's slice, drawn solid; the
            rest of the path is dashed and faint. None: all solid.
        periods: the period of the x and y coordinates (2 pi for angles) or
            None. A step of more than half a period crosses the axis' seam
            (-pi and pi are one pose): it is drawn the short way, leaving the
            panel at one edge and coming back at the other.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    solid = np.ones(x.size, dtype=bool) if near is None else np.asarray(near, dtype=bool)
    crossing, steps = _seams(x, y, periods)
    cuts = np.flatnonzero(crossing) + 1

    def broken(values):  # the path with a gap at each seam crossing
        return np.insert(values, cuts, np.nan)

    solid_style = {"color": PATH_COLOR, "lw": 1.8, "path_effects": halo(3.5), "zorder": 5}
    faint_style = {"color": PATH_COLOR, "lw": 1.0, "ls": "--", "alpha": 0.5, "zorder": 5}
    if not solid.all():
        ax.plot(broken(x), broken(y), **faint_style)
    line_x, line_y = broken(np.where(solid, x, np.nan)), broken(np.where(solid, y, np.nan))
    ax.plot(line_x, line_y, gid="path", **solid_style)
    # seam crossings: out through one edge, back in through the other (the
    # stubs end outside the map: left out of the data limits)
    from matplotlib.collections import LineCollection

    for i in np.flatnonzero(crossing):
        dx, dy = steps[i]
        stubs = [
            [(x[i], y[i]), (x[i] + dx, y[i] + dy)],
            [(x[i + 1] - dx, y[i + 1] - dy), (x[i + 1], y[i + 1])],
        ]
        style = solid_style if solid[i] and solid[i + 1] else faint_style
        if i in suspect and solid[i] and solid[i + 1]:
            style = {**solid_style, "color": SUSPECT_COLOR, "lw": 3.0}
        ax.add_collection(
            LineCollection(
                stubs,
                colors=style["color"],
                linewidths=style["lw"],
                linestyles=style.get("ls", "-"),
                alpha=style.get("alpha"),
                path_effects=style.get("path_effects"),
                zorder=style["zorder"],
                gid="path seam",
            ),
            autolim=False,
        )
    # only where the path is drawn solid (in this slice); across a seam: the stubs above
    marked = [i for i in suspect if not crossing[i] and solid[i] and solid[i + 1]]
    if marked:
        # optional: cdpm[viz/maps]
        from matplotlib.collections import LineCollection

        segments = [[(x[i], y[i]), (x[i + 1], y[i + 1])] for i in marked]
        ax.add_collection(
            LineCollection(
                segments,
                colors=SUSPECT_COLOR,
                linewidths=3.0,
                path_effects=halo(5.0),
                zorder=6,
                gid="suspect steps",
            ),
            autolim=False,
        )
    # a pose alone near its slice draws no segment: mark it
    padded = np.concatenate([[False], solid, [False]])
    alone = solid & ~padded[:-2] & ~padded[2:]
    if alone.any() and x.size > 1:
        ax.plot(x[alone], y[alone], "o", ms=3.5, color=PATH_COLOR, zorder=5, clip_on=False)
    # markers unclipped: a path that ends on the edge of the map keeps its
    # star; faint, as the dashed line, where the end is away from the slice
    ends = {"zorder": 7, "clip_on": False}
    start, goal = (1.0 if solid[i] else AWAY_ALPHA for i in (0, -1))
    ax.plot(
        x[0],
        y[0],
        "o",
        ms=8,
        mfc="white",
        mec=PATH_COLOR,
        mew=1.8,
        alpha=start,
        gid="start",
        **ends,
    )
    ax.plot(
        x[-1],
        y[-1],
        "*",
        ms=13,
        mfc=PATH_COLOR,
        mec="white",
        mew=1.0,
        alpha=goal,
        gid="goal",
        **ends,
    )


def path_handles(path: PathCoordinates, sliced: bool = False, ends: bool = True) -> list:
    """Legend entries of a path (:func:`check_path`'s): its line, with
    ``ends`` its start and goal, and its suspect steps when it has any."""
    # optional: cdpm[viz/maps]
    from matplotlib.lines import Line2D

    label = f"path ({next(iter(path.values())).size} poses)"
    if sliced:
        label += "; dashed: away from this slice"
    handles = [Line2D([], [], color=PATH_COLOR, lw=1.8, label=label)]
    if ends:
        handles += [
            Line2D([], [], ls="", marker="o", ms=7, mfc="white", mec=PATH_COLOR, label="start"),
            Line2D([], [], ls="", marker="*", ms=11, mfc=PATH_COLOR, mec="white", label="goal"),
        ]
    if path.suspect:
        label = f"step that may cross a thin NO set ({len(path.suspect)})"
        handles.append(Line2D([], [], color=SUSPECT_COLOR, lw=3.0, label=label))
    return handles
