"""Shared pieces of the map pictures: matplotlib import, labels, colours,
cell edges and legends placed outside the data.

Private to :mod:`cdpm.plotting`.
"""

from __future__ import annotations

import numpy as np

from cdpm.errors import MissingExtraError
from cdpm.verdicts import (
    MARGINAL,
    NO,
    NOT_ANALYSED,
    STATUS_CODES,
    STATUS_LABELS,
    VERDICT_CODES,
    VERDICT_COLORS,
    VERDICT_LABELS,
    VERDICT_ORDER,
    YES,
)

#: legends list yes, no, marginal, not analysed (the order of VERDICT_CODES)
LEGEND_ORDER = tuple(VERDICT_CODES.values())
#: scatter plots draw poses not analysed first (they carry no verdict), then
#: the rarer verdicts on top: where poses fall on one point (a map of more
#: coordinates than the panel shows), it is grey only if none was analysed,
#: and red if any is NO
DRAW_ORDER = (NOT_ANALYSED, YES, MARGINAL, NO)

#: panel titles of the verdict variables
VERDICT_TITLES = {
    "poc": "POC verdict",
    "wrench_closure": "wrench closure verdict",
    "positive_controllable": "positive controllability verdict (Brammer)",
    "output_controllable": "output controllability verdict",
    "static_feasible": "static feasibility verdict",
    "poc_some_tension": "POC for some feasible tension",
}

#: status code -> colour of a pose that was not analysed, by reason; greys
#: and sand, none of them in the margin colour map or the zero-margin red
STATUS_COLORS = {
    STATUS_CODES["pending"]: "#ffffff",
    STATUS_CODES["zero_length_cable"]: "#d9c48f",
    STATUS_CODES["singular_mass_matrix"]: "#8f8f8f",
    STATUS_CODES["no_equilibrium"]: "#cfcfcf",
    STATUS_CODES["analysis_failed"]: "#555555",
}
STATUS_TEXT = {
    **{code: f"not analysed: {label}" for code, label in STATUS_LABELS.items()},
    STATUS_CODES["pending"]: "not computed yet",
}

#: a zero margin (not POC, or the horizon too short): red, outside the colour map
ZERO_MARGIN_COLOR = "#e0312b"
#: a pose analysed without a margin (r_T not resolvable in double precision,
#: docs/analysis.md): pink, apart from the greys, the red and the colour map
#: (a lighter pink was hard to tell from the greys)
NO_MARGIN_COLOR = "#e377c2"
#: sequential colour map of positive margins (dark = small)
MARGIN_CMAP = "viridis"

#: vertical gap between an axes' bottom and a legend below it [points]:
#: room for the tick labels and the axis label
BELOW_AXES_PT = 40.0


def matplotlib_parts(what: str = "plots", extra: str = "maps"):
    """``(matplotlib, Figure)``: cdpm's one import of matplotlib (the Agg
    canvas only: no GUI backend). Raises MissingExtraError naming ``what``
    needs it and the ``extra`` that installs it."""
    try:
        # optional: cdpm[viz/maps]
        import matplotlib
        from matplotlib.figure import Figure
    except ImportError as exc:
        if extra == "maps":
            message = f"{what} need matplotlib: pip install 'cdpm[maps]'"
        else:
            message = (
                f'{what} need matplotlib ({exc}); install it with: pip install "cdpm[{extra}]"'
            )
        raise MissingExtraError(message) from exc
    return matplotlib, Figure


def coordinate_label(ds, name: str) -> str:
    """``"q1 [rad]"``: a coordinate's name and units (from its attributes)."""
    units = ds[name].attrs.get("units") if name in ds.variables else None
    return f"{name} [{units}]" if units else name


#: a coordinate value within this fraction of its axis' largest magnitude
#: of 0 is written 0 (a grid from -5 pi/6 by pi/6 steps has 4.4e-16 for 0)
ROUNDOFF = 1e-12


def clean_value(ds, name: str, value: float) -> float:
    """``value`` of the coordinate ``name``, 0.0 when it is round-off of 0
    (within ROUNDOFF of the axis' largest magnitude)."""
    if name in ds.variables:
        values = np.asarray(ds[name].values, dtype=float)
        if values.size and abs(value) <= ROUNDOFF * float(np.max(np.abs(values))):
            return 0.0
    return float(value) + 0.0


def coordinate_value(ds, name: str, value: float) -> str:
    """``"q3 = 0.5 rad"``: a coordinate value with its units."""
    units = ds[name].attrs.get("units") if name in ds.variables else None
    return f"{name} = {clean_value(ds, name, value):.3g}" + (f" {units}" if units else "")


def verdict_title(variable: str) -> str:
    """Panel title of a verdict variable, in words."""
    return VERDICT_TITLES.get(variable, variable.replace("_", " ") + " verdict")


def cell_edges(x: np.ndarray) -> np.ndarray:
    """Edges of cells centred on monotonic values x (half-way between
    neighbours), shape (n + 1,)."""
    x = np.asarray(x, dtype=float)
    if x.size == 1:
        half = 0.5 * max(abs(float(x[0])), 1.0)
        return np.array([x[0] - half, x[0] + half])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.concatenate([[2 * x[0] - mid[0]], mid, [2 * x[-1] - mid[-1]]])


def verdict_cmap():
    """Colour map and norm of verdict indices (:func:`verdict_index`)."""
    # optional: cdpm[viz/maps]
    from matplotlib.colors import BoundaryNorm, ListedColormap

    cmap = ListedColormap([VERDICT_COLORS[c] for c in VERDICT_ORDER])
    norm = BoundaryNorm(np.arange(len(VERDICT_ORDER) + 1) - 0.5, len(VERDICT_ORDER))
    return cmap, norm


def verdict_index(codes: np.ndarray) -> np.ndarray:
    """Verdict codes -> index into :data:`VERDICT_ORDER` (same shape)."""
    index = np.zeros(np.shape(codes), dtype=int)
    for k, c in enumerate(VERDICT_ORDER):
        index[np.asarray(codes) == c] = k
    return index


def verdict_handles(codes: np.ndarray) -> list:
    """Legend patches of the verdicts present in ``codes``."""
    # optional: cdpm[viz/maps]
    from matplotlib.patches import Patch

    return [
        Patch(facecolor=VERDICT_COLORS[c], edgecolor="0.3", label=VERDICT_LABELS[c])
        for c in LEGEND_ORDER
        if np.any(np.asarray(codes) == c)
    ]


def legend_below(ax, handles: list, *, ncol: int = 2, title: str | None = None):
    """A legend below ``ax``, under its tick labels and axis label, so that
    it never covers a pose. Returns the legend (None without handles)."""
    if not handles:
        return None
    # optional: cdpm[viz/maps]
    from matplotlib.transforms import offset_copy

    below = offset_copy(ax.transAxes, fig=ax.figure, y=-BELOW_AXES_PT, units="points")
    return ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, 0.0),
        bbox_transform=below,
        ncol=min(ncol, len(handles)),
        fontsize=8,
        title=title,
        title_fontsize=8,
        frameon=False,
        handlelength=1.4,
        columnspacing=1.0,
        borderaxespad=0.0,
    )


def halo(width: float = 2.5):
    """Path effects drawing a white outline under lines and text."""
    # optional: cdpm[viz/maps]
    from matplotlib import patheffects

    return [patheffects.withStroke(linewidth=width, foreground="white")]
