"""A certified map's boxes with a certified path through them
(:func:`save_certified_path_plot`, ``cdpm path --plot`` on a certified map).

The boxes are drawn over the mapped coordinates: proven YES light green,
those of the path's certified region a darker green, proven NO red,
undecided hatched; the path's straight steps in blue (each inside one YES
box), the start a circle and the goal a star.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError
from cdpm.plotting._common import halo, legend_below, matplotlib_parts
from cdpm.plotting.map_plot import check_dpi, check_image_path
from cdpm.verdicts import NO, YES

__all__ = ["plot_certified_path", "save_certified_path_plot"]

#: proven YES boxes outside the path's region
YES_OTHER_COLOR = "#d9f0d3"
#: proven YES boxes of the path's region
YES_REGION_COLOR = "#8fd18a"
#: proven NO boxes
NO_BOX_COLOR = "#e0312b"
#: the path
PATH_COLOR = "#1f4e9c"
#: box outlines
EDGE_COLOR = "#8a8a8a"
#: undecided boxes: fill, hatching and outline, and the outline's width [points]
UNDECIDED_COLOR = "#e6e6e6"
UNDECIDED_EDGE_COLOR = "#4d4d4d"
UNDECIDED_OUTLINE_PT = 0.5


def plot_certified_path(cmap: Any, path: Any = None, *, ends=None, title=None, subtitle=None):
    """The figure: the map's boxes over its two (or one) mapped coordinates
    and the path's steps (``path`` a :class:`~cdpm.regions.certified.CertifiedPath`
    or None).

    Raises:
        InputError: a map over more than two coordinates.
    """
    _, Figure = matplotlib_parts("certified path pictures")
    # optional: cdpm[maps]
    from matplotlib.collections import PolyCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    names = tuple(cmap.coordinates)
    d = len(names)
    if d > 2:
        raise InputError(
            f"the picture draws certified maps over one or two coordinates; this one maps {d} "
            f"({', '.join(names)})"
        )
    lo = np.asarray(cmap.lower, dtype=float)
    hi = np.asarray(cmap.upper, dtype=float)
    if d == 1:  # a strip: the boxes as bars of unit height
        lo = np.column_stack([lo, np.zeros(lo.shape[0])])
        hi = np.column_stack([hi, np.ones(hi.shape[0])])
    verdict = np.asarray(cmap.verdict)
    labels = np.asarray(cmap.regions())
    region = -1 if path is None else int(path.region)
    fig = Figure(figsize=(7.0, 6.6 if d == 2 else 3.2), layout="constrained")
    ax = fig.add_subplot()

    def boxes(mask, **style):
        if not np.any(mask):
            return
        a, b = lo[mask], hi[mask]
        corners = np.stack(
            [
                np.column_stack([a[:, 0], a[:, 1]]),
                np.column_stack([b[:, 0], a[:, 1]]),
                np.column_stack([b[:, 0], b[:, 1]]),
                np.column_stack([a[:, 0], b[:, 1]]),
            ],
            axis=1,
        )
        ax.add_collection(PolyCollection(corners, **style))

    thin = {"edgecolor": EDGE_COLOR, "linewidths": 0.15}
    in_region = (verdict == YES) & (labels == region)
    boxes((verdict == YES) & ~in_region, facecolor=YES_OTHER_COLOR, **thin)
    boxes(in_region, facecolor=YES_REGION_COLOR, **thin)
    boxes(verdict == NO, facecolor=NO_BOX_COLOR, edgecolor=NO_BOX_COLOR, linewidths=0.5)
    undecided = (verdict != YES) & (verdict != NO)
    # outlined in their own grey: a box thinner than a pixel still shows as a line
    boxes(
        undecided,
        facecolor=UNDECIDED_COLOR,
        hatch="////",
        edgecolor=UNDECIDED_EDGE_COLOR,
        linewidths=UNDECIDED_OUTLINE_PT,
    )
    handles = []
    if np.any(in_region):
        handles.append(
            Patch(facecolor=YES_REGION_COLOR, edgecolor=EDGE_COLOR, label=f"YES, region {region}")
        )
    if np.any((verdict == YES) & ~in_region):
        word = "YES, other regions" if region >= 0 else "proven YES"
        handles.append(Patch(facecolor=YES_OTHER_COLOR, edgecolor=EDGE_COLOR, label=word))
    if np.any(verdict == NO):
        handles.append(Patch(facecolor=NO_BOX_COLOR, edgecolor=EDGE_COLOR, label="proven NO"))
    if np.any(undecided):
        handles.append(
            Patch(
                facecolor=UNDECIDED_COLOR,
                hatch="////",
                edgecolor=UNDECIDED_EDGE_COLOR,
                label="undecided",
            )
        )
    if path is not None and path.n_steps:
        # one line per run of steps between seam crossings (a step ends where the next starts)
        cuts = [0, *path.seam_crossings, path.n_steps]
        for a, b in zip(cuts[:-1], cuts[1:], strict=True):
            xy = np.concatenate([path.steps[a:b, 0], path.steps[b - 1 : b, 1]])
            if d == 1:
                xy = np.column_stack([xy[:, 0], np.full(xy.shape[0], 0.5)])
            ax.plot(xy[:, 0], xy[:, 1], color=PATH_COLOR, lw=2.0, path_effects=halo(3.5))
        first, last = path.steps[0, 0], path.steps[-1, 1]
        if d == 1:
            first, last = np.array([first[0], 0.5]), np.array([last[0], 0.5])
        ax.plot(*first, "o", color=PATH_COLOR, ms=8, mec="white", mew=1.2)
        ax.plot(*last, "*", color=PATH_COLOR, ms=14, mec="white", mew=1.0)
        handles.append(Line2D([], [], color=PATH_COLOR, lw=2.0, label="certified path"))
        handles.append(
            Line2D([], [], marker="o", ls="", color=PATH_COLOR, mec="white", label="start")
        )
        handles.append(
            Line2D([], [], marker="*", ls="", ms=11, color=PATH_COLOR, mec="white", label="goal")
        )
    if (path is None or not path.n_steps) and ends is not None:
        # no path (start and goal not connected): where they are
        kinds = zip(ends, ("o", "*"), (8, 14), ("start", "goal"), strict=True)
        for point, marker, size, label in kinds:
            xy = np.asarray(point, dtype=float).reshape(-1)
            if d == 1:
                xy = np.array([xy[0], 0.5])
            ax.plot(*xy[:2], marker, color=PATH_COLOR, ms=size, mec="white", mew=1.2)
            handles.append(
                Line2D(
                    [],
                    [],
                    marker=marker,
                    ls="",
                    ms=size * 0.8,
                    color=PATH_COLOR,
                    mec="white",
                    label=label,
                )
            )
    edges = [np.asarray(e, dtype=float) for e in cmap.edges]
    ax.set_xlim(edges[0][0], edges[0][-1])
    units = tuple(getattr(cmap, "units", ()) or ())
    label = [f"{n} [{u}]" if u else n for n, u in zip(names, units or ("",) * d, strict=True)]
    ax.set_xlabel(label[0])
    if d == 2:
        ax.set_ylim(edges[1][0], edges[1][-1])
        ax.set_ylabel(label[1])
        ax.set_aspect("equal")
    else:
        ax.set_ylim(0, 1)
        ax.set_yticks([])
    legend_below(ax, handles, ncol=3)
    f = cmap.fractions()
    heading = title or (
        f"certified map: {len(verdict)} boxes; proven YES {100 * f['yes']:.1f}%, NO "
        f"{100 * f['no']:.1f}%, undecided {100 * f['undecided']:.1f}% of the volume"
    )
    if path is not None:
        heading += (
            f"\ncertified path in region {region}: {path.n_steps} straight steps, each in one "
            f"YES box; r_T >= {path.min_margin:.3g} {path.margin_unit} along it"
        )
    if subtitle:
        heading += f"\n{subtitle}"
    fig.suptitle(heading, fontsize=9)
    return fig


def save_certified_path_plot(
    cmap: Any,
    image: str | os.PathLike,
    *,
    path: Any = None,
    ends: Any = None,
    dpi: float = 110,
    title: str | None = None,
    subtitle: str | None = None,
) -> Path:
    """Draw :func:`plot_certified_path` into the file ``image`` (format from
    its extension) and return the file written; ``ends``: the start and the
    goal over the mapped coordinates, marked when there is no path."""
    out = check_image_path(image)
    dpi = check_dpi(dpi)
    fig = plot_certified_path(cmap, path, ends=ends, title=title, subtitle=subtitle)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    return out
