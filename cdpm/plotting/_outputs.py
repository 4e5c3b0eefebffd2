"""The output-space panel of a map picture: every pose at its outputs,
coloured by verdict.

What is plotted (:func:`choose_outputs`):

- one output: that output against the map's first coordinate;
- two outputs: the first against the second;
- ``FRAME.x`` / ``FRAME.y`` / ``FRAME.z``: a world coordinate of the first
  output's frame (``output_frame_position``), labelled as a frame position.

Each axis is labelled with the output's name and unit (``y``'s
``output_units``: [m] for positions and lengths, [rad] for rotations and
revolute joints) and, for an output that is not one component of a frame,
its formula (``output_formulas``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpm.errors import InputError
from cdpm.plotting._common import (
    DRAW_ORDER,
    coordinate_label,
    legend_below,
    verdict_handles,
    verdict_title,
)
from cdpm.verdicts import MARGINAL, NO, VERDICT_COLORS, VERDICT_LABELS

#: least marker size [points^2] of NO and MARGINAL poses in the output panel:
#: on a dense map (a 1 pt^2 marker for 14641 poses) they did not show
RARE_VERDICT_MIN_SIZE = 6.0


@dataclass(frozen=True)
class OutputChoice:
    """The quantities of the output-space panel.

    Attributes:
        names: one or two names: outputs of the map or ``FRAME.c``.
        note: what the default left out (e.g. "first 2 of 3 outputs"), or "".
    """

    names: tuple[str, ...]
    note: str = ""


def _output_names(ds) -> list[str]:
    if "y" not in ds or "output" not in ds["y"].dims:
        return []
    return [str(n) for n in ds["output"].values]


def _frame_names(ds) -> list[str]:
    if "output_frame_position" not in ds:
        return []
    frame = ds["output_frame_position"].attrs.get("frame", "frame")
    if not frame:  # no output is drawn at a frame (joints and cables only)
        return []
    return [f"{frame}.{c}" for c in "xyz"]


def _output_unit(ds, name: str) -> str | None:
    """The unit of output ``name``: its entry of ``y``'s ``output_units``,
    else ``y``'s ``units`` (maps made before outputs had their own)."""
    attrs = ds["y"].attrs
    units = attrs.get("output_units")
    outs = _output_names(ds)
    if units is not None and len(units) == len(outs):
        return str(units[outs.index(name)])
    return attrs.get("units")


def _output_formula(ds, name: str) -> str:
    """The formula of output ``name`` (e.g. ``joint elbow``), or "" for one
    component of a frame (its name says what it is)."""
    formulas = ds["y"].attrs.get("output_formulas")
    outs = _output_names(ds)
    if formulas is None or len(formulas) != len(outs):
        return ""
    return str(formulas[outs.index(name)])


def _unit(ds, name: str) -> str | None:
    """The unit of an output or a frame coordinate (``FRAME.c``)."""
    if name in _output_names(ds):
        return _output_unit(ds, name)
    return ds["output_frame_position"].attrs.get("units", "m")


def _varying_outputs(ds, outs: list[str]) -> list[str]:
    """The first two outputs, unless fewer than two of them vary over the
    map: then the two whose values span the widest range (in map order)."""

    y = np.asarray(ds["y"].values, dtype=float).reshape(-1, len(outs))
    with np.errstate(invalid="ignore"):
        span = np.nan_to_num(np.nanmax(y, axis=0) - np.nanmin(y, axis=0)) if y.size else None
    if span is None or (span[:2] > 0).all():
        return outs[:2]
    if np.count_nonzero(span > 0) == 1:  # one varies: it against the map's coordinate
        return [outs[int(np.argmax(span))]]
    best = sorted(np.argsort(-span, kind="stable")[:2])
    return [outs[k] for k in best]


