"""Pictures of certified maps (:class:`cdpm.certify.map.CertifiedMap`):
the boxes proven YES (green) and NO (red), the undecided ones hatched grey,
over one or two mapped coordinates, with the volume fractions in the
legend; optionally the YES outline of a sampled map (``cdpm map``) over
them, to compare. A map of more than two coordinates is drawn as the
slice through the base pose over the first two.

Boxes are drawn as polygon collections, filled and outlined in their own
colour: a box thinner than a pixel (the undecided ones along a NO curve)
still shows as a line of its colour.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError
from cdpm.plotting._common import legend_below, matplotlib_parts
from cdpm.plotting.map_plot import check_dpi, check_image_path
from cdpm.verdicts import MARGINAL, NO, VERDICT_COLORS, YES

__all__ = [
    "plot_certified",
    "save_certified_plot",
    "check_sampled",
    "UNDECIDED_COLOR",
    "SAMPLED_OUTLINE_COLOR",
]

#: the fill of undecided boxes (hatched in a darker grey)
UNDECIDED_COLOR = "#d0d0d0"
#: the hatching of undecided boxes
UNDECIDED_HATCH_COLOR = "#555555"
#: the YES outline of a sampled map drawn over the boxes
SAMPLED_OUTLINE_COLOR = "#1f3a93"

#: outline width of a box in its own colour [points]: a box thinner than a
#: pixel still shows
BOX_OUTLINE_PT = 0.6


def _label(cmap: Any, k: int) -> str:
    unit = cmap.units[k] if k < len(cmap.units) else ""
    return f"{cmap.coordinates[k]} [{unit}]" if unit else cmap.coordinates[k]


def _slice(cmap: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """The boxes drawn and their corners over (at most) the first two
    mapped coordinates, and the slice's description ("" for a map of at
    most two coordinates): boxes that hold the base pose's value of every
    further mapped coordinate (clipped into its axis' range)."""
    d = len(cmap.coordinates)
    keep = np.ones(cmap.verdict.size, dtype=bool)
    where = []
    if d > 2:
        for k in range(2, d):
            e = cmap.edges[k]
            value = _base_value(cmap, k)
            value = float(np.clip(value, e[0], e[-1]))
            keep &= (cmap.lower[:, k] <= value) & (value <= cmap.upper[:, k])
            unit = cmap.units[k] if k < len(cmap.units) else ""
            where.append(f"{cmap.coordinates[k]} = {value:.3g}{' ' + unit if unit else ''}")
    rows = np.flatnonzero(keep)
    lo, hi = cmap.lower[rows, : min(d, 2)], cmap.upper[rows, : min(d, 2)]
    text = f"slice through the base pose at {', '.join(where)}" if where else ""
    return rows, lo, hi, text


def _base_value(cmap: Any, k: int) -> float:
    """The base pose's value of mapped coordinate k."""
    names = list(cmap.provenance.get("settings", {}).get("coordinates", []))
    if cmap.coordinates[k] in names:
        return float(cmap.base[names.index(cmap.coordinates[k])])
    e = cmap.edges[k]
    return 0.5 * float(e[0] + e[-1])


def _rectangles(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Polygons (n, 4, 2) of boxes over two coordinates (a band of unit
    height over one)."""
    if lo.shape[1] == 1:
        lo = np.concatenate([lo, np.zeros_like(lo)], axis=1)
        hi = np.concatenate([hi, np.ones_like(hi)], axis=1)
    x0, y0, x1, y1 = lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]
    return np.stack(
        [
            np.stack([x0, y0], 1),
            np.stack([x1, y0], 1),
            np.stack([x1, y1], 1),
            np.stack([x0, y1], 1),
        ],
        axis=1,
    )


def plot_certified(
    cmap: Any,
    sampled: Any = None,
    *,
    title: str | None = None,
):
    """Draw a certified map (module docstring); returns the matplotlib Figure.

    Args:
        cmap: a :class:`cdpm.certify.map.CertifiedMap` (or the path of its
            store).
        sampled: a sampled map (the ``xarray.Dataset`` of
            :func:`cdpm.workspace_map`, or its store's path) over the same
            one or two coordinates: the outline of its YES poses is drawn
            over the boxes.
        title: the figure's title (default: the spec and the boxes).

    Raises:
        InputError: ``sampled`` is not a grid over the drawn coordinates.
        MissingExtraError: matplotlib is missing.
    """
    _, Figure = matplotlib_parts("certified map plots")
    # optional: cdpm[maps]
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Patch

    if isinstance(cmap, (str, os.PathLike)):
        # loaded on first use
        from cdpm.certify.map import open_certified

        cmap = open_certified(cmap)
    rows, lo, hi, where = _slice(cmap)
    verdict = cmap.verdict[rows]
    d2 = min(len(cmap.coordinates), 2)
    fig = Figure(figsize=(7.0, 6.4 if d2 == 2 else 3.2), layout="constrained")
    ax = fig.add_subplot()
    polygons = _rectangles(lo, hi)
    styles = {
        YES: {"facecolor": VERDICT_COLORS[YES], "edgecolor": VERDICT_COLORS[YES]},
        NO: {"facecolor": VERDICT_COLORS[NO], "edgecolor": VERDICT_COLORS[NO]},
        MARGINAL: {
            "facecolor": UNDECIDED_COLOR,
            "edgecolor": UNDECIDED_HATCH_COLOR,
            "hatch": "////",
        },
    }
    for code in (YES, MARGINAL, NO):  # the rarer verdicts on top
        pick = verdict == code
        if not pick.any():
            continue
        collection = PolyCollection(
            polygons[pick], linewidths=BOX_OUTLINE_PT, antialiaseds=True, **styles[code]
        )
        ax.add_collection(collection)
    e0 = cmap.edges[0]
    ax.set_xlim(e0[0], e0[-1])
    ax.set_xlabel(_label(cmap, 0))
    if d2 == 2:
        e1 = cmap.edges[1]
        ax.set_ylim(e1[0], e1[-1])
        ax.set_ylabel(_label(cmap, 1))
        ax.set_aspect("auto")
    else:
        ax.set_ylim(0, 1)
        ax.set_yticks([])
    fractions = cmap.fractions()
    handles = [
        Patch(
            facecolor=VERDICT_COLORS[YES],
            edgecolor=VERDICT_COLORS[YES],
            label=f"proven YES ({100 * fractions['yes']:.1f}% of the volume)",
        ),
        Patch(
            facecolor=VERDICT_COLORS[NO],
            edgecolor=VERDICT_COLORS[NO],
            label=f"proven NO ({100 * fractions['no']:.1f}%)",
        ),
        Patch(
            facecolor=UNDECIDED_COLOR,
            edgecolor=UNDECIDED_HATCH_COLOR,
            hatch="////",
            label=f"undecided ({100 * fractions['undecided']:.1f}%)",
        ),
    ]
    if sampled is not None:
        handles.append(_sampled_outline(ax, cmap, sampled, d2))
    legend_below(ax, handles, ncol=2)
    n_regions = int(cmap.regions().max(initial=0))
    spec = cmap.provenance.get("spec")
    name = Path(spec).name if spec else "the robot"
    cells = " x ".join(str(e.size - 1) for e in cmap.edges)
    fig.suptitle(
        title
        or f"certified POC map of {name}: {cells} cells, {cmap.verdict.size} boxes, "
        f"{n_regions} certified region(s)",
        fontsize=10,
    )
    reasons = np.unique(np.asarray(cmap.boxes.reason)[cmap.verdict == MARGINAL])
    if fractions["undecided"] == 1.0 and reasons.size == 1:  # e.g. a robot under load
        where = "\n".join(filter(None, [where, *_wrapped(f"nothing proven: {reasons[0]}")]))
    if where:
        ax.set_title(where, fontsize=9)
    return fig


def _wrapped(text: str, width: int = 90) -> list[str]:
    """``text`` cut into lines of at most about ``width`` characters."""
    # textwrap: loaded on first use
    import textwrap

    return textwrap.wrap(text, width)


def _sampled_outline(ax, cmap: Any, sampled: Any, d2: int):
    """Draw the outline of a sampled map's YES poses; returns its legend handle."""
    # optional: cdpm[maps]
    from matplotlib.lines import Line2D

    if isinstance(sampled, (str, os.PathLike)):
        # loaded on first use
        from cdpm.maps import open_map

        sampled = open_map(sampled)
    names = list(cmap.coordinates[:d2])
    check_sampled(sampled, names)
    # loaded on first use
    from cdpm.maps import VERDICT_CODES

    yes = np.asarray(sampled["poc"].transpose(*names).values) == VERDICT_CODES["yes"]
    x = np.asarray(sampled[names[0]].values, dtype=float)
    label = "sampled map: edge of its YES poses"
    if d2 == 2:
        y = np.asarray(sampled[names[1]].values, dtype=float)
        ax.contour(
            x,
            y,
            yes.T.astype(float),
            levels=[0.5],
            colors=SAMPLED_OUTLINE_COLOR,
            linewidths=1.0,
        )
    else:
        ax.plot(x, 0.5 + 0.4 * (yes.astype(float) - 0.5), color=SAMPLED_OUTLINE_COLOR, lw=1.0)
        label = "sampled map: YES (high) / not YES (low)"
    return Line2D([], [], color=SAMPLED_OUTLINE_COLOR, lw=1.0, label=label)


def check_sampled(sampled: Any, names: list[str]) -> None:
    """Raise an InputError unless ``sampled`` (a sampled map's dataset) is
    a grid over exactly the coordinates ``names`` (those a certified map's
    picture draws)."""
    axes = sampled.attrs.get("axes", [])
    axes = [axes] if isinstance(axes, str) else list(axes)
    grid = sampled.attrs.get("mode") == "grid"
    if not grid or sorted(axes) != sorted(names):
        raise InputError(
            f"the compared map must be a sampled map over a grid of {', '.join(names)} (cdpm "
            f"map --axis ... for each); this one maps {', '.join(axes) or 'nothing'}"
            + ("" if grid else " at random samples")
        )


def save_certified_plot(
    cmap: Any,
    image: str | os.PathLike,
    *,
    sampled: Any = None,
    dpi: float = 150,
    title: str | None = None,
) -> Path:
    """Draw a certified map with :func:`plot_certified` and write it to the
    file ``image`` (format from its extension, PNG without one); returns the
    file written.

    Raises:
        InputError: an image format matplotlib does not write, a bad
            ``dpi`` (both before any drawing), or a ``sampled`` map over
            other coordinates.
    """
    out = check_image_path(image)
    dpi = check_dpi(dpi)
    fig = plot_certified(cmap, sampled, title=title)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    return out
