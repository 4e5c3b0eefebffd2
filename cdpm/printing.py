"""How results are written for people and programs: the shared vocabulary
of cdpm's text, JSON and notebook cells.

- :func:`packed_lines`: a list of named values, as many to a line as fit.
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
    "to_plain",
    "strict",
    "json_text",
    "TextRepr",
    "html_table",
]

#: longest line of a list of named values in a printout [characters]
LIST_LINE_WIDTH = 100


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
    JSON has no NaN."""
    value = to_plain(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: strict(v) for k, v in value.items()}
    if isinstance(value, list):
        return [strict(v) for v in value]
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
