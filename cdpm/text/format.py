"""Text of the pose reports (:mod:`cdpm.text.report`): numbers rounded to the
scale they stand next to, outputs with their units and formulas, the
criteria as a map stores them, the cable table."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from cdpm.numerics import RANK_RTOL
from cdpm.pipeline.criteria import CRITERIA
from cdpm.printing import VALUE_DIGITS, largest_magnitude, named_values, round_to_scale

# ---------------------------------------------------------------- printing
#
# Numbers print rounded to the scale they stand next to (see the printing
# helpers of cdpm.printing); the analysis results' own text is cleaned
# of round-off in the quantities they decide.

#: a decided quantity (a margin, an eigenvalue) below this fraction of its
#: scale is round-off of 0
ROUND_OFF_RTOL = 1e-12

# "margin -1.5e-33": a label followed by one number
_NUMBER = r"-?\d+(?:\.\d*)?(?:e[+-]?\d+)?"


def without_round_off(text: str, scales: dict[str, float]) -> str:
    """``text`` with each number after a label of ``scales`` (e.g.
    ``"margin"``) shown as 0 when it is below ROUND_OFF_RTOL times that
    label's scale."""
    for label, scale in scales.items():
        if not (np.isfinite(scale) and scale > 0):
            continue

        def zero(match: re.Match, scale=scale) -> str:
            small = abs(float(match.group(2))) <= ROUND_OFF_RTOL * scale
            return match.group(1) + ("0" if small else match.group(2))

        text = re.sub(rf"(\b{re.escape(label)} )({_NUMBER})", zero, text)
    return text


# A printed zero with a minus sign: "-0", "-0.000", "-0e+00" (from format
# specs) or numpy's "-0." (followed by padding, "," or "]"), standing alone.
_NEGATIVE_ZERO = re.compile(r"(?<![\w.])-(0(?:\.0*)?(?:e[+-]?\d+)?)(?![\w.])")


def without_negative_zeros(text: str) -> str:
    """``text`` with every printed negative zero shown as zero.

    Values such as -1e-17 print as ``-0`` at a few significant digits (and
    an exact -0.0 always does); the sign carries no information there.
    numpy's ``-0.`` becomes `` 0.`` so matrix columns stay aligned.
    """

    def positive(match: re.Match) -> str:
        zero = match.group(1)
        return (" " if zero == "0." else "") + zero

    return _NEGATIVE_ZERO.sub(positive, text)


def criteria_lines(
    criteria: dict[str, Any],
    output_names=(),
    length_scale: float = 0.0,
    output_units=(),
    criteria_attrs: dict[str, dict] | None = None,
) -> list[str]:
    """One line per criterion: verdict and status codes by name, quantities
    with their units (``criteria_attrs``' units for this robot, else the
    registry's; per-output values with the outputs' names and units;
    arrays rounded to their scale, lengths [m] to at least
    ``length_scale``)."""

    lines = []
    for name, value in criteria.items():
        c = CRITERIA.get(name)
        if c is not None and c.on_request and _all_fill(value, c.fill):
            continue  # not asked for at this pose
        attrs = (criteria_attrs or {}).get(name, {})
        units = attrs.get("units", c.units if c is not None else None)
        if c is not None and c.flags is not None:
            names = {code: key for key, code in c.flags.items()}
            text = f"{names.get(int(value), str(value))} ({int(value)})"
        elif c is not None and _is_nan(c.fill) and _all_fill(value, c.fill):
            text = "not computed (NaN)"  # the map's fill: no value, so no unit
        elif c is not None and c.dims == ("output",) and len(output_names) == np.size(value):
            per_output = attrs.get("output_units") or [units] * len(output_names)
            text = values_with_units(output_names, value, per_output, length_scale)
        else:
            arr = np.asarray(value, dtype=float) + 0.0
            scale = largest_magnitude(arr)
            if units == "m":
                scale = max(scale, length_scale)
            if arr.ndim:
                text = np.array2string(round_to_scale(arr, scale), precision=6, suppress_small=True)
            else:
                text = f"{float(arr):.6g}"
            if units not in (None, "1"):
                text += f" {units}"
        lines.append(f"{name + ':':<24}{text}")
    return lines


