"""Pictures of workspace maps (matplotlib, imported on first use).

:func:`plot_map` draws a map made by :func:`cdpm.workspace_map` (or read
with :func:`cdpm.maps.open_map`) as one figure:

- the verdict (categorical colours with a legend) over the first two axes,
  with axis labels in the coordinates' names and units;
- the POC margin with a diverging colour map centred at 0;
- for more than two axes, small multiples: slices of the verdict along the
  third axis (further axes at their middle value);
- an output-space view: each pose at its outputs y (or at the position of
  the first output's frame when p = 1), coloured by verdict.

A map over one axis (a grid or samples of one coordinate) is drawn as a
coloured verdict band along that axis above a line of the margin. Random-sample
maps of more axes are drawn as scatter plots in the first two coordinates.
Figures are built with the object-oriented API (no pyplot state), so it
works headless; :func:`save_map_plot` writes an image in any format
matplotlib writes (:func:`image_formats`).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError, MissingExtraError
from cdpm.verdicts import (
    MARGINAL,
    NO,
    NOT_ANALYSED,
    VERDICT_CODES,
    VERDICT_COLORS,
    VERDICT_LABELS,
    VERDICT_ORDER,
    YES,
)

__all__ = [
    "plot_map",
    "save_map_plot",
    "image_formats",
    "check_image_path",
    "check_dpi",
    "VERDICT_COLORS",
]

# verdict codes, labels, colours and colour-map order come from cdpm.verdicts;
# VERDICT_COLORS (code -> hex colour) stays importable from here

#: legends list yes, no, marginal, not analysed (the order of VERDICT_CODES)
_LEGEND_ORDER = tuple(VERDICT_CODES.values())
#: scatter plots draw the rarer verdicts on top
_DRAW_ORDER = (YES, NOT_ANALYSED, MARGINAL, NO)


def _matplotlib():
    try:
        import matplotlib
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise MissingExtraError("plots need matplotlib: pip install 'cdpm[maps]'") from exc
    return matplotlib, Figure


def image_formats() -> list[str]:
    """File extensions (no dot) matplotlib can write, sorted."""
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
        InputError: matplotlib cannot write the extension (the message lists
            those it can).
    """
    _matplotlib()
    out = Path(path).expanduser()
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
        import shutil

        import matplotlib

        tex = matplotlib.rcParams["pgf.texsystem"]
        if shutil.which(tex) is None:
            raise InputError(f"cannot write {out.name}: .pgf needs {tex}, not found; use .pdf")
    return out


def check_dpi(dpi: Any) -> float:
    """``dpi`` as a float, when it is a positive finite number.

    Raises:
        InputError: it is not.
    """
    try:
        value = float(dpi)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"dpi={dpi} must be a positive number of dots per inch")
    return value


def _load(ds_or_path):
    if isinstance(ds_or_path, (str, os.PathLike)):
        from cdpm.maps import open_map

        return open_map(ds_or_path)
    return ds_or_path


def _label(ds, name: str) -> str:
    units = ds[name].attrs.get("units")
    return f"{name} [{units}]" if units else name


def _verdict_cmap(matplotlib):
    from matplotlib.colors import BoundaryNorm, ListedColormap

    cmap = ListedColormap([VERDICT_COLORS[c] for c in VERDICT_ORDER])
    norm = BoundaryNorm(np.arange(len(VERDICT_ORDER) + 1) - 0.5, len(VERDICT_ORDER))
    return cmap, norm


def _verdict_index(codes: np.ndarray) -> np.ndarray:
    index = np.zeros(codes.shape, dtype=int)
    for k, c in enumerate(VERDICT_ORDER):
        index[codes == c] = k
    return index


def _legend(ax, codes: np.ndarray, variable: str) -> None:
    from matplotlib.patches import Patch

    present = [c for c in _LEGEND_ORDER if np.any(codes == c)]
    handles = [
        Patch(facecolor=VERDICT_COLORS[c], edgecolor="0.3", label=VERDICT_LABELS[c])
        for c in present
    ]
    ax.legend(
        handles=handles,
        title=variable,
        loc="upper right",
        fontsize=8,
        title_fontsize=8,
        framealpha=0.85,
    )


