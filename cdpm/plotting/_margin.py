"""The margin panel of a map picture: positive margins on a log colour
scale, zero margins in red, poses without a margin by reason.

A map's headline margin is ``reach_margin`` r_T [output units]: within the
horizon T (dataset attribute ``reach_horizon`` [s]) the cables, with
tension changes within their bounds (up to +-``tension_budget`` [N] for
cables without an upper bound), can move the output r_T in every
direction. Older maps carry only ``poc_margin``, the unit-impulse
index mu_T (unitless); it is drawn the same way and labelled as what it is.

The colour scale spans the positive margins but clips stragglers at either
end by one rule (:func:`margin_range`): a few margins far beyond the 1st or
99th percentile take the end colour, the colour bar gets a triangle at that
end and its label says what was clipped.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from cdpm.plotting._common import (
    MARGIN_CMAP,
    NO_MARGIN_COLOR,
    STATUS_COLORS,
    STATUS_TEXT,
    ZERO_MARGIN_COLOR,
    cell_edges,
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


def _budget_used(ds) -> bool:
    """Some cable of the map has no upper tension bound (so the tension
    budget plays a part in r_T); True when the map does not say."""
    try:
        bounds = json.loads(ds.attrs["cable_tension_bounds"])
        return any(not math.isfinite(float(high)) for _, high in bounds.values())
    except (KeyError, TypeError, ValueError):
        return True


#: the margin drawn beside a verdict other than poc: the tension search's
#: verdict goes with the reach margin at its chosen tension
MARGIN_OF_VERDICT = {"poc_some_tension": "reach_margin_best"}


def margin_scale(ds, verdict: str = "poc") -> MarginScale | None:
    """The margin variable of ``ds`` drawn beside ``verdict``, and its
    labels (None without one)."""
    name = MARGIN_OF_VERDICT.get(verdict, "reach_margin")
    if name in ds:
        units = ds[name].attrs.get("units") or "output units"
        horizon = _attr(ds, "reach_margin", "reach_horizon")
        budget = _attr(ds, "reach_margin", "tension_budget")
        within = f" within $T$ = {horizon:.3g} s" if horizon is not None else ""
        what = "at the chosen tension " if name != "reach_margin" else ""
        # beside another criterion's verdicts: the margin is still POC's
        of = "" if verdict in ("poc", "poc_some_tension") else "POC "
        title = f"{of}reach margin $r_T$ {what}[{units}]{within} (log scale)"
        if budget is not None and _budget_used(ds):
            # bounded cables use their own bounds (docs/analysis.md)
            title += f"\ntension changes up to ±{budget:.3g} N\nfor cables without an upper bound"
        return MarginScale(
            name,
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
        ("analysed, margin not resolvable (NaN)", NO_MARGIN_COLOR),
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
    """Legend patches of the categories present, each with its count of
    poses (a few cells of a large map are easily missed)."""
    # optional: cdpm[viz/maps]
    from matplotlib.patches import Patch

    handles = []
    for k, (label, colour) in enumerate(_categories()):
        n = int(np.count_nonzero(category == k))
        if n:
            text = scale.zero_label if k == ZERO else label
            handles.append(Patch(facecolor=colour, edgecolor="0.3", label=f"{text} ({n})"))
    return handles


def _category_cmap():
    # optional: cdpm[viz/maps]
    from matplotlib.colors import BoundaryNorm, ListedColormap

    colours = [c for _, c in _categories()]
    return ListedColormap(colours), BoundaryNorm(np.arange(len(colours) + 1) - 0.5, len(colours))


#: the bulk of the positive margins runs from this quantile to 1 minus it
#: (the 1st to the 99th percentile): at most this fraction of them is
#: clipped at either end of the colour scale
STRAGGLER_FRACTION = 0.01
#: a margin more than this many decades beyond the bulk (below the 1st
#: percentile / 10 or above the 99th percentile x 10) is a straggler: it
#: takes the end colour of its side and the colour bar says so. Below:
#: round-off values at singular poses; above: poses whose equilibrium needs
#: huge tensions (e.g. 692 m next to a median of 0.12 m on the gravity arm)
STRAGGLER_DECADES = 1.0


@dataclass(frozen=True)
class MarginRange:
    """The colour (or axis) range of the positive margins.

    Attributes:
        low, high: the range [margin units], low < high.
        below, above: how many margins are clipped below ``low`` and above
            ``high`` (stragglers, :data:`STRAGGLER_DECADES`).
    """

    low: float
    high: float
    below: int = 0
    above: int = 0

    def norm(self):
        """``matplotlib.colors.LogNorm`` of the range."""
        # optional: cdpm[viz/maps]
        from matplotlib.colors import LogNorm

        return LogNorm(self.low, self.high)

    @property
    def extend(self) -> str:
        """The colour bar's ``extend``: which ends have clipped values."""
        return {(0, 0): "neither", (1, 0): "min", (0, 1): "max", (1, 1): "both"}[
            (int(self.below > 0), int(self.above > 0))
        ]

    @property
    def clip_note(self) -> str:
        """``"below 0.00081 and above 1.3 clipped"``, or ``""``."""
        parts = [f"below {self.low:.2g}"] * (self.below > 0)
        parts += [f"above {self.high:.2g}"] * (self.above > 0)
        return " and ".join(parts) + " clipped" if parts else ""