def choose_outputs(ds, outputs) -> OutputChoice | None:
    """The quantities the output-space panel plots.

    Args:
        ds: the map.
        outputs: None for the default (one output: it against the first
            coordinate; two or more: the first two, or the two that vary
            most when one of the first two is constant), else one or two names
            of the map's outputs (the ``output`` coordinate of ``y``) or
            ``FRAME.x|y|z`` for the world position of the first output's
            frame.

    Returns:
        The choice, or None when the map has neither outputs nor frame
        positions (and none were asked for).

    Raises:
        InputError: an unknown name (the message lists the available ones),
            none or more than two names, a name twice.
    """
    outs, frames = _output_names(ds), _frame_names(ds)
    if outputs is None:
        if len(outs) > 2:
            picked = _varying_outputs(ds, outs)
            if picked == outs[:2]:
                return OutputChoice(tuple(picked), f"first 2 of {len(outs)} outputs")
            if len(picked) == 1:
                return OutputChoice(tuple(picked), "the only output that varies")
            return OutputChoice(tuple(picked), f"the 2 of {len(outs)} outputs that vary most")
        if len(outs) == 2:
            return OutputChoice(tuple(outs))
        if outs:
            return OutputChoice((outs[0],))
        return OutputChoice(tuple(frames[:2])) if frames else None
    names = [outputs] if isinstance(outputs, str) else [str(n) for n in outputs]
    available = f"its outputs: {', '.join(outs) or 'none'}"
    if frames:
        available += f" (or the output frame's world position: {', '.join(frames)})"
    if not 1 <= len(names) <= 2:
        raise InputError(
            f"outputs takes one or two names (one is plotted against the first map "
            f"coordinate), got {len(names)}; {available}"
        )
    if len(set(names)) != len(names):
        raise InputError(f"outputs names {names[0]!r} twice; give two different names")
    for name in names:
        if name not in outs and name not in frames:
            raise InputError(f"{name!r} is not an output of this map; {available}")
    return OutputChoice(tuple(names))


def _values(ds, name: str, pose_dims: tuple) -> tuple[np.ndarray, str]:
    """Values (flattened over the poses in the order of ``pose_dims``) and
    axis label of an output or a frame coordinate."""
    if name in _output_names(ds):
        values = ds["y"].sel(output=name).transpose(*pose_dims).values
        units = _output_unit(ds, name)
        formula = _output_formula(ds, name)
        label = f"output {name}" + (f" = {formula}" if formula else "")
        label += f" [{units}]" if units else ""
    else:
        frame, _, component = name.rpartition(".")
        values = ds["output_frame_position"].sel(xyz=component).transpose(*pose_dims).values
        units = ds["output_frame_position"].attrs.get("units", "m")
        label = f"{component} of frame '{frame}' (world) [{units}]"
    return np.asarray(values, dtype=float).reshape(-1), label


def _describe(ds, name: str) -> str:
    """``output tip_x`` or ``world x of frame 'tip'``."""
    if name in _output_names(ds):
        return f"output {name}"
    frame, _, component = name.rpartition(".")
    return f"world {component} of frame '{frame}'"


def output_panel(ax, ds, variable: str, choice: OutputChoice, first_axis: str) -> None:
    """Scatter every pose at the chosen outputs, coloured by ``variable``
    (in DRAW_ORDER: rarer verdicts on top; the title says when poses fall
    on the same points); the legend goes below the axes."""
    verdict = ds[variable]
    codes = np.asarray(verdict.values).reshape(-1)
    y_values, y_label = _values(ds, choice.names[-1], verdict.dims)
    if len(choice.names) == 1:
        x_values = ds[first_axis].broadcast_like(verdict).transpose(*verdict.dims).values
        x_values = np.asarray(x_values, dtype=float).reshape(-1)
        x_label = coordinate_label(ds, first_axis)
        what = f"{_describe(ds, choice.names[0])} against {first_axis}"
    else:
        x_values, x_label = _values(ds, choice.names[0], verdict.dims)
        outs = _output_names(ds)
        if all(n in outs for n in choice.names):
            what = f"outputs {choice.names[0]}, {choice.names[1]}"
        elif not any(n in outs for n in choice.names):
            frame = choice.names[0].rpartition(".")[0]
            components = ", ".join(n.rpartition(".")[2] for n in choice.names)
            what = f"world position ({components}) of frame '{frame}'"
        else:
            what = f"{_describe(ds, choice.names[0])} and {_describe(ds, choice.names[1])}"
    if choice.note:
        what += f" ({choice.note})"
    points = np.unique(np.stack([x_values, y_values], axis=1).round(9), axis=0).shape[0]
    overlap = (
        f";\n{codes.size} poses on {points} points,\nno drawn over yes over not analysed"
        if points < codes.size
        else ""
    )
    size = max(1.0, min(30.0, 12000.0 / max(codes.size, 1)))
    for c in DRAW_ORDER:
        sel = codes == c
        if sel.any():
            ax.scatter(
                x_values[sel],
                y_values[sel],
                s=max(size, RARE_VERDICT_MIN_SIZE) if c in (NO, MARGINAL) else size,
                c=VERDICT_COLORS[int(c)],
                linewidths=0,
                label=VERDICT_LABELS[int(c)],
                rasterized=True,
                gid="outputs",
            )
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    if len(choice.names) == 2 and _unit(ds, choice.names[0]) == _unit(ds, choice.names[1]):
        ax.set_aspect("equal", adjustable="datalim")  # the same unit on both axes
    ax.set_title(f"{what},\ncoloured by {verdict_title(variable)}{overlap}", fontsize=10)
    legend_below(ax, verdict_handles(codes), ncol=4)