def _pose_dims(ds) -> list[str]:
    return [d for d in ds["poc"].dims if d not in ("output", "xyz")]


def _grid_panel(ax, ds, variable: str, x: str, y: str, index: dict, kind: str, fig):
    da = ds[variable].isel(index).transpose(y, x)
    xv, yv = ds[x].values, ds[y].values
    values = np.asarray(da.values)
    if kind == "verdict":
        matplotlib, _ = _matplotlib()
        cmap, norm = _verdict_cmap(matplotlib)
        ax.pcolormesh(xv, yv, _verdict_index(values), cmap=cmap, norm=norm, shading="nearest")
    else:
        from matplotlib.colors import TwoSlopeNorm

        finite = values[np.isfinite(values)]
        span = float(np.max(np.abs(finite))) if finite.size else 1.0
        span = span if span > 0 else 1.0
        mesh = ax.pcolormesh(
            xv, yv, values, cmap="RdBu", norm=TwoSlopeNorm(0.0, -span, span), shading="nearest"
        )
        fig.colorbar(mesh, ax=ax, shrink=0.85, label=variable)
    ax.set_xlabel(_label(ds, x))
    ax.set_ylabel(_label(ds, y))
    return values


def _output_view(ax, ds, variable: str) -> None:
    codes = np.asarray(ds[variable].values).reshape(-1)
    if ds.sizes.get("output", 0) >= 2:
        pts = np.asarray(ds["y"].values).reshape(-1, ds.sizes["output"])[:, :2]
        names = [str(n) for n in ds["output"].values[:2]]
        xlabel, ylabel = f"{names[0]} [m]", f"{names[1]} [m]"
    else:
        pts = np.asarray(ds["output_frame_position"].values).reshape(-1, 3)
        frame = ds["output_frame_position"].attrs.get("frame", "frame")
        spread = np.nanstd(pts, axis=0)
        axes = np.argsort(spread)[::-1][:2]
        axes.sort()
        pts = pts[:, axes]
        xlabel = f"{frame} {'xyz'[axes[0]]} [m]"
        ylabel = f"{frame} {'xyz'[axes[1]]} [m]"
    size = max(1.0, min(30.0, 12000.0 / max(len(codes), 1)))
    for c in _DRAW_ORDER:
        sel = codes == c
        if sel.any():
            ax.scatter(
                pts[sel, 0],
                pts[sel, 1],
                s=size,
                c=VERDICT_COLORS[int(c)],
                linewidths=0,
                label=VERDICT_LABELS[int(c)],
                rasterized=True,
            )
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"output space, coloured by {variable}", fontsize=10)
    _legend(ax, codes, variable)