def margin_range(positive: np.ndarray) -> MarginRange:
    """The range of the positive margins (NaN ignored): the smallest to the
    largest, but stragglers (more than :data:`STRAGGLER_DECADES` beyond the
    1st or 99th percentile, at most :data:`STRAGGLER_FRACTION` of the
    margins at either end) are clipped: the range ends at the most extreme
    margin that is not one. The rule is the same at both ends. A single
    value gets a decade either side."""
    finite = np.sort(np.asarray(positive, dtype=float)[np.isfinite(positive)])
    if finite.size == 0:
        return MarginRange(0.1, 10.0)
    logs = np.log10(finite)
    most = int(STRAGGLER_FRACTION * finite.size)  # most stragglers at either end
    low_fence, high_fence = np.quantile(logs, [STRAGGLER_FRACTION, 1.0 - STRAGGLER_FRACTION])
    below = int(np.sum(logs < low_fence - STRAGGLER_DECADES))
    above = int(np.sum(logs > high_fence + STRAGGLER_DECADES))
    below = below if below <= most else 0
    above = above if above <= most else 0
    low, high = float(finite[below]), float(finite[finite.size - 1 - above])
    if high <= low * 1.0001:
        return MarginRange(low / 10.0, high * 10.0, below, above)
    return MarginRange(low, high, below, above)


def colorbar_beside(ax, fig, mappable, scale: MarginScale, limits: MarginRange):
    """The colour bar of the positive margins in a slim axes to the right
    of ``ax`` (a child of ``ax``, so it follows the axes' box and the
    layout makes room for it); a clipped end is drawn as a triangle and the
    label says what was clipped."""
    cax = ax.inset_axes([1.04, 0.0, 0.045, 1.0])
    label = scale.colorbar_label
    if limits.clip_note:
        label += f"\n({limits.clip_note})"
    bar = fig.colorbar(mappable, cax=cax, label=label, extend=limits.extend)
    plain_log_ticks(bar.ax.yaxis, limits.low, limits.high)
    return bar


def plain_log_ticks(axis, low: float, high: float) -> None:
    """Over less than a decade, a log axis shows few or no powers of ten:
    label its ticks with plain numbers (1.42, 1.43) instead of 1.42x10^0."""
    if not (0 < low < high < 10 * low):
        return
    # optional: cdpm[viz/maps]
    from matplotlib.ticker import FormatStrFormatter, MaxNLocator

    axis.set_major_locator(MaxNLocator(5))
    axis.set_minor_formatter(FormatStrFormatter(""))
    axis.set_major_formatter(FormatStrFormatter("%.3g"))


def margin_computed(ds, scale: MarginScale) -> bool:
    """Whether the map carries margins: False for a map made with
    ``margin=False`` (``cdpm map --no-margin``: its settings say so) and for
    a map without a single finite margin, unless none of its poses has
    been computed yet (``status`` pending everywhere)."""

    try:
        settings = json.loads(ds.attrs.get("cdpm_settings", "{}"))
    except (TypeError, ValueError):
        settings = {}
    if isinstance(settings, dict) and settings.get("margin") is False:
        return False
    values = np.asarray(ds[scale.variable].values, dtype=float)
    if np.isfinite(values).any():
        return True
    pending = STATUS_CODES["pending"]
    return "status" in ds and bool(np.all(np.asarray(ds["status"].values) == pending))


