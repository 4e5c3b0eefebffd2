"""The margin panel of a map picture: positive margins on a log colour
scale, zero margins in red, poses without a margin by reason.

A map's headline margin is ``reach_margin`` r_T [output units]: within the
horizon T (dataset attribute ``reach_horizon`` [s]) the cables, with
tension changes within their bounds (up to +-``tension_budget`` [N] for
cables without an upper bound), can move the output r_T in every
direction. Older maps carry only ``poc_margin``, the unit-impulse
index mu_T (unitless); it is drawn the same way and labelled as what it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cdpm._plot_common import (
    MARGIN_CMAP,
    NO_MARGIN_COLOR,
    STATUS_COLORS,
    STATUS_TEXT,
    ZERO_MARGIN_COLOR,
    cell_edges,
    legend_below,
)
from cdpm.verdicts import NOT_ANALYSED, STATUS_CODES

#: margin variables, the headline one first
MARGIN_VARIABLES = ("reach_margin", "poc_margin")

#: category index of a pose without a positive margin
ZERO, NO_MARGIN, UNKNOWN = 0, 1, 2
_STATUS_ORDER = (
    STATUS_CODES["no_equilibrium"],
    STATUS_CODES["singular_mass_matrix"],
    STATUS_CODES["zero_length_cable"],
    STATUS_CODES["analysis_failed"],
    STATUS_CODES["pending"],
)
#: category index of status code s: _FIRST_STATUS + _STATUS_ORDER.index(s)
_FIRST_STATUS = 3
#: positive margins: no category
POSITIVE = -1


@dataclass(frozen=True)
class MarginScale:
    """How a map's margin is labelled.

    Attributes:
        variable: ``"reach_margin"`` or ``"poc_margin"``.
        title: panel title, with units, horizon and scale.
        colorbar_label: colour bar label, with units and scale.
        zero_label: legend label of a zero margin.
        symbol: ``r_T`` or ``mu_T`` (matplotlib mathtext).
        axis_label: the symbol with its units (one-axis maps).
    """

    variable: str
    title: str
    colorbar_label: str
    zero_label: str
    symbol: str
    axis_label: str


def _attr(ds, name: str, key: str):
    value = ds[name].attrs.get(key, ds.attrs.get(key))
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def margin_scale(ds) -> MarginScale | None:
    """The margin variable of ``ds`` and its labels (None without one)."""
    if "reach_margin" in ds:
        units = ds["reach_margin"].attrs.get("units") or "output units"
        horizon = _attr(ds, "reach_margin", "reach_horizon")
        budget = _attr(ds, "reach_margin", "tension_budget")
        within = f" within $T$ = {horizon:.3g} s" if horizon is not None else ""
        title = f"reach margin $r_T$ [{units}]{within} (log scale)"
        if budget is not None:
            title += f"\ntension changes up to ±{budget:.3g} N"
        return MarginScale(
            "reach_margin",
            title,
            f"$r_T$ [{units}], log scale",
            "$r_T$ = 0 (not POC, or $T$ too short)",
            "$r_T$",
            f"$r_T$ [{units}]",
        )
    if "poc_margin" in ds:
        return MarginScale(
            "poc_margin",
            "POC margin $\\mu_T$ (unit-impulse index, unitless; log scale)",
            "$\\mu_T$ (unitless), log scale",
            "$\\mu_T \\leq 0$ (not POC)",
            "$\\mu_T$",
            "$\\mu_T$ (unitless)",
        )
    return None


def _categories() -> list[tuple[str, str]]:
    """(label, colour) of every category index."""
    cats = [
        ("", ZERO_MARGIN_COLOR),  # label from the MarginScale
        ("analysed, no margin computed", NO_MARGIN_COLOR),
        ("not analysed", STATUS_COLORS[STATUS_CODES["no_equilibrium"]]),
    ]
    return cats + [(STATUS_TEXT[s], STATUS_COLORS[s]) for s in _STATUS_ORDER]


def classify(values, status, verdict) -> tuple[np.ndarray, np.ndarray]:
    """Split poses by what their margin says.

    Args:
        values: margins, any shape.
        status: ``status`` codes of the same shape, or None (then a pose is
            not analysed when its verdict is and its margin is NaN).
        verdict: verdict codes of the same shape (used without ``status``).

    Returns:
        ``(positive, category)``: the margin where it is > 0 (NaN elsewhere)
        and the category index of every other pose (:data:`POSITIVE` where
        the margin is positive): :data:`ZERO` for a margin <= 0,
        :data:`NO_MARGIN` for an analysed pose without one, a status
        category for a pose not analysed.
    """
    values = np.asarray(values, dtype=float)
    finite = np.isfinite(values)
    category = np.full(values.shape, POSITIVE, dtype=int)
    if status is not None:
        status = np.asarray(status)
        not_ok = status != STATUS_CODES["ok"]
        category[not_ok] = UNKNOWN
        for k, code in enumerate(_STATUS_ORDER):
            category[status == code] = _FIRST_STATUS + k
    else:
        not_ok = (np.asarray(verdict) == NOT_ANALYSED) & ~finite
        category[not_ok] = UNKNOWN
    ok = ~not_ok
    category[ok & ~finite] = NO_MARGIN
    category[ok & finite & (values <= 0)] = ZERO
    positive = np.where(category == POSITIVE, values, np.nan)
    return positive, category


def category_handles(category: np.ndarray, scale: MarginScale) -> list:
    """Legend patches of the categories present."""
    from matplotlib.patches import Patch

    handles = []
    for k, (label, colour) in enumerate(_categories()):
        if np.any(category == k):
            text = scale.zero_label if k == ZERO else label
            handles.append(Patch(facecolor=colour, edgecolor="0.3", label=text))
    return handles


def _category_cmap():
    from matplotlib.colors import BoundaryNorm, ListedColormap

    colours = [c for _, c in _categories()]
    return ListedColormap(colours), BoundaryNorm(np.arange(len(colours) + 1) - 0.5, len(colours))


#: stragglers: at most this fraction of the positive margins, separated
#: from the others by a gap of at least _STRAGGLER_GAP decades, are clipped
#: to the bottom colour (e.g. round-off values ~1e-15 at singular poses)
_STRAGGLER_FRACTION = 0.02
_STRAGGLER_GAP = 3.0


def log_norm(positive: np.ndarray):
    """LogNorm of the positive margins: vmax the largest, vmin the smallest
    (a decade either side of a single value), unless a few stragglers (at
    most 2 % of them) lie three decades or more below the rest: then vmin
    is just below the rest, the stragglers take the bottom colour, and the
    norm's ``clipped`` attribute says so."""
    from matplotlib.colors import LogNorm

    finite = np.sort(positive[np.isfinite(positive)])
    clipped = False
    if finite.size == 0:
        low, high = 0.1, 10.0
    else:
        low, high = float(finite[0]), float(finite[-1])
        most = int(_STRAGGLER_FRACTION * finite.size)  # most stragglers
        if most >= 1:
            # decades between each of the lowest margins and the next one up
            decades = np.diff(np.log10(finite[: most + 1]))
            gap = int(np.argmax(decades))
            if decades[gap] >= _STRAGGLER_GAP:
                low, clipped = float(finite[gap + 1]) / 1.5, True
        if high <= low * 1.0001:
            low, high = low / 10.0, high * 10.0
    norm = LogNorm(low, high)
    norm.clipped = clipped
    return norm


