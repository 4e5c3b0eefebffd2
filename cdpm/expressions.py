"""Numbers as users type them: ``pi/6``, ``-2*pi/3``, ``1e-3``, ``.inf``.

Specs, the CLI and configuration mappings all read numbers through
:func:`parse_number`. The text is parsed with :mod:`ast` and only numeric
literals, the constants ``pi``, ``e`` and ``inf`` and ``+ - * / **`` are
allowed; nothing is evaluated as Python. This module imports nothing from
cdpm, so any layer may use it.
"""

from __future__ import annotations

import ast
import decimal
import math
import numbers
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

#: longest expression text [characters]
MAX_EXPRESSION_CHARS = 200

#: deepest nesting of operations in an expression
MAX_EXPRESSION_DEPTH = 50


def parse_number(value: Any) -> float:
    """Turn a YAML scalar (or a real number from Python: numpy scalars and
    0-d arrays, fractions, decimals) into a float.

    Accepts numbers and strings of plain arithmetic on numbers and the
    constants ``pi``, ``e`` and ``inf`` (``"pi/6"``, ``"-2*pi/3"``, ``"1e-3"``).
    Nothing is evaluated as Python: the string is parsed and only numeric
    literals, those constants and ``+ - * / **`` are allowed.

    Raises:
        ValueError: the value is not a number or such an expression.
    """
    if getattr(value, "ndim", None) == 0 and getattr(value, "dtype", None) is not None:
        # numpy scalars and 0-d arrays: their Python value (booleans refused below)
        if value.dtype.kind not in "biuf":
            raise ValueError(f"{str(value)[:40]!r} is not a real number")
        value = value.item()
    if isinstance(value, bool):
        raise ValueError(f"{value!r} is a boolean, not a number")
    if isinstance(value, (numbers.Real, decimal.Decimal)):
        try:
            return float(value)
        except OverflowError:
            raise ValueError(f"{str(value)[:20]}... is too large for a float") from None
    if not isinstance(value, str):
        kind = type(value).__name__
        raise ValueError(
            f"a {kind} is not a number"
            if kind in ("dict", "list")
            else f"{str(value)[:40]!r} is not a number"
        )
    text = value.strip()
    if len(text) > MAX_EXPRESSION_CHARS:
        raise ValueError(
            f"{text[:30]!r}... has {len(text)} characters; an arithmetic expression may "
            f"have at most {MAX_EXPRESSION_CHARS}"
        )
    if text.lower() in (".inf", "+.inf"):
        return math.inf
    if text.lower() == "-.inf":
        return -math.inf
    try:
        tree = ast.parse(text, mode="eval")
    except (SyntaxError, RecursionError, MemoryError) as exc:
        raise ValueError(f"{value!r} is not a number or arithmetic expression") from exc
    try:
        result = _eval_node(tree.body, 0)
    except ZeroDivisionError as exc:
        raise ValueError(f"{value!r} divides by zero") from exc
    except OverflowError:
        raise ValueError(f"{value!r} is too large for a number (beyond 1.8e308)") from None
    except ValueError as exc:
        raise ValueError(f"{value!r} is not a number ({exc})") from exc
    if isinstance(result, complex):
        raise ValueError(f"{value!r} is not a real number (its value is complex)")
    result = float(result)
    if math.isinf(result) and not any(
        isinstance(node, ast.Name) and node.id == "inf" for node in ast.walk(tree)
    ):  # finite numbers past the largest float: 1e400, 1e308 * 10
        raise ValueError(f"{value!r} is too large for a number (beyond 1.8e308)")
    if math.isnan(result):
        raise ValueError(f"{value!r} is not a number (its value is undefined, NaN)")
    return result


def _eval_node(node: ast.AST, depth: int) -> float:
    if depth > MAX_EXPRESSION_DEPTH:
        raise ValueError(f"the expression nests more than {MAX_EXPRESSION_DEPTH} operations deep")
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
        if isinstance(node.value, bool):
            raise ValueError("booleans are not numbers")
        return float(node.value)
    if isinstance(node, ast.Name) and node.id in _CONSTANTS:
        return _CONSTANTS[node.id]
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY_OPS:
        # floats throughout: 9**9**9 overflows at once instead of growing an integer
        left, right = _eval_node(node.left, depth + 1), _eval_node(node.right, depth + 1)
        if isinstance(left, complex) or isinstance(right, complex):
            raise ValueError("the value is complex, not a real number")
        return _BINARY_OPS[type(node.op)](left, right)
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY_OPS:
        return _UNARY_OPS[type(node.op)](_eval_node(node.operand, depth + 1))
    raise ValueError(
        f"only numbers, pi, e, inf and + - * / ** are allowed (found {ast.unparse(node)!r})"
    )
