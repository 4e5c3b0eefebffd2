"""Exception tree of cdpm.

Every error cdpm raises on purpose derives from :class:`CdpmError`, so a
caller can catch them all at once; the subclasses also derive from the
matching builtin (``ValueError``, ``FileNotFoundError``) so generic handlers
keep working.
"""

from __future__ import annotations

import math
import reprlib

from cdpm.numerics import SPAN_TOL

__all__ = [
    "CdpmError",
    "SpecError",
    "InputError",
    "ModelError",
    "UnsupportedError",
    "MissingExtraError",
    "short_repr",
    "capped_lines",
    "float_array",
    "float_scalar",
    "positive_number",
    "check_tol",
    "MAX_LISTED_PROBLEMS",
    "MAX_PROBLEM_CHARS",
    "MAX_MESSAGE_CHARS",
]

#: problems a message lists before "and N more"
MAX_LISTED_PROBLEMS = 8

#: characters of one problem line before it is cut with "..."
MAX_PROBLEM_CHARS = 400


def short_repr(value, limit: int = 80) -> str:
    """``repr(value)`` cut to about ``limit`` characters (containers
    abbreviated), for messages that quote what a user gave."""

    r = reprlib.Repr()
    r.maxstring = r.maxother = limit
    r.maxlist = r.maxtuple = r.maxdict = r.maxset = 6
    r.maxlevel = 3
    text = r.repr(value)
    return text if len(text) <= limit + 20 else text[: limit + 17] + "..."


