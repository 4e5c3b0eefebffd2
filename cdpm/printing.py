"""How results are written for people and programs: the shared vocabulary
of cdpm's text, JSON and notebook cells.

- :func:`packed_lines`: a list of named values, as many to a line as fit.
- :func:`round_to_scale`, :func:`largest_magnitude`, :func:`named_values`,
  :func:`matrix_text`: numbers printed to the scale they stand next to.
- :func:`to_plain`: numpy data (nested in dicts, lists) as plain Python.
- :func:`strict` and :func:`json_text`: strict JSON (NaN and inf as null).
- :class:`TextRepr`: a notebook cell that shows a result's ``str`` as is.

No cdpm imports: every layer, the analysis included, writes through these.
"""

from __future__ import annotations

import enum
import html
import json
import math
from typing import Any

import numpy as np

__all__ = [
    "LIST_LINE_WIDTH",
    "packed_lines",
    "round_to_scale",
    "largest_magnitude",
    "matrix_text",
    "named_values",
    "to_plain",
    "strict",
    "json_text",
    "TextRepr",
    "html_table",
]

#: longest line of a list of named values in a printout [characters]
LIST_LINE_WIDTH = 100
#: significant digits of the largest entry of a printed matrix, and the
#: fewest decimals of every entry
MATRIX_DIGITS = 5
MATRIX_DECIMALS = 4
#: widest printed matrix row [characters]; a wider matrix wraps at 100
MATRIX_WIDTH = 200
#: significant digits of printed values (coordinates, outputs, tensions)
VALUE_DIGITS = 6


def packed_lines(head: str, items: list[str], indent: str = "    ") -> list[str]:
    """``head`` and then ``items`` (each kept whole: ``q1_dot 0.012
    rad/s``), separated by commas, as many to a line as fit in
    LIST_LINE_WIDTH; further lines start with ``indent``."""
    lines, first = [head], True
    for item in items:
        if not first and len(lines[-1]) + len(item) + 2 > LIST_LINE_WIDTH:
            lines[-1] += ","
            lines.append(indent + item)
        else:
            lines[-1] += (" " if first else ", ") + item
        first = False
    return lines


# Printed numbers are rounded relative to the scale they are printed with: an
# entry of a matrix to the matrix's largest entry, an output [m] to the
# robot's size, a tension to the largest tension. Round-off such as
# tip_x = 1.2e-16 next to a 2 m arm then prints as 0, not as a number that
# looks like information.


def round_to_scale(values: Any, scale: float, digits: int = VALUE_DIGITS) -> np.ndarray:
    """``values`` with every entry below half the last digit of ``scale``
    printed at ``digits`` significant digits set to 0 (and no -0.0).

    Args:
        values: numbers, any shape.
        scale: the size they are printed next to (e.g. the largest of
            them); 0 or not finite leaves them unchanged.
        digits: significant digits of ``scale`` in print.

    Returns:
        A new float array (the input is not modified).
    """
    arr = np.array(values, dtype=float)
    if np.isfinite(scale) and scale > 0:
        last = 0.5 * 10.0 ** (math.floor(math.log10(scale)) - digits + 1)
        arr[np.abs(arr) < last] = 0.0
    return arr + 0.0


def largest_magnitude(values: Any) -> float:
    """The largest finite |value| (0 when none): the scale values print at."""
    arr = np.abs(np.asarray(values, dtype=float))
    arr = arr[np.isfinite(arr)]
    return float(arr.max()) if arr.size else 0.0


def matrix_text(M: Any, digits: int = MATRIX_DIGITS) -> str:
    """A matrix in numpy's layout, every entry to the same decimals: at least
    MATRIX_DECIMALS, more when needed for ``digits`` significant digits of
    the largest entry (entries below the last printed decimal print as 0,
    never as -0); a row that fits in MATRIX_WIDTH characters is not
    wrapped."""
    M = np.asarray(M, dtype=float)
    scale = largest_magnitude(M)
    decimals = MATRIX_DECIMALS
    if scale > 0:
        decimals = max(decimals, digits - 1 - math.floor(math.log10(scale)))
    M = np.where(np.abs(M) < 0.5 * 10.0**-decimals, 0.0, M) + 0.0
    options = {"precision": decimals, "suppress_small": True}
    text = np.array2string(M, max_line_width=10**6, **options)
    if max(map(len, text.splitlines()), default=0) > MATRIX_WIDTH:
        text = np.array2string(M, max_line_width=100, **options)
    return text


def named_values(names: Any, values: Any, scale: float | None = None) -> str:
    """``"a = 1, b = 0"``: each value to VALUE_DIGITS significant digits,
    rounded relative to ``scale`` (default: the largest |value|)."""
    values = np.asarray(values, dtype=float).reshape(-1)
    scale = largest_magnitude(values) if scale is None else scale
    rounded = round_to_scale(values, scale)
    return ", ".join(f"{n} = {v:.{VALUE_DIGITS}g}" for n, v in zip(names, rounded, strict=True))


def to_plain(x: Any) -> Any:
    """Numpy data (arrays, scalars; nested in dicts, lists and tuples), enums
    and complex numbers as plain Python (lists, bool, int, float, str keys),
    for JSON. Non-finite floats stay: :func:`strict` turns them into None."""
    if isinstance(x, dict):
        return {str(k): to_plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return to_plain(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, enum.Enum):
        return x.value
    if isinstance(x, complex):
        return [x.real, x.imag]
    return x


def strict(value: Any) -> Any:
    """``value`` as plain Python (:func:`to_plain`) with every non-finite
    float (NaN, inf) replaced by None, through dicts, lists and tuples:
    JSON has no NaN. A negative zero is written 0.0 (``-0.0`` in a margin
    reads as a sign that is not there)."""
    return _finite_or_none(to_plain(value))


def _finite_or_none(value: Any) -> Any:
    """Plain data (:func:`to_plain`'s) with NaN and inf as None, -0.0 as 0.0."""
    if isinstance(value, float):
        return value + 0.0 if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_or_none(v) for v in value]
    return value


def json_text(value: Any, indent: int | None = 2) -> str:
    """Strict JSON of ``value`` (:func:`strict`: non-finite numbers as
    null), indented by ``indent`` spaces (None: one line)."""
    return json.dumps(strict(value), indent=indent, allow_nan=False)


class TextRepr:
    """Mixin: a notebook shows the result's ``str`` as preformatted text."""

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(str(self))}</pre>"


def html_table(title: str, rows: list[tuple[str, str]]) -> str:
    """Minimal HTML for a notebook cell: a title and a two-column table of
    (name, value) rows."""
    body = "".join(
        f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
        f"<td style='text-align:left'><code>{html.escape(v)}</code></td></tr>"
        for k, v in rows
    )
    return f"<div><b>{html.escape(title)}</b><table>{body}</table></div>"
