"""The figure titles of map plots: what the map covers (its poses, the
base pose, the tension), what it overrode of its spec, and what the
picture leaves out (:func:`cdpm.plotting.plot_map`)."""

from __future__ import annotations

import json
import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cdpm.maps.plan import describe_overrides
from cdpm.plotting._common import clean_value, coordinate_value
from cdpm.plotting._margin import MarginScale
from cdpm.plotting._slices import distinct_poses

__all__ = ["map_suptitle", "slices_text"]


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