def margin_grid(ax, fig, x_edges, y_edges, values, status, verdict, scale: MarginScale) -> list:
    """Margin cells over a grid slice, with a colour bar and a legend.

    Args:
        ax, fig: the axes and figure to draw in.
        x_edges, y_edges: cell edges along the horizontal and vertical
            coordinates, shapes (n0 + 1,), (n1 + 1,).
        values, status, verdict: margins and codes, shape (n0, n1), the
            first index along x.

    Returns:
        The legend handles of the categories present (zero margins, poses
        not analysed).
    """
    positive, category = classify(values, status, verdict)
    X, Y = np.meshgrid(x_edges, y_edges, indexing="ij")
    limits = margin_range(positive)
    mesh = ax.pcolormesh(
        X,
        Y,
        np.ma.masked_invalid(positive),
        cmap=MARGIN_CMAP,
        norm=limits.norm(),
        shading="flat",
        gid="margin",
    )
    cmap, cnorm = _category_cmap()
    category_cells = np.ma.masked_less(category, 0)
    ax.pcolormesh(
        X, Y, category_cells, cmap=cmap, norm=cnorm, shading="flat", gid="margin categories"
    )
    if np.any(category == POSITIVE):
        colorbar_beside(ax, fig, mesh, scale, limits)
    return category_handles(category, scale)


def margin_scatter(ax, fig, x, y, values, status, verdict, scale: MarginScale, size: float):
    """Margins of sampled poses at (x, y), all arrays of shape (N,), with a
    colour bar. Returns the legend handles of the categories present."""
    positive, category = classify(values, status, verdict)
    limits = margin_range(positive)
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
        norm=limits.norm(),
        linewidths=0,
        rasterized=True,
        gid="margin",
    )
    if np.any(category == POSITIVE):
        colorbar_beside(ax, fig, points, scale, limits)
    return category_handles(category, scale)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in a 1-D mask."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    change = np.flatnonzero(np.diff(padded))
    return list(zip(change[::2], change[1::2] - 1, strict=True))


def margin_line(ax, x, values, status, verdict, scale: MarginScale) -> list:
    """The margin over one coordinate (sorted x, shape (N,)) on a log axis:
    a line through the positive margins, red ticks at zero margins along
    the bottom, shaded spans where poses are not analysed (by reason). The
    axis spans :func:`margin_range`: stragglers are marked by triangles at
    the top (or bottom) edge. Returns the legend handles."""
    # optional: cdpm[viz/maps]
    from matplotlib.lines import Line2D
    from matplotlib.transforms import blended_transform_factory

    positive, category = classify(values, status, verdict)
    ax.set_yscale("log")
    ax.plot(x, positive, color="0.15", lw=1.4, label=scale.symbol, gid="margin")
    # a value between two gaps draws no line segment: mark it
    finite = np.isfinite(positive)
    padded = np.concatenate([[False], finite, [False]])
    alone = finite & ~padded[:-2] & ~padded[2:]
    ax.plot(x[alone], positive[alone], ".", color="0.15", ms=4)
    limits = margin_range(positive)
    ax.set_ylim(limits.low / 1.5, limits.high * 1.5)
    plain_log_ticks(ax.yaxis, limits.low / 1.5, limits.high * 1.5)
    edges = cell_edges(x)
    cats = _categories()
    for k in np.unique(category[category > ZERO]):
        for first, last in _runs(category == k):
            ax.axvspan(edges[first], edges[last + 1], color=cats[k][1], lw=0, zorder=0)
    edge = blended_transform_factory(ax.transData, ax.transAxes)
    zero = category == ZERO
    ax.plot(
        x[zero],
        np.full(zero.sum(), 0.03),
        "|",
        color=ZERO_MARGIN_COLOR,
        ms=12,
        mew=2,
        transform=edge,
        clip_on=False,
        gid="zero margin",
    )
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
    off_scale = (
        (positive > limits.high, 1.0, "^", f"above {limits.high:.2g}"),
        (positive < limits.low, 0.0, "v", f"below {limits.low:.2g}"),
    )
    for beyond, height, marker, where in off_scale:
        if beyond.any():
            style = {"ls": "", "marker": marker, "ms": 6, "color": "0.15", "clip_on": False}
            ax.plot(
                x[beyond], np.full(beyond.sum(), height), transform=edge, gid="off scale", **style
            )
            label = f"{scale.symbol} {where}: off the scale ({int(beyond.sum())})"
            handles.append(Line2D([], [], label=label, **style))
    ax.set_ylabel(f"{scale.axis_label}, log scale")
    ax.grid(True, which="major", color="0.9", lw=0.6)
    others = [h for h in category_handles(category, scale) if h.get_label() != scale.zero_label]
    return handles + others
