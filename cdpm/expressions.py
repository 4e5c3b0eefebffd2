"""Numbers as users type them: ``pi/6``, ``-2*pi/3``, ``1e-3``, ``.inf``.

Specs, the CLI and configuration mappings all read numbers through
:func:`parse_number`. The text is parsed with :mod:`ast` and only numeric
literals, the constants ``pi``, ``e`` and ``inf`` and ``+ - * / **`` are
allowed; nothing is evaluated as Python. This module imports nothing from
cdpm, so any layer may use it.
"""

from __future__ import annotations

import ast
import math
import operator
from typing import Any

__all__ = ["parse_number"]

_BINARY_OPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_UNARY_OPS = {ast.UAdd: operator.pos, ast.USub: operator.neg}
_CONSTANTS = {"pi": math.pi, "inf": math.inf, "e": math.e}


def parse_number(value: Any) -> float:
    """Turn a YAML scalar into a float.

    Accepts numbers and strings of plain arithmetic on numbers and the
    constants ``pi``, ``e`` and ``inf`` (``"pi/6"``, ``"-2*pi/3"``, ``"1e-3"``).
    Nothing is evaluated as Python: the string is parsed and only numeric
    literals, those constants and ``+ - * / **`` are allowed.

    Raises:
        ValueError: the value is not a number or such an expression.
    """
    if isinstance(value, bool):
        raise ValueError(f"{value!r} is a boolean, expected a number")
    if isinstance(value, (int, float)):
        return float(value)
    if not isinstance(value, str):
        raise ValueError(f"{value!r} is not a number")
    text = value.strip()
    if text.lower() in (".inf", "+.inf"):
        return math.inf
    if text.lower() == "-.inf":
        return -math.inf
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise ValueError(f"{value!r} is not a number or arithmetic expression") from exc
    try:
        return float(_eval_node(tree.body))
    except ZeroDivisionError as exc:
        raise ValueError(f"{value!r} divides by zero") from exc
    except (ValueError, OverflowError) as exc:
        raise ValueError(f"{value!r} is not a number ({exc})") from exc


def _eval_node(node: ast.AST) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
        if isinstance(node.value, bool):
            raise ValueError("booleans are not numbers")
        return node.value
    if isinstance(node, ast.Name) and node.id in _CONSTANTS:
        return _CONSTANTS[node.id]
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY_OPS:
        # floats throughout: 9**9**9 overflows at once instead of growing an integer
        left, right = float(_eval_node(node.left)), float(_eval_node(node.right))
        return _BINARY_OPS[type(node.op)](left, right)
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY_OPS:
        return _UNARY_OPS[type(node.op)](_eval_node(node.operand))
    raise ValueError(
        f"only numbers, pi, e, inf and + - * / ** are allowed (found {ast.unparse(node)!r})"
    )