def plot_map(
    ds_or_path: Any,
    *,
    variable: str = "poc",
    margin: bool = True,
    output_view: bool = True,
    max_slices: int = 6,
    title: str | None = None,
):
    """Draw a workspace map.

    Args:
        ds_or_path: the ``xarray.Dataset`` of :func:`cdpm.workspace_map` or
            the path of its zarr store.
        variable: verdict variable to colour by (``poc``, ``wrench_closure``,
            ``positive_controllable``, ``output_controllable``, ``static_feasible``).
        margin: add the ``poc_margin`` panel.
        output_view: add the output-space panel.
        max_slices: most slices drawn for maps of more than two axes.
        title: figure title (default: spec name and settings).

    Returns:
        ``matplotlib.figure.Figure``.
    """
    _, Figure = _matplotlib()
    ds = _load(ds_or_path)
    if variable not in ds or "flag_values" not in ds[variable].attrs or variable == "status":
        choices = [v for v in ds.data_vars if "flag_values" in ds[v].attrs and v != "status"]
        raise InputError(f"{variable!r} is not a verdict of this map; choose one of {choices}")
    dims = _pose_dims(ds)
    sample = dims == ["sample"]
    axes_names = list(ds.attrs.get("axes", dims))
    if len(axes_names) == 1:
        fig = _plot_one_axis(ds, variable, axes_names[0], margin, output_view)
        _suptitle(fig, ds, title)
        return fig
    panels: list[str] = []
    slices: list[dict] = [{}]
    if not sample and len(dims) > 2:
        third = dims[2]
        n3 = ds.sizes[third]
        picks = np.unique(np.linspace(0, n3 - 1, min(max_slices, n3)).round().astype(int))
        rest = {d: ds.sizes[d] // 2 for d in dims[3:]}
        slices = [{third: int(k), **rest} for k in picks]
    panels += ["verdict"] * len(slices)
    if margin:
        panels.append("margin")
    if output_view:
        panels.append("output")
    ncols = min(len(panels), 3)
    nrows = -(-len(panels) // ncols)
    fig = Figure(figsize=(4.6 * ncols, 4.0 * nrows), layout="constrained")
    axs = [fig.add_subplot(nrows, ncols, k + 1) for k in range(len(panels))]
    mid = slices[len(slices) // 2]
    for k, (ax, kind) in enumerate(zip(axs, panels, strict=True)):
        if kind == "output":
            _output_view(ax, ds, variable)
            continue
        if sample:
            _sample_panel(
                ax, ds, variable if kind == "verdict" else "poc_margin", dims, axes_names, kind, fig
            )
            continue
        x, y = dims[1], dims[0]
        index = slices[k] if kind == "verdict" else mid
        _grid_panel(ax, ds, variable if kind == "verdict" else "poc_margin", x, y, index, kind, fig)
        where = ", ".join(f"{d} = {float(ds[d].values[i]):.3g}" for d, i in index.items())
        name = variable if kind == "verdict" else "POC margin"
        ax.set_title(name + (f" ({where})" if where else ""), fontsize=10)
        if kind == "verdict" and k == 0:
            _legend(ax, np.asarray(ds[variable].values), variable)
    _suptitle(fig, ds, title)
    return fig


def _suptitle(fig, ds, title: str | None) -> None:
    tension = ds.attrs.get("tension", "?")
    try:
        tension = json.loads(tension)
    except (TypeError, ValueError):
        pass
    spec = Path(str(ds.attrs.get("spec", "map"))).name
    fig.suptitle(title or f"{spec}: equilibrium tension {tension}", fontsize=11)


def _cell_edges(x: np.ndarray) -> np.ndarray:
    """Edges of cells centred on sorted values x (half-way between neighbours)."""
    if x.size == 1:
        half = 0.5 * max(abs(float(x[0])), 1.0)
        return np.array([x[0] - half, x[0] + half])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.concatenate([[2 * x[0] - mid[0]], mid, [2 * x[-1] - mid[-1]]])


def _plot_one_axis(ds, variable: str, name: str, margin: bool, output_view: bool):
    """A map over one coordinate: the verdict as a coloured band along it,
    the margin as a line over it (same x axis), the output-space view beside."""
    matplotlib, Figure = _matplotlib()
    x = np.asarray(ds[name].values, dtype=float).reshape(-1)
    order = np.argsort(x, kind="stable")
    x = x[order]
    codes = np.asarray(ds[variable].values).reshape(-1)[order]
    tall = margin or output_view
    fig = Figure(figsize=(10.6 if output_view else 6.4, 4.0 if tall else 1.9), layout="constrained")
    widths = [1.4, 1.0] if output_view else [1.0]
    grid = fig.add_gridspec(1, len(widths), width_ratios=widths)
    if margin:
        left = grid[0, 0].subgridspec(2, 1, height_ratios=[1, 4])
    elif output_view:  # the band alone, at mid height beside the output view
        left = grid[0, 0].subgridspec(3, 1, height_ratios=[3, 2, 3])
        left = [left[1]]
    else:
        left = [grid[0, 0]]
    strip = fig.add_subplot(left[0])
    cmap, norm = _verdict_cmap(matplotlib)
    strip.pcolormesh(
        _cell_edges(x), [0.0, 1.0], _verdict_index(codes)[None, :], cmap=cmap, norm=norm
    )
    strip.set_ylim(0.0, 1.0)
    strip.set_yticks([])
    strip.set_title(f"{variable} along {name}", fontsize=10, loc="left")
    from matplotlib.patches import Patch

    present = [c for c in _LEGEND_ORDER if np.any(codes == c)]
    strip.legend(
        handles=[
            Patch(facecolor=VERDICT_COLORS[c], edgecolor="0.3", label=VERDICT_LABELS[c])
            for c in present
        ],
        loc="lower right",
        bbox_to_anchor=(1.0, 1.0),
        ncol=len(present),
        fontsize=8,
        frameon=False,
        borderaxespad=0.1,
        handlelength=1.2,
        columnspacing=1.0,
    )
    axis_label = _label(ds, name)
    if margin:
        line = fig.add_subplot(left[1], sharex=strip)
        strip.tick_params(labelbottom=False)
        values = np.asarray(ds["poc_margin"].values, dtype=float).reshape(-1)[order]
        line.axhline(0.0, color="0.55", lw=0.8, ls="--")
        line.fill_between(
            x, 0.0, values, where=values > 0, color=VERDICT_COLORS[YES], alpha=0.25, lw=0
        )
        line.plot(x, values, color="0.15", lw=1.4, label="POC margin")
        # a value between two gaps draws no line segment: mark it
        finite = np.isfinite(values)
        padded = np.concatenate([[False], finite, [False]])
        alone = finite & ~padded[:-2] & ~padded[2:]
        line.plot(x[alone], values[alone], ".", color="0.15", ms=4)
        if not np.isfinite(values).any():
            line.text(
                0.5,
                0.5,
                "no margin in this map (made with --no-margin)",
                transform=line.transAxes,
                ha="center",
                va="center",
                color="0.4",
            )
        line.set_ylabel("POC margin")
        line.set_xlabel(axis_label)
        line.grid(True, color="0.9", lw=0.6)
    else:
        strip.set_xlabel(axis_label)
    if output_view:
        _output_view(fig.add_subplot(grid[0, 1]), ds, variable)
    return fig


def _sample_panel(ax, ds, variable, dims, axes_names, kind, fig):
    xn, yn = axes_names[0], axes_names[1]
    xv, yv = np.asarray(ds[xn].values), np.asarray(ds[yn].values)
    values = np.asarray(ds[variable].values).reshape(-1)
    size = max(3.0, min(40.0, 30000.0 / max(values.size, 1)))
    if kind == "verdict":
        for c in _DRAW_ORDER:
            sel = values == c
            if sel.any():
                ax.scatter(
                    xv[sel], yv[sel], s=size, c=VERDICT_COLORS[c], linewidths=0, rasterized=True
                )
        _legend(ax, values, variable)
        ax.set_title(variable, fontsize=10)
    else:
        from matplotlib.colors import TwoSlopeNorm

        finite = values[np.isfinite(values)]
        span = float(np.max(np.abs(finite))) if finite.size else 1.0
        span = span if span > 0 else 1.0
        sc = ax.scatter(
            xv,
            yv,
            s=size,
            c=values,
            cmap="RdBu",
            norm=TwoSlopeNorm(0.0, -span, span),
            linewidths=0,
            rasterized=True,
        )
        fig.colorbar(sc, ax=ax, shrink=0.85, label=variable)
        ax.set_title("POC margin", fontsize=10)
    ax.set_xlabel(_label(ds, xn))
    ax.set_ylabel(_label(ds, yn))


def save_map_plot(ds_or_path: Any, path: str | os.PathLike, *, dpi: float = 100, **kwargs) -> Path:
    """Draw a map with :func:`plot_map` and write it as an image in the
    format of the file extension (PNG without one); returns the path written.

    Raises:
        InputError: matplotlib cannot write the extension, ``dpi`` is not
            positive (both checked before any drawing), or the store is not
            a cdpm map.
    """
    out = check_image_path(path)
    dpi = check_dpi(dpi)
    fig = plot_map(ds_or_path, **kwargs)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    return out
