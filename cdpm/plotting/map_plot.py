"""Pictures of workspace maps (matplotlib, imported on first use).

:func:`plot_map` draws a map made by :func:`cdpm.workspace_map` (or read
with :func:`cdpm.maps.open_map`) as one figure, the map's first coordinate
on the horizontal axis of every map panel:

- the verdict (categorical colours) over the first two coordinates, with
  the outlines and numbers of the POC regions (``poc_region``; on the POC
  verdict only) and a path when one is given;
- the reach margin r_T [output units] within the horizon T (or, for older
  maps, the unit-impulse POC margin mu_T) on a log colour scale, a few
  stragglers far beyond the rest clipped at either end (said on the colour
  bar); zero margins in red; poses not analysed in greys by reason
  (``status``); the path again. A map made without margins gets no margin
  panel, and its title says so;
- for more than two coordinates, small multiples: slices of the verdict
  along the third coordinate (further coordinates at their middle value);
- an output-space view: every pose at its outputs, coloured by verdict.

Legends sit below the panels, never over a pose. A map over one coordinate
is drawn as a verdict band along it above a line of the margin (the title
gives the other coordinates' base values). Maps of random samples are drawn
as scatter plots in their first two coordinates.
Figures are built with the object-oriented API (no pyplot state), so it
works headless; :func:`save_map_plot` writes an image in any format
matplotlib writes (:func:`image_formats`).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.errors import InputError, is_integer, short_str
from cdpm.maps import open_map
from cdpm.maps.plan import describe_overrides
from cdpm.maps.regions import grid_wrap
from cdpm.pipeline.criteria import CRITERIA
from cdpm.plotting._common import (
    DRAW_ORDER,
    cell_edges,
    clean_value,
    coordinate_label,
    coordinate_value,
    legend_below,
    matplotlib_parts,
    verdict_cmap,
    verdict_handles,
    verdict_index,
    verdict_title,
)
from cdpm.plotting._margin import (
    MarginScale,
    margin_computed,
    margin_grid,
    margin_line,
    margin_scale,
    margin_scatter,
)
from cdpm.plotting._outputs import OutputChoice, choose_outputs, output_panel
from cdpm.plotting._overlays import (
    check_path,
    draw_path,
    draw_regions_band,
    draw_regions_grid,
    draw_regions_samples,
    path_handles,
    region_count,
    region_handle,
)
from cdpm.plotting._slabs import SampleSlab, sample_slabs, slabs_text
from cdpm.verdicts import NOT_ANALYSED, VERDICT_COLORS

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.regions.paths import POCPath

__all__ = [
    "plot_map",
    "save_map_plot",
    "image_formats",
    "check_image_path",
    "check_dpi",
    "VERDICT_COLORS",
]

# VERDICT_COLORS (code -> hex colour, from cdpm.verdicts) stays importable from here


def image_formats() -> list[str]:
    """File extensions (no dot) matplotlib can write, sorted."""
    # optional: cdpm[viz/maps]
    from matplotlib.backend_bases import FigureCanvasBase

    return sorted(FigureCanvasBase.get_supported_filetypes())


def check_output_folder(path: Path) -> None:
    """Raise an InputError (before any work) when the folder ``path`` is to
    be written in does not exist or is not writable."""
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {path}: folder {folder} does not exist; create it first")
    if not os.access(folder, os.W_OK):
        raise InputError(f"cannot write {path}: folder {folder} is not writable")


def check_image_path(path: str | os.PathLike) -> Path:
    """The image file a figure saved at ``path`` ends up in: ``path`` itself
    when matplotlib writes its extension, ``path`` + ``.png`` without one.

    Raises:
        InputError: ``path`` is a folder, or matplotlib cannot write the
            extension (the message lists those it can).
    """
    matplotlib_parts()
    out = Path(path).expanduser()
    if out.is_dir():
        raise InputError(f"{out} is a folder; give an image file name, e.g. {out / 'map.png'}")
    check_output_folder(out)
    if not out.suffix:
        return out.with_name(out.name + ".png")  # what matplotlib would write
    formats = image_formats()
    extension = out.suffix[1:].lower()
    if extension not in formats:
        raise InputError(
            f"cannot write {out.name}: unknown image format {out.suffix!r}; "
            f"use one of {', '.join(formats)}"
        )
    if extension == "pgf":
        # optional: cdpm[viz/maps]
        import matplotlib

        tex = matplotlib.rcParams["pgf.texsystem"]
        if shutil.which(tex) is None:
            raise InputError(f"cannot write {out.name}: .pgf needs {tex}, not found; use .pdf")
    return out


#: highest resolution of a picture [dots per inch]: a page-wide figure at
#: this resolution is already about 10^8 pixels
MAX_DPI = 1200


def check_dpi(dpi: Any) -> float:
    """``dpi`` as a float, when it is a positive finite number.

    Raises:
        InputError: it is not.
    """
    try:
        value = float(dpi)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and 0 < value <= MAX_DPI):
        raise InputError(
            f"dpi={short_str(dpi, 40)} must be a number of dots per inch from 1 to {MAX_DPI} "
            "(print quality is 300-600)"
        )
    return value


def _computed(ds, variable: str) -> bool:
    """Whether the map computed ``variable``: not a variable computed only
    on request (the tension search) in a map made without that request,
    where every pose is 'not analysed'."""

    criterion = CRITERIA.get(variable)
    if criterion is None or not criterion.on_request:
        return True
    return not bool((ds[variable] == NOT_ANALYSED).all())


def _require_computed(ds, variable: str) -> None:
    """Refuse a variable the map did not compute (:func:`_computed`)."""
    if not _computed(ds, variable):
        raise InputError(
            f"{variable!r} was not computed in this map: it comes from the tension "
            "search; make the map with --tension best (tension='best')"
        )


def _load(ds_or_path):
    if isinstance(ds_or_path, (str, os.PathLike)):
        return open_map(ds_or_path)
    return ds_or_path


def _pose_dims(ds, variable: str) -> list[str]:
    return [d for d in ds[variable].dims if d not in ("output", "xyz", "cable")]


def _sampled_axes(ds) -> list[str]:
    """The coordinates of a sampled map: its ``axes`` attribute, else every
    coordinate along ``sample``."""
    axes = ds.attrs.get("axes")
    if axes is None:
        axes = [str(c) for c in ds.coords if ds[c].dims == ("sample",)]
    return list(axes)


def _status(ds, index: dict | None = None, dims: Sequence[str] | None = None):
    """``status`` codes (of a slice, transposed to ``dims``), or None."""
    if "status" not in ds:
        return None
    da = ds["status"].isel(index or {})
    return np.asarray(da.transpose(*dims).values if dims else da.values)


def plot_map(
    ds_or_path: Any,
    *,
    variable: str = "poc",
    margin: bool = True,
    output_view: bool = True,
    outputs: Sequence[str] | str | None = None,
    path: Mapping[str, Any] | POCPath | None = None,
    max_slices: int = 6,
    title: str | None = None,
    subtitle: str | None = None,
):
    """Draw a workspace map.

    Args:
        ds_or_path: the ``xarray.Dataset`` of :func:`cdpm.workspace_map` or
            the path of its zarr store.
        variable: verdict variable to colour by (``poc``, ``wrench_closure``,
            ``positive_controllable``, ``output_controllable``, ``static_feasible``);
            the POC regions are outlined over ``poc`` only.
        margin: add the margin panel: ``reach_margin`` r_T [output units]
            within the horizon T, or ``poc_margin`` mu_T (unitless) on maps
            without it; positive margins on a log colour scale (at most 1 %
            of them at either end, stragglers more than a decade beyond the
            1st or 99th percentile, clipped and said so on the colour bar),
            zero margins red, poses not analysed grey by reason. Maps with neither
            variable, or made with ``margin=False``, get no margin panel
            (the title of the latter says so).
        output_view: add the output-space panel.
        outputs: what the output-space panel plots: one or two names of the
            map's outputs (the ``output`` coordinate of ``y``) or
            ``FRAME.x|y|z`` (world position of the first output's frame).
            One name is plotted against the map's first coordinate. Default:
            the map's outputs (one: against the first coordinate; two or
            more: the first two).
        path: coordinate name -> values along a path of map poses, each of
            shape (k,) [the coordinates' units], or a :class:`cdpm.regions.paths.POCPath`
            (its coordinates, and its ``suspect_steps`` drawn over in magenta:
            steps that may cross a NO set thinner than the map's
            resolution); it must give the plotted coordinates (the first
            two, or the one of a one-axis map). It is drawn over the verdict
            and margin panels as a blue line from a start circle to a goal
            star (on a one-axis map, along the margin line). Coordinates not
            plotted are projected out: on the slices of a grid map of more
            than two axes, the poses whose third coordinate is nearest the
            slice's value are drawn solid and the rest dashed, and on the
            slabs of a sampled map those whose third coordinate lies in the
            slab (all solid without a third coordinate in ``path``); further
            coordinates are ignored. A step across the seam of a full-turn angle (pi to -pi)
            is drawn the short way, out through one edge of the panel and
            back through the other.
        max_slices: most slices drawn for grid maps of more than two axes;
            most slabs for sampled ones, whose samples are cut along the
            third coordinate into slabs of equal width (each of about
            ``cdpm.plotting._slabs.MIN_SLAB_SAMPLES`` = 300 samples at least), one
            panel each; further coordinates are projected.
        title: figure title (default: spec name, poses, the base values of
            the coordinates off the axes, tension).
        subtitle: a line added under the figure title (e.g. how steering
            along ``path`` went).

    Returns:
        ``matplotlib.figure.Figure``.

    Raises:
        InputError: ``variable`` is not a verdict of the map, an unknown
            output name (the message lists the map's), a malformed ``path``
            (not a mapping, a name not of the map, a plotted coordinate
            missing, arrays not 1-D finite numbers of one length).
    """
    _, Figure = matplotlib_parts()
    if not is_integer(max_slices) or max_slices < 1:
        raise InputError(f"max_slices must be a positive integer, got {max_slices!r}")
    ds = _load(ds_or_path)
    if variable not in ds or "flag_values" not in ds[variable].attrs or variable == "status":
        choices = [
            v
            for v in sorted(ds.data_vars)
            if "flag_values" in ds[v].attrs and v != "status" and _computed(ds, v)
        ]
        raise InputError(f"{variable!r} is not a verdict of this map; choose one of {choices}")
    _require_computed(ds, variable)
    dims = _pose_dims(ds, variable)
    sample = dims == ["sample"]
    axes_names = _sampled_axes(ds) if sample else list(dims)
    plotted = axes_names[:2]
    # names are checked even when the panel is left out, so that a typo shows
    choice = choose_outputs(ds, outputs) if output_view or outputs is not None else None
    choice = choice if output_view else None
    if path is not None:
        path = check_path(path, axes_names, plotted)
    scale = margin_scale(ds, variable) if margin else None
    missing = None  # a margin asked for but not in the map: said in the title, no panel
    if scale is not None and not margin_computed(ds, scale):
        missing, scale = scale, None
    # region outlines are POC regions: drawn over POC verdicts only
    regions = region_count(ds) if variable == "poc" else 0
    if len(axes_names) == 1:
        fig = _plot_one_axis(ds, variable, axes_names[0], scale, choice, path, regions)
        map_suptitle(fig, ds, title, axes_names, missing, subtitle=subtitle)
        return fig
    slices: list[dict] = [{}]
    drawn = ""
    slabs: list[SampleSlab] = [SampleSlab.everything(ds)] if sample else []
    if sample and len(axes_names) > 2:
        slabs = sample_slabs(ds, axes_names[2], max_slices)
        slices = [{}] * len(slabs)
        drawn = slabs_text(axes_names[2:], len(slabs))
    elif not sample and len(dims) > 2:
        third = dims[2]
        picks = slice_picks(ds, third, max_slices, path)
        rest = {d: ds.sizes[d] // 2 for d in dims[3:]}
        slices = [{third: int(k), **rest} for k in picks]
        drawn = slices_text(ds, third, picks, rest)
    panels = ["verdict"] * len(slices)
    if scale is not None:
        panels.append("margin")
    if choice is not None:
        panels.append("output")
    ncols = min(len(panels), 3)
    nrows = -(-len(panels) // ncols)
    fig = Figure(figsize=(5.0 * ncols, 5.1 * nrows), layout="constrained")
    axs = [fig.add_subplot(nrows, ncols, k + 1) for k in range(len(panels))]
    for k, (ax, kind) in enumerate(zip(axs, panels, strict=True)):
        if kind == "output":
            output_panel(ax, ds, variable, choice, axes_names[0])
        elif sample:
            slab = slabs[k] if kind == "verdict" else slabs[len(slabs) // 2]
            _sample_panel(ax, fig, ds, variable, axes_names, kind, scale, path, regions, slab)
        elif kind == "margin":
            _margin_grid_panel(ax, fig, ds, variable, dims, slices, scale, path)
        else:
            _verdict_grid_panel(ax, ds, variable, dims, slices, k, path, regions)
    map_suptitle(fig, ds, title, axes_names, missing, drawn, subtitle)
    return fig


def _period(ds, name: str) -> float | None:
    """2 pi for an angle coordinate (units rad), else None: a path step of
    more than half of it crosses the seam where -pi meets pi."""
    return 2.0 * math.pi if ds[name].attrs.get("units") == "rad" else None


def _where(ds, index: dict) -> str:
    """The slice's value of the map's third axis (``"q3 = 0.5 rad"``), or "";
    further axes are at their middle value, which the figure title says."""
    return ", ".join(
        coordinate_value(ds, d, float(ds[d].values[i])) for d, i in list(index.items())[:1]
    )


def _verdict_grid_panel(ax, ds, variable, dims, slices, k, path, regions) -> None:
    """Verdict slice ``k`` over the first two grid coordinates, with the
    region outlines and the path; the legend below the first slice."""
    x, y = dims[0], dims[1]
    index = slices[k]
    x_edges, y_edges = cell_edges(ds[x].values), cell_edges(ds[y].values)
    X, Y = np.meshgrid(x_edges, y_edges, indexing="ij")
    # the mesh keeps the map's (x, y) order: cell (i, j) is pose (i, j)
    codes = np.asarray(ds[variable].isel(index).transpose(x, y).values)
    cmap, norm = verdict_cmap()
    ax.pcolormesh(X, Y, verdict_index(codes), cmap=cmap, norm=norm, shading="flat", gid="verdict")
    all_numbered = True
    if regions:
        ids = ds["poc_region"].isel(index).transpose(x, y).values
        _, all_numbered = draw_regions_grid(ax, ids, x_edges, y_edges)
    sliced = _grid_path(ax, ds, dims, slices, k, path)
    ax.set_xlabel(coordinate_label(ds, x))
    ax.set_ylabel(coordinate_label(ds, y))
    ax.set_box_aspect(1)
    where = _where(ds, index)
    ax.set_title(verdict_title(variable) + (f" ({where})" if where else ""), fontsize=10)
    if k == 0:
        handles = verdict_handles(np.asarray(ds[variable].values))
        if regions:
            handles.append(region_handle(regions, all_numbered))
        if path is not None:
            handles += path_handles(path, sliced)
        legend_below(ax, handles, ncol=3)


def _grid_path(ax, ds, dims, slices, k, path) -> bool:
    """Draw the path over grid slice ``k``; returns whether it is drawn
    solid near the slice and dashed away from it."""
    if path is None:
        return False
    x, y = dims[0], dims[1]
    sliced = bool(slices[k]) and dims[2] in path
    near = near_slice(ds, dims[2], path[dims[2]], slices, k) if sliced else None
    draw_path(ax, path[x], path[y], near, (_period(ds, x), _period(ds, y)), path.suspect)
    return sliced


def _margin_grid_panel(ax, fig, ds, variable, dims, slices, scale: MarginScale, path) -> None:
    """The margin over a slice of the first two grid coordinates (the
    path's start's, else the middle one: :func:`margin_slice`), with the
    path (where a maximin path matters)."""
    x, y = dims[0], dims[1]
    k = margin_slice(ds, dims[2] if len(dims) > 2 else None, slices, path)
    index = slices[k]
    values = ds[scale.variable].isel(index).transpose(x, y).values
    codes = ds[variable].isel(index).transpose(x, y).values
    x_edges, y_edges = cell_edges(ds[x].values), cell_edges(ds[y].values)
    status = _status(ds, index, (x, y))
    handles = margin_grid(ax, fig, x_edges, y_edges, values, status, codes, scale)
    sliced = _grid_path(ax, ds, dims, slices, k, path)
    if path is not None:
        handles += path_handles(path, sliced, ends=False)
    legend_below(ax, handles, ncol=1)
    ax.set_xlabel(coordinate_label(ds, x))
    ax.set_ylabel(coordinate_label(ds, y))
    ax.set_box_aspect(1)
    where = _where(ds, index)
    ax.set_title(scale.title + (f"\n({where})" if where else ""), fontsize=10)


def _sample_panel(ax, fig, ds, variable, axes_names, kind, scale, path, regions, slab) -> None:
    """A scatter of the samples of ``slab`` (a :class:`SampleSlab`) in
    their first two coordinates: verdicts (with regions and the path) or
    margins."""
    xn, yn = axes_names[0], axes_names[1]
    keep = slab.mask
    xv = np.asarray(ds[xn].values, dtype=float)[keep]
    yv = np.asarray(ds[yn].values, dtype=float)[keep]
    values = np.asarray(ds[variable].values).reshape(-1)[keep]
    size = max(3.0, min(40.0, 30000.0 / max(values.size, 1)))
    verdicts = kind == "verdict"
    if verdicts:
        for c in DRAW_ORDER:
            sel = values == c
            if sel.any():
                ax.scatter(
                    xv[sel],
                    yv[sel],
                    s=size,
                    c=VERDICT_COLORS[c],
                    linewidths=0,
                    rasterized=True,
                    gid="verdict",
                )
        handles = verdict_handles(values)
        if regions:
            ids = np.asarray(ds["poc_region"].values).reshape(-1)[keep]
            _, all_numbered = draw_regions_samples(ax, ids, xv, yv, len(axes_names) == 2)
            handles.append(region_handle(regions, all_numbered))
        title = verdict_title(variable)
    else:
        margins = np.asarray(ds[scale.variable].values, dtype=float)[keep]
        status = _status(ds)
        status = None if status is None else status.reshape(-1)[keep]
        handles = margin_scatter(ax, fig, xv, yv, margins, status, values, scale, size)
        title = scale.title
    if path is not None:
        periods = (_period(ds, xn), _period(ds, yn))
        near = slab.near(path)
        draw_path(ax, path[xn], path[yn], near, periods=periods, suspect=path.suspect)
        handles += path_handles(path, near is not None, ends=verdicts)
    legend_below(ax, handles, ncol=3 if verdicts else 1)
    ax.set_title(title + slab.title(), fontsize=10)
    ax.set_xlabel(coordinate_label(ds, xn))
    ax.set_ylabel(coordinate_label(ds, yn))
    ax.set_box_aspect(1)


def _plot_one_axis(ds, variable, name, scale, choice: OutputChoice | None, path, regions: int):
    """A map over one coordinate: the verdict as a coloured band along it
    (regions and path on it), the margin as a line over it on a log axis
    (same x axis, the path along it), the output-space view beside."""
    matplotlib, Figure = matplotlib_parts()
    x = np.asarray(ds[name].values, dtype=float).reshape(-1)
    order = np.argsort(x, kind="stable")
    x = x[order]
    codes = np.asarray(ds[variable].values).reshape(-1)[order]
    tall = scale is not None or choice is not None
    width = 11.5 if choice is not None else 6.8
    fig = Figure(figsize=(width, 4.6 if tall else 2.2), layout="constrained")
    widths = [1.35, 1.0] if choice is not None else [1.0]
    grid = fig.add_gridspec(1, len(widths), width_ratios=widths)
    if scale is not None:
        left = grid[0, 0].subgridspec(2, 1, height_ratios=[1, 4])
    elif choice is not None:  # the band alone, at mid height beside the output view
        left = grid[0, 0].subgridspec(3, 1, height_ratios=[3, 2, 3])
        left = [left[1]]
    else:
        left = [grid[0, 0]]
    strip = fig.add_subplot(left[0])
    edges = cell_edges(x)
    cmap, norm = verdict_cmap()
    strip.pcolormesh(
        edges, [0.0, 1.0], verdict_index(codes)[None, :], cmap=cmap, norm=norm, gid="verdict"
    )
    strip.set_ylim(0.0, 1.0)
    strip.set_yticks([])
    strip.set_ylabel(verdict_title(variable).replace(" verdict", "\nverdict"), fontsize=9)
    handles = verdict_handles(codes)
    if regions:
        ids = np.asarray(ds["poc_region"].values).reshape(-1)[order]
        count, all_numbered = draw_regions_band(strip, ids, edges)
        if count:
            handles.append(region_handle(regions, all_numbered))
    period = _period(ds, name)
    if path is not None:
        draw_path(
            strip,
            path[name],
            np.full(path[name].size, 0.5),
            periods=(period, None),
            suspect=path.suspect,
        )
        handles += path_handles(path)
    # above the strip, in as many columns as fit its width: a wider legend
    # (a path's entries) set the width of the strip's column and squeezed it
    room = 0.9 * fig.get_figwidth() * fig.dpi * widths[0] / sum(widths)
    if not hasattr(fig.canvas, "get_renderer"):  # a bare Figure: measure with Agg
        # optional: cdpm[viz/maps]
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
    renderer = fig.canvas.get_renderer()
    for ncol in range(min(len(handles), 4), 0, -1):
        legend = strip.legend(
            handles=handles,
            loc="lower left",
            bbox_to_anchor=(0.0, 1.02),
            ncol=ncol,
            fontsize=8,
            frameon=False,
            borderaxespad=0.0,
            handlelength=1.2,
            columnspacing=1.0,
        )
        if ncol == 1 or legend.get_window_extent(renderer).width <= room:
            break
        legend.remove()
    axis_label = coordinate_label(ds, name)
    if scale is not None:
        line = fig.add_subplot(left[1], sharex=strip)
        strip.tick_params(labelbottom=False)
        values = np.asarray(ds[scale.variable].values, dtype=float).reshape(-1)[order]
        status = _status(ds)
        status = None if status is None else status.reshape(-1)[order]
        margin_handles = margin_line(line, x, values, status, codes, scale)
        if path is not None:
            heights = _along_line(line, x, values, path[name])
            draw_path(line, path[name], heights, periods=(period, None), suspect=path.suspect)
        line.set_xlabel(axis_label)
        line.set_title(scale.title, fontsize=10)
        legend_below(line, margin_handles, ncol=2)
    else:
        strip.set_xlabel(axis_label)
    if choice is not None:
        output_panel(fig.add_subplot(grid[0, 1]), ds, variable, choice, name)
    return fig


def _along_line(ax, x: np.ndarray, values: np.ndarray, path_x: np.ndarray) -> np.ndarray:
    """Heights of path poses on the margin line: the margin of the nearest
    map pose (x sorted, shape (N,)), kept within the axis' limits; the
    bottom edge where the margin is not positive (with the zero ticks)."""
    nearest = np.clip(np.searchsorted(x, path_x), 1, x.size - 1) if x.size > 1 else None
    if nearest is None:
        index = np.zeros(path_x.size, dtype=int)
    else:
        left_closer = np.abs(path_x - x[nearest - 1]) <= np.abs(x[nearest] - path_x)
        index = np.where(left_closer, nearest - 1, nearest)
    low, high = ax.get_ylim()
    return np.clip(np.where(values[index] > 0, values[index], low), low, high)


def save_map_plot(
    ds_or_path: Any,
    image: str | os.PathLike,
    *,
    dpi: float = 100,
    variable: str = "poc",
    margin: bool = True,
    output_view: bool = True,
    outputs: Sequence[str] | str | None = None,
    path: Mapping[str, Any] | POCPath | None = None,
    max_slices: int = 6,
    title: str | None = None,
    subtitle: str | None = None,
) -> Path:
    """Draw a map with :func:`plot_map` and write it to the file ``image``
    in the format of its extension (PNG without one); returns the file
    written. The keywords are :func:`plot_map`'s (``path``: coordinate name
    -> (k,) values along a path of map poses, or a POCPath), and ``dpi``
    the resolution.

    Raises:
        InputError: matplotlib cannot write the extension, ``dpi`` is not
            positive (both checked before any drawing), the store is not a
            cdpm map, or a keyword is wrong (see :func:`plot_map`).
    """
    out = check_image_path(image)
    dpi = check_dpi(dpi)
    fig = plot_map(
        ds_or_path,
        variable=variable,
        margin=margin,
        output_view=output_view,
        outputs=outputs,
        path=path,
        max_slices=max_slices,
        title=title,
        subtitle=subtitle,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    return out


# ------------------------------------------------------------------ slices


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


# ------------------------------------------------------------------ titles


#: most slice values left out that a title names one by one
_MAX_NAMED_SLICES = 4


def slices_text(ds, third: str, picks: np.ndarray, rest: dict) -> str:
    """What the slices of a map of more than two axes leave out, or "":
    ``"slices: 6 of the 8 values of q3 (not drawn: -0.257, 0.257 rad); q4 =
    0 rad only (the middle of its 3 values)"``."""
    parts = []
    units = ds[third].attrs.get("units", "")
    unit = f" {units}" if units else ""
    every = np.asarray(ds[third].values, dtype=float)
    poses = distinct_poses(ds, third)
    same = ""
    if poses.size < every.size:  # a closed axis: its upper end is its lower end's pose
        same = f"{every.max():.3g} = {every.min():.3g}{unit}; "
    if picks.size < poses.size:
        left = np.setdiff1d(poses, picks)
        named = (
            ", ".join(f"{clean_value(ds, third, v):.3g}" for v in every[left]) + unit
            if left.size <= _MAX_NAMED_SLICES
            else f"{left.size} values"
        )
        distinct = "distinct " if same else ""
        parts.append(
            f"slices: {picks.size} of the {poses.size} {distinct}values of {third} "
            f"({same}not drawn: {named})"
        )
    for d, i in rest.items():
        value = coordinate_value(ds, d, float(ds[d].values[i]))
        parts.append(f"{value} only (the middle of its {ds.sizes[d]} values)")
    return "; ".join(parts)


#: most base coordinates a title lists
_MAX_BASE_IN_TITLE = 6


def _base_text(ds, axes_names: Sequence[str]) -> str:
    """``"q2 = 1.047 (base)"``: the coordinates off the map's axes at the
    base pose (attributes ``robot_coordinates`` and ``base``), or ""."""
    names, base = ds.attrs.get("robot_coordinates"), ds.attrs.get("base")
    try:
        names, base = [str(n) for n in names], [float(v) for v in base]
    except (TypeError, ValueError):
        return ""
    if len(names) != len(base):  # natural coordinates that are not named one by one
        return ""
    fixed = [  # + 0.0: no "-0"
        f"{n} = {v + 0.0:.4g}" for n, v in zip(names, base, strict=True) if n not in axes_names
    ]
    if not fixed:
        return ""
    if len(fixed) > _MAX_BASE_IN_TITLE:
        fixed = [*fixed[:_MAX_BASE_IN_TITLE], "..."]
    return ", ".join(fixed) + " (base)"


def _poses_text(ds, axes_names: Sequence[str]) -> str:
    """``"q1: 181 poses, q2 = 1.047 (base)"``, ``"181 x 181 grid"``,
    ``"2000 random poses"``: what the map covers."""
    if "sample" in ds.dims:
        poses = f"{ds.sizes['sample']} random poses"
    elif len(axes_names) == 1:
        poses = f"{axes_names[0]}: {ds.sizes[axes_names[0]]} poses"
    else:
        sizes = [ds.sizes[d] for d in ds.dims if d not in ("output", "xyz", "cable")]
        poses = " x ".join(str(n) for n in sizes) + " grid"
    base = _base_text(ds, axes_names)
    return f"{poses}, {base}" if base else poses


def _overrides_text(ds) -> str:
    """``"overrides of the spec: gravity [0, 0, -5] m/s^2; ..."``: what the
    map's robot changed of its spec (attribute ``overrides``), or ""."""

    try:
        overrides = json.loads(ds.attrs.get("overrides", "{}"))
    except (TypeError, ValueError):
        return ""
    if not isinstance(overrides, dict) or not overrides:
        return ""
    return f"overrides of the spec: {describe_overrides(overrides)}"


def map_suptitle(
    fig,
    ds,
    title: str | None,
    axes_names,
    missing: MarginScale | None,
    drawn: str = "",
    subtitle: str | None = None,
) -> None:
    """The figure title: ``title``, else the spec, the poses, the base pose
    and the tension, a line on the spec's values the map overrode, a line
    ``drawn`` on the slices left out (maps of more than two axes), and a
    line when the margin was asked for but the map has none; then
    ``subtitle``."""
    width = int(12 * fig.get_figwidth())  # characters: about 12 an inch at 11 points
    if title is None:
        tension = ds.attrs.get("tension", "?")
        try:
            tension = json.loads(tension)
        except (TypeError, ValueError):
            pass
        spec = Path(str(ds.attrs.get("spec", "map"))).name
        head = f"{spec}: {_poses_text(ds, axes_names)}"
        tail = f"equilibrium tension {tension}"
        if "poc_some_tension" in ds and bool((ds["poc_some_tension"] >= 0).any()):
            tail += " (and the tension search)"
        fits = len(head) + len(tail) + 2 <= width
        title = f"{head}, {tail}" if fits else f"{textwrap.fill(head, width)}\n{tail}"
        overrides = _overrides_text(ds)
        if overrides:
            title += "\n" + textwrap.fill(overrides, width)
        if drawn:
            title += "\n" + textwrap.fill(drawn, width)
        if missing is not None:
            what = "reach margin" if missing.variable == "reach_margin" else "POC margin"
            title += f"\n{what} not computed (map made with --no-margin): no margin panel"
    if subtitle:
        title += "\n" + textwrap.fill(subtitle, width)
    fig.suptitle(title, fontsize=11)