def colorbar_beside(ax, fig, mappable, scale: MarginScale):
    """The colour bar of the positive margins in a slim axes to the right
    of ``ax`` (a child of ``ax``, so it follows the axes' box and the
    layout makes room for it)."""
    cax = ax.inset_axes([1.04, 0.0, 0.045, 1.0])
    label = scale.colorbar_label
    clipped = getattr(mappable.norm, "clipped", False)
    if clipped:
        label += f" (below {mappable.norm.vmin:.2g} clipped)"
    return fig.colorbar(mappable, cax=cax, label=label, extend="min" if clipped else "neither")


#: title line of a margin panel without margins
NO_MARGIN_NOTE = "not computed: map made with margin=False (cdpm map --no-margin)"


def _note(category: np.ndarray) -> str:
    """:data:`NO_MARGIN_NOTE` when no analysed pose has a margin, else ""."""
    if np.any(category == NO_MARGIN) and not np.any(category == POSITIVE):
        return NO_MARGIN_NOTE
    return ""


def margin_grid(ax, fig, x_edges, y_edges, values, status, verdict, scale: MarginScale):
    """Margin cells over a grid slice.

    Args:
        ax, fig: the axes and figure to draw in.
        x_edges, y_edges: cell edges along the horizontal and vertical
            coordinates, shapes (n0 + 1,), (n1 + 1,).
        values, status, verdict: margins and codes, shape (n0, n1), the
            first index along x.

    Returns:
        A note for the title ("" unless the map has no margins).
    """
    positive, category = classify(values, status, verdict)
    X, Y = np.meshgrid(x_edges, y_edges, indexing="ij")
    norm = log_norm(positive)
    mesh = ax.pcolormesh(
        X,
        Y,
        np.ma.masked_invalid(positive),
        cmap=MARGIN_CMAP,
        norm=norm,
        shading="flat",
        gid="margin",
    )
    cmap, cnorm = _category_cmap()
    category_cells = np.ma.masked_less(category, 0)
    ax.pcolormesh(
        X, Y, category_cells, cmap=cmap, norm=cnorm, shading="flat", gid="margin categories"
    )
    if np.any(category == POSITIVE):
        colorbar_beside(ax, fig, mesh, scale)
    legend_below(ax, category_handles(category, scale), ncol=1)
    return _note(category)