def short_str(value, limit: int = 80) -> str:
    """``str(value)`` cut to ``limit`` characters (ending in ``...``), for
    messages that quote a value as the user typed it."""
    text = str(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def capped_lines(lines: list[str]) -> list[str]:
    """The first MAX_LISTED_PROBLEMS lines, each cut to MAX_PROBLEM_CHARS,
    then ``and N more`` when there were more."""
    out = [
        line if len(line) <= MAX_PROBLEM_CHARS else line[: MAX_PROBLEM_CHARS - 3] + "..."
        for line in lines[:MAX_LISTED_PROBLEMS]
    ]
    if len(lines) > MAX_LISTED_PROBLEMS:
        out.append(f"and {len(lines) - MAX_LISTED_PROBLEMS} more")
    return out


def float_array(value, copy: bool = False):
    """``value`` as a float numpy array, as ``np.asarray(value, dtype=float)``
    makes it (``np.array``, a copy, with ``copy``), except that complex
    numbers, booleans and None raise: numpy would drop imaginary parts with
    only a ComplexWarning, read True as 1 and None as nan. The TypeError is
    the one numpy raises for other non-numbers, so a caller's message for
    those (``except (TypeError, ValueError)``) covers these too. Strings
    are read as a single number is (:func:`cdpm.expressions.parse_number`:
    ``["pi/6", "2*pi/3"]``), not only as numpy reads them (``"0.5"``).

    Raises:
        TypeError: complex entries (e.g. ``[0.1j, 0.2]``), booleans, None,
            or other non-numbers as numpy raises for them.
        ValueError: strings that are not numbers, and ragged lists.
    """
    # numpy: loaded on first use (the command line's parser imports this module)
    import numpy as np

    if isinstance(value, _BYTES):  # numpy reads their byte codes as numbers
        raise _not_numbers("bytes", value)
    try:
        arr = np.asarray(value)
    except ValueError as exc:
        if "inhomogeneous" not in str(exc):
            raise
        raise ValueError(
            f"rows of different lengths (a ragged list: {short_repr(value, 60)})"
        ) from None
    except OverflowError:  # a Python integer beyond float64 (10**400)
        raise ValueError(f"a number too large for a float ({short_repr(value, 60)})") from None
    kind = arr.dtype.kind
    hidden = None
    if kind == "S":
        hidden = "bytes"
    elif kind == "O" or (kind in "fiu" and isinstance(value, (list, tuple))):
        # numpy reads [True, 0.5] as [1.0, 0.5]; object arrays hold anything
        hidden = _hidden_non_number([arr] if kind == "O" else value)
    if hidden:
        raise _not_numbers(hidden, value)
    if kind == "c":
        raise TypeError(
            f"complex numbers are not accepted (got {short_repr(value, 60)}); give real numbers"
        )
    if kind == "b":
        raise _not_numbers("booleans", value)
    if kind == "O" and any(x is None for x in arr.reshape(-1)):
        raise TypeError(f"None is not a number (got {short_repr(value, 60)})")
    if kind == "U" or (kind == "O" and any(isinstance(x, str) for x in arr.reshape(-1))):
        # loaded on first use: decimal and ast (the command line's parser imports this module)
        from cdpm.expressions import parse_number

        # numbers beside strings became their repr (exact for floats)
        flat = [parse_number(x) if isinstance(x, str) else x for x in arr.reshape(-1).tolist()]
        return float_array(flat).reshape(arr.shape)
    try:
        return np.array(arr, dtype=float) if copy else np.asarray(arr, dtype=float)
    except OverflowError:  # a Python integer beyond float64 (10**400)
        raise ValueError(f"a number too large for a float ({short_repr(value, 60)})") from None


def _not_numbers(what: str, value) -> TypeError:
    """The error for ``what`` ("booleans", "bytes") given as numbers."""
    fix = "; give str or numbers" if what == "bytes" else ""
    return TypeError(f"{what} are not numbers (got {short_repr(value, 60)}){fix}")


def _hidden_non_number(value: list | tuple) -> str | None:
    """What the nested lists and tuples ``value`` hold that numpy reads
    as numbers but is none (``"booleans"``, also in boolean or object
    arrays, or ``"bytes"``), or None."""
    # numpy: loaded on first use (the command line's parser imports this module)
    import numpy as np

    stack = [value]
    while stack:
        for x in stack.pop():
            kind = type(x)
            if kind is float or kind is int or kind is np.float64:  # the common cases
                continue
            if kind is list or kind is tuple:
                stack.append(x)
            elif kind is bool or kind is np.bool_:
                return "booleans"
            elif isinstance(x, _BYTES):
                return "bytes"
            elif kind is np.ndarray and x.dtype.kind == "b":
                return "booleans"
            elif kind is np.ndarray and x.dtype.kind == "O":
                stack.append(x.reshape(-1).tolist())  # 0-d too
    return None


#: buffers whose bytes numpy would read as numbers
_BYTES = (bytes, bytearray, memoryview)


def float_scalar(value) -> float:
    """One real number as a float: :func:`float_array` of a single value
    (a number, a numeric string or a 0-d array; not a list of one).

    Raises:
        TypeError: complex numbers, lists and arrays (even of one value),
            None and other non-numbers.
        ValueError: strings that are not numbers.
    """
    arr = float_array(value)
    if arr.ndim:
        many = f"{arr.size} values" if arr.size != 1 else "a sequence of one"
        raise TypeError(f"expected one number, got {many} (shape {arr.shape})")
    return float(arr.reshape(-1)[0])


def is_integer(value) -> bool:
    """Whether ``value`` is an integer (Python's or numpy's), not a bool
    (True is no count) nor a float with an integral value."""
    # numpy: loaded on first use (the command line's parser imports this module)
    import numpy as np

    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def round_down(x: float, digits: int = 6) -> float:
    """``x`` > 0 rounded down to ``digits`` significant digits: a bound a
    message names, which the bound's own check then accepts (``:.6g``
    may round it up, past the bound)."""

    if not (math.isfinite(x) and x > 0):
        return x
    step = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    k = math.floor(x / step + 1e-9)  # x / step of an exact k may be just below it
    down = float(f"{k * step:.{digits}g}")  # printed as it reads
    return down if down <= x else float(f"{(k - 1) * step:.{digits}g}")


def checked_seed(seed) -> int:
    """A random seed as an int from 0 to 2**63 - 1 (what
    ``numpy.random.default_rng`` takes), or an InputError."""
    if not (is_integer(seed) and 0 <= seed < 2**63):
        raise InputError(f"seed must be an integer from 0 to 2**63 - 1, got {short_repr(seed)}")
    return int(seed)


def positive_number(
    value, message: str, largest: float = 1.7976931348623157e308, smallest: float = 0.0
) -> float:
    """``value`` (a number, a numpy scalar or an arithmetic string such as
    ``"pi/20"``: :func:`cdpm.expressions.parse_number`) as a float in
    (0, ``largest``] (by default: positive and finite), and at least
    ``smallest``, or an InputError with ``message`` (which names the
    argument, its unit and its range) when it is not one real number in
    that range."""
    # loaded on first use: decimal and ast (the command line's parser imports this module)
    from cdpm.expressions import parse_number

    try:
        x = parse_number(value)
    except ValueError:
        x = float("nan")
    if not (0 < x <= largest and x >= smallest):
        raise InputError(message)
    return x


def check_tol(
    tol, default: float | None = None, kind: str = "an angle", unit: str = " rad"
) -> float:
    """A tolerance as a float in (0, 1), or an InputError: by default the
    span tolerance [rad] (default SPAN_TOL). (Here, not beside the
    analysis, so that a map's worker processes need not import SciPy to
    check it.)"""

    default = SPAN_TOL if default is None else default
    message = f"tol must be {kind} in (0, 1){unit}, got {tol!r} (default {default:g})"
    return positive_number(tol, message, largest=math.nextafter(1.0, 0.0))


#: longest message a cdpm error prints [characters]; the full text stays in
#: ``exc.args[0]``
MAX_MESSAGE_CHARS = 4000


class CdpmError(Exception):
    """Base class of all errors raised by cdpm. Its message is cut to
    MAX_MESSAGE_CHARS characters (quoted user input can be long)."""

    def __str__(self) -> str:
        text = super().__str__()
        if len(text) <= MAX_MESSAGE_CHARS:
            return text
        cut = MAX_MESSAGE_CHARS - 40
        return f"{text[:cut]}... ({len(text) - cut:,} more characters)"


class SpecError(CdpmError, ValueError):
    """A cable spec (YAML) or the URDF it names is invalid.

    Args:
        problems: one human-readable line per problem found; the message
            lists them so a user can fix a spec in one pass (the first
            MAX_LISTED_PROBLEMS, each cut to MAX_PROBLEM_CHARS; ``problems``
            keeps them all).
        path: the spec file the problems were found in, if any.
    """

    def __init__(self, problems: list[str] | str, path: str | None = None):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = list(problems)
        self.path = path
        where = f"{path}: " if path else ""
        listed = capped_lines(self.problems)
        if len(self.problems) == 1:
            message = f"{where}{listed[0]}"
        else:
            lines = "\n".join(f"  - {p}" for p in listed)
            message = f"{where}{len(self.problems)} problems in cable spec:\n{lines}"
        super().__init__(message)


class InputError(CdpmError, ValueError):
    """An argument passed to a cdpm function has the wrong shape or value."""


class ModelError(CdpmError, ValueError):
    """The robot model cannot be evaluated at the requested configuration
    (e.g. a cable of zero length, a singular mass matrix)."""


class UnsupportedError(CdpmError, NotImplementedError):
    """The request is valid but not supported (the message says what is)."""


class MissingExtraError(CdpmError, ImportError):
    """An optional dependency is missing; the message gives the pip command."""