def _is_nan(fill) -> bool:
    return isinstance(fill, float) and math.isnan(fill)


def _all_fill(value, fill) -> bool:
    """Every entry of ``value`` is the criterion's fill value (NaN counts)."""
    arr = np.asarray(value)
    if _is_nan(fill):
        return bool(np.all(np.isnan(arr.astype(float))))
    return bool(np.all(arr == fill))


def units_of_outputs(outputs, p: int) -> tuple[str, ...]:
    """Units of the p outputs from their definitions (metres without)."""
    if len(outputs) == p:
        return tuple(out.unit for out in outputs)
    return ("m",) * p


def values_with_units(names, values, units, length_scale: float = 0.0) -> str:
    """``"tip_x = 0.5 m, elbow = 1.0472 rad"``: each value with its unit,
    rounded to the scale of the values of the same unit (at least
    ``length_scale`` for metres, 1 rad for radians: round-off of a zero
    prints as 0)."""
    values = np.asarray(values, dtype=float).reshape(-1) + 0.0
    floors = {"m": length_scale, "rad": 1.0}
    rounded = values.copy()
    for unit in set(units):
        same = np.array([u == unit for u in units], dtype=bool)
        scale = max(largest_magnitude(values[same]), floors.get(unit, 0.0))
        rounded[same] = round_to_scale(values[same], scale)
    parts = []
    for name, value, unit in zip(names, rounded, units, strict=True):
        text = named_values([name], [value], 0.0)
        parts.append(text if unit in (None, "", "1") else f"{text} {unit}")
    return ", ".join(parts)


def labelled(label: str, result: Any) -> str:
    """A result's text under ``label`` (without the result's own name)."""
    text = str(result)
    head, sep, rest = text.partition(": ")
    if sep and head.lower() in label.lower():
        text = rest
    return f"{label}: {text}"


def indent(text: str, prefix: str = "  ") -> str:
    return "\n".join(prefix + line for line in text.splitlines())


def impulse_scale(poc: Any) -> float:
    """The size of the POC result's output curves ``|W C e^{At} b_j s_j|``
    on its margin horizon (the scale of its impulse index); NaN when it
    cannot be evaluated."""
    # scipy: loaded on first use
    from scipy.linalg import expm

    try:
        A, B, C = poc.A, poc.B, poc.C
        if poc.input_scale is not None:
            B = B * poc.input_scale
        if poc.output_weight is not None:
            W = np.asarray(poc.output_weight, dtype=float)
            C = W[:, None] * C if W.ndim == 1 else W @ C
        times = np.linspace(0.0, float(poc.margin_horizon), 5)
        return max(largest_magnitude(C @ expm(A * t) @ B) for t in times)
    except (AttributeError, TypeError, ValueError, np.linalg.LinAlgError):
        return math.nan


def tension_texts(tensions, at_bound) -> list[str]:
    """Each tension [N] as the text tables print it, to VALUE_DIGITS
    significant digits: a cable at one of its bounds rounded to the largest
    tension (round-off of a zero bound prints as 0), a cable strictly inside
    its bounds (taut) to its own digits, so that it never prints as 0
    (``3.5e-09``: a taut cable shown as 0 would contradict its state).

    Args:
        tensions: the cables' tensions [N], shape (m,).
        at_bound: True where the cable is at a tension bound (slack, at its
            least or greatest tension), shape (m,).
    """
    tensions = np.asarray(tensions, dtype=float).reshape(-1)
    rounded = round_to_scale(tensions, largest_magnitude(tensions))
    shown = np.where(np.asarray(at_bound, dtype=bool).reshape(-1), rounded, tensions + 0.0)
    return [f"{f:.{VALUE_DIGITS}g}" for f in shown]