def margin_scatter(ax, fig, x, y, values, status, verdict, scale: MarginScale, size: float):
    """Margins of sampled poses at (x, y), all arrays of shape (N,).
    Returns a note for the title, as :func:`margin_grid`."""
    positive, category = classify(values, status, verdict)
    norm = log_norm(positive)
    cats = _categories()
    for k in np.unique(category[category >= 0]):
        sel = category == k
        ax.scatter(
            x[sel],
            y[sel],
            s=size,
            c=cats[k][1],
            linewidths=0,
            rasterized=True,
            gid="margin categories",
        )
    sel = category == POSITIVE
    points = ax.scatter(
        x[sel],
        y[sel],
        s=size,
        c=positive[sel],
        cmap=MARGIN_CMAP,
        norm=norm,
        linewidths=0,
        rasterized=True,
        gid="margin",
    )
    if np.any(category == POSITIVE):
        colorbar_beside(ax, fig, points, scale)
    legend_below(ax, category_handles(category, scale), ncol=1)
    return _note(category)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in a 1-D mask."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    change = np.flatnonzero(np.diff(padded))
    return list(zip(change[::2], change[1::2] - 1, strict=True))


def margin_line(ax, x, values, status, verdict, scale: MarginScale):
    """The margin over one coordinate (sorted x, shape (N,)) on a log axis:
    a line through the positive margins, red ticks at zero margins along
    the bottom, shaded spans where poses are not analysed (by reason).
    Returns (legend handles, a note for the title as :func:`margin_grid`)."""
    from matplotlib.transforms import blended_transform_factory

    positive, category = classify(values, status, verdict)
    ax.set_yscale("log")
    ax.plot(x, positive, color="0.15", lw=1.4, label=scale.symbol, gid="margin")
    # a value between two gaps draws no line segment: mark it
    finite = np.isfinite(positive)
    padded = np.concatenate([[False], finite, [False]])
    alone = finite & ~padded[:-2] & ~padded[2:]
    ax.plot(x[alone], positive[alone], ".", color="0.15", ms=4)
    norm = log_norm(positive)
    ax.set_ylim(norm.vmin / 1.5, norm.vmax * 1.5)
    edges = cell_edges(x)
    cats = _categories()
    for k in np.unique(category[category > ZERO]):
        for first, last in _runs(category == k):
            ax.axvspan(edges[first], edges[last + 1], color=cats[k][1], lw=0, zorder=0)
    bottom = blended_transform_factory(ax.transData, ax.transAxes)
    zero = category == ZERO
    ax.plot(
        x[zero],
        np.full(zero.sum(), 0.03),
        "|",
        color=ZERO_MARGIN_COLOR,
        ms=12,
        mew=2,
        transform=bottom,
        clip_on=False,
        gid="zero margin",
    )
    ax.set_ylabel(f"{scale.axis_label}, log scale")
    ax.grid(True, which="major", color="0.9", lw=0.6)
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="0.15", lw=1.4, label=f"{scale.symbol} > 0")]
    if zero.any():
        handles.append(
            Line2D(
                [],
                [],
                ls="",
                marker="|",
                ms=10,
                mew=2,
                color=ZERO_MARGIN_COLOR,
                label=scale.zero_label,
            )
        )
    others = [h for h in category_handles(category, scale) if h.get_label() != scale.zero_label]
    return handles + others, _note(category)
