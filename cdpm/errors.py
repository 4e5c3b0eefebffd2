"""Exception tree of cdpm.

Every error cdpm raises on purpose derives from :class:`CdpmError`, so a
caller can catch them all at once; the subclasses also derive from the
matching builtin (``ValueError``, ``FileNotFoundError``) so generic handlers
keep working.
"""

from __future__ import annotations

__all__ = [
    "CdpmError",
    "SpecError",
    "InputError",
    "ModelError",
    "UnsupportedError",
    "MissingExtraError",
]


class CdpmError(Exception):
    """Base class of all errors raised by cdpm."""


class SpecError(CdpmError, ValueError):
    """A cable spec (YAML) or the URDF it names is invalid.

    Args:
        problems: one human-readable line per problem found; the message
            lists them all so a user can fix a spec in one pass.
        path: the spec file the problems were found in, if any.
    """

    def __init__(self, problems: list[str] | str, path: str | None = None):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = list(problems)
        self.path = path
        where = f"{path}: " if path else ""
        if len(self.problems) == 1:
            message = f"{where}{self.problems[0]}"
        else:
            lines = "\n".join(f"  - {p}" for p in self.problems)
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