def tension_table(
    names, lengths, tensions, states, last: list[str], last_head: str, at_bound=None
) -> list[str]:
    """The cable table: name, length [m], tension [N] (:func:`tension_texts`:
    a taut cable never as 0), state (``taut`` or a bound, as
    :meth:`~cdpm.dynamics.equilibrium.EquilibriumResult.cable_states`) and a
    last column. ``at_bound`` (m,): the cables at a tension bound (default:
    every cable whose state is not ``taut``)."""
    if at_bound is None:
        at_bound = [state != "taut" for state in states]
    texts = tension_texts(tensions, at_bound)
    lines = [f"  {'name':<12} {'length [m]':>11} {'tension [N]':>12}  {'state':<7} {last_head}"]
    for name, length, f, state, extra in zip(names, lengths, texts, states, last, strict=True):
        lines.append(f"  {name:<12} {length:>11.6f} {f:>12}  {state:<7} {extra}".rstrip())
    return lines


def _rank(matrix: np.ndarray) -> int:
    """Numerical rank: singular values above RANK_RTOL times max(1, the largest)."""
    if matrix.size == 0:
        return 0
    s = np.linalg.svd(np.asarray(matrix, dtype=float), compute_uv=False)
    return int(np.count_nonzero(s > RANK_RTOL * max(1.0, float(s.max()))))


def singular_pose_notes(output_jacobian, cable_jacobian) -> tuple[str, ...]:
    """Whether a pose is singular, in words: one sentence for an output
    Jacobian dy/dq (p, nv) or a cable Jacobian L (m, nv) whose rank drops
    below the most its shape allows (a robot with fewer cables than
    coordinates is not singular at every pose); none at a regular pose.
    ``cdpm analyze`` and the viewer's panel print these."""
    notes = []
    p, nv = np.shape(output_jacobian)
    rank = _rank(np.asarray(output_jacobian))
    if rank < min(p, nv):
        notes.append(
            f"singular pose: the output Jacobian dy/dq has rank {rank} < {_bound(p, 'p', nv)}, "
            "so to first order the outputs cannot move in some direction"
        )
    m = np.shape(cable_jacobian)[0]
    rank = _rank(np.asarray(cable_jacobian))
    if rank < min(m, nv):
        notes.append(
            f"singular pose: the cable Jacobian L has rank {rank} < {_bound(m, 'm', nv)}, "
            "so the cables cannot act on every coordinate"
        )
    return tuple(notes)


def _bound(rows: int, name: str, nv: int) -> str:
    """``p = 1`` or ``nv = 2``: the largest rank of a (rows, nv) matrix, named."""
    return f"{name} = {rows}" if rows <= nv else f"nv = {nv}"


def pose_words(pose_name: str | None) -> str:
    """``"pose 'nominal'"``, or ``"the given q"`` for a pose without a name."""
    return f"pose {pose_name!r}" if pose_name else "the given q"


def pose_head(report: Any, output, output_names, outputs=(), notes=()) -> list[str]:
    """The report's first lines: model, pose, coordinates, the outputs with
    their units, the formula of each output that is not one component of a
    frame (a joint, a cable length, a weighted sum) and ``notes`` (e.g.
    :func:`singular_pose_notes`), one line each."""
    where = pose_words(report.pose_name)
    units = units_of_outputs(outputs, len(output_names))
    values = values_with_units(output_names, output, units, report.length_scale or 0.0)
    lines = [
        f"cdpm report: {report.model_name}, {where}",
        f"  coordinates: {named_values(report.coordinate_names, report.natural)}",
        f"  outputs:     {values or '(none)'}",
    ]
    formulas = [
        f"{out.name} = {out.describe()}"
        for out in outputs
        if not (len(out.terms) == 1 and out.terms[0].weight == 1.0 and out.component)
    ]
    if formulas:
        lines.append(f"  where:       {'; '.join(formulas)}")
    lines += [f"  note:        {note}" for note in notes]
    return [*lines, ""]
