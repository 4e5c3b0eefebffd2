"""Equilibrium results and their errors and warnings.

The errors and warnings say what to change, naming the Python arguments
(``tension=``, ``pretension=``) by default. A command line shows its own
options instead: each has ``spelled(...)``, which returns the same error or
warning with the options spelled as given (format strings, see
:class:`InfeasibleEquilibriumError`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cdpm.errors import InputError, ModelError
from cdpm.numerics import ROUNDED_RESIDUAL_RTOL, STATICS_RTOL
from cdpm.printing import TextRepr

__all__ = [
    "EquilibriumResult",
    "EquilibriumWarning",
    "ZeroPretensionWarning",
    "InfeasibleEquilibriumError",
    "NotAnEquilibriumError",
    "PYTHON_OPTIONS",
]

#: how messages name the arguments that fix a problem, in the Python API:
#: ``method_option`` takes a method name, ``pretension_option`` a
#: placeholder, ``omit_option`` is the words for "no tension given"
PYTHON_OPTIONS: dict[str, str] = {
    "method_option": "tension={!r}",
    "pretension_option": "pretension={}",
    "omit_option": "omit the tension (tension=None)",
}


class EquilibriumWarning(UserWarning):
    """An equilibrium request that is valid but probably not what was meant
    (e.g. the ``pretension`` method with a pretension of 0 N)."""

    def spelled(self, **options: str) -> EquilibriumWarning:
        """This warning with the arguments spelled as ``options`` (keys of
        :data:`PYTHON_OPTIONS`); a plain warning names none, so it is
        returned unchanged."""
        return self


class ZeroPretensionWarning(EquilibriumWarning):
    """The ``pretension`` method with a pretension of 0 N: it is the
    ``min_norm`` method.

    Args:
        pretension_option: how to spell "set the pretension", a format
            string taking a placeholder (default ``"pretension={}"``).
    """

    def __init__(self, pretension_option: str = PYTHON_OPTIONS["pretension_option"]):
        self.pretension_option = pretension_option
        super().__init__(
            "the 'pretension' method with a pretension of 0 N is the 'min_norm' method "
            "(cables the load does not need stay slack); give a pretension > 0 N "
            f"({pretension_option.format('N')} or the spec's equilibrium.pretension) to "
            "keep every cable taut"
        )

    def spelled(self, **options: str) -> ZeroPretensionWarning:
        return ZeroPretensionWarning(
            options.get("pretension_option", PYTHON_OPTIONS["pretension_option"])
        )


class InfeasibleEquilibriumError(ModelError):
    """No tension within the cable bounds holds the robot at the pose.

    The message says what to change, naming the Python arguments by
    default; a command line passes its own spelling of the options (or
    calls :meth:`spelled`).

    Args:
        result: the infeasible :class:`EquilibriumResult`.
        method_option: how to spell "use this tension method", a format
            string taking the method name (default ``"tension={!r}"``, the
            argument of :func:`cdpm.linearise` and :func:`cdpm.analyze_pose`).
        pretension_option: how to spell "use this pretension", a format
            string taking a placeholder (default ``"pretension={}"``).

    Attributes:
        result: the :class:`EquilibriumResult` (``feasible`` False, with the
            smallest statics residual reachable within the bounds).
    """

    def __init__(
        self,
        result: EquilibriumResult,
        *,
        method_option: str = PYTHON_OPTIONS["method_option"],
        pretension_option: str = PYTHON_OPTIONS["pretension_option"],
    ):
        self.result = result
        super().__init__(
            f"no equilibrium at this pose with method {result.method!r}: {result.message}. "
            f"To fix: {infeasible_fix(result, method_option, pretension_option)}"
        )

    def spelled(self, **options: str) -> InfeasibleEquilibriumError:
        """The same error with the options spelled as given (keys of
        :data:`PYTHON_OPTIONS`; others are ignored)."""
        return InfeasibleEquilibriumError(
            self.result,
            method_option=options.get("method_option", PYTHON_OPTIONS["method_option"]),
            pretension_option=options.get("pretension_option", PYTHON_OPTIONS["pretension_option"]),
        )


def infeasible_fix(
    result: EquilibriumResult,
    method_option: str = PYTHON_OPTIONS["method_option"],
    pretension_option: str = PYTHON_OPTIONS["pretension_option"],
) -> str:
    """What to change when ``result`` is infeasible, in the given spelling
    of the options (see :class:`InfeasibleEquilibriumError`)."""
    min_norm = method_option.format("min_norm")
    bounds = "wider tension bounds for the cables in the spec"
    if result.method == "zero":
        return f"let the cables take the load ({min_norm}), or try another pose"
    if result.method == "pretension":
        return (
            f"try a lower pretension ({pretension_option.format('N')}, now "
            f"{result.pretension:g} N), {min_norm}, another pose or {bounds}"
        )
    return f"try another pose or {bounds}"


class NotAnEquilibriumError(InputError):
    """Given tensions that are within the cable bounds but do not hold the
    robot at the pose.

    Args:
        result: the :class:`EquilibriumResult` of the given tensions
            (method ``given``, ``feasible`` False, with their residual).
        methods: the method names to suggest.
        method_option: how to spell "use this tension method" (as for
            :class:`InfeasibleEquilibriumError`).
        omit_option: the words for "give no tension" (default
            ``"omit the tension (tension=None)"``).

    Attributes:
        result: the :class:`EquilibriumResult` of the given tensions.
    """

    def __init__(
        self,
        result: EquilibriumResult,
        methods: tuple[str, ...] = ("zero", "min_norm", "pretension"),
        *,
        method_option: str = PYTHON_OPTIONS["method_option"],
        omit_option: str = PYTHON_OPTIONS["omit_option"],
    ):
        self.result = result
        self.methods = tuple(methods)
        named = ", ".join(method_option.format(m) for m in self.methods)
        # the statics' own scale without the robot: the load or the tensions
        scale = max(float(np.linalg.norm(result.load)), float(np.max(np.abs(result.tension))))
        near = result.residual <= ROUNDED_RESIDUAL_RTOL * scale
        hint = (
            f"; the statics hold to a relative {STATICS_RTOL:g}, which tensions copied from "
            "printed output or held in float32 miss by round-off: give them to full "
            "precision (cdpm analyze --json prints it)"
            if near
            else ""
        )
        super().__init__(
            "the given tension is not an equilibrium at this pose: statics residual "
            f"|L^T f + G + w_ext| = {result.residual:.6g} (N or N m){hint}; let cdpm compute "
            f"one: {omit_option} or name a method ({named})"
        )

    def spelled(self, **options: str) -> NotAnEquilibriumError:
        """The same error with the options spelled as given (keys of
        :data:`PYTHON_OPTIONS`; others are ignored)."""
        return NotAnEquilibriumError(
            self.result,
            self.methods,
            method_option=options.get("method_option", PYTHON_OPTIONS["method_option"]),
            omit_option=options.get("omit_option", PYTHON_OPTIONS["omit_option"]),
        )


@dataclass(frozen=True)
class EquilibriumResult(TextRepr):
    """Equilibrium tensions at one pose.

    Attributes:
        q: configuration vector, shape (nq,).
        tension: cable tensions f [N], shape (m,). When infeasible: the
            tensions within bounds that come closest to holding the pose.
        feasible: True when the tensions hold the pose within the bounds.
        residual: statics residual ``|L^T f + G + w_ext|`` [N or N m].
        method: ``zero``, ``min_norm``, ``pretension`` or ``given``.
        pretension: lower tension the ``pretension`` method enforced [N].
        at_lower_bound: cables at their minimum tension f_min (slack when
            f_min = 0): their tension can only increase, shape (m,).
        at_upper_bound: cables at their maximum tension: their tension can
            only decrease, shape (m,).
        taut: cables with strictly positive tension, shape (m,).
        load: the generalised force the cables must balance,
            ``-G(q) - w_ext``, shape (nv,).
        message: one line on how the tensions were found or why none exist.
        cable_names: the cable names, length m.
        tension_min, tension_max: the cable bounds used [N], each (m,).
    """

    q: np.ndarray
    tension: np.ndarray
    feasible: bool
    residual: float
    method: str
    pretension: float
    at_lower_bound: np.ndarray
    at_upper_bound: np.ndarray
    taut: np.ndarray
    load: np.ndarray
    message: str
    cable_names: tuple[str, ...] = ()
    tension_min: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tension_max: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __bool__(self) -> bool:
        return bool(self.feasible)

    @property
    def free(self) -> np.ndarray:
        """Cables strictly inside their bounds: their tension can move both
        ways, so their input is free, shape (m,)."""
        return ~(self.at_lower_bound | self.at_upper_bound)

    def cable_states(self) -> list[str]:
        """One word per cable: ``slack`` (at f_min = 0), ``at min``, ``at max``
        or ``taut`` (strictly inside its bounds)."""
        states = []
        for i in range(self.tension.shape[0]):
            if self.at_upper_bound[i]:
                states.append("at max")
            elif self.at_lower_bound[i]:
                states.append("slack" if self.tension[i] == 0 else "at min")
            else:
                states.append("taut")
        return states

    def as_dict(self) -> dict:
        """JSON-serialisable content."""
        return {
            "method": self.method,
            "feasible": bool(self.feasible),
            "residual": float(self.residual),
            "pretension": float(self.pretension),
            "message": self.message,
            "q": self.q.tolist(),
            "load": self.load.tolist(),
            "cables": [
                {
                    "name": name,
                    "tension": float(f),
                    "state": state,
                    "at_lower_bound": bool(lo),
                    "at_upper_bound": bool(hi),
                    "taut": bool(t),
                }
                for name, f, state, lo, hi, t in zip(
                    self._names(),
                    self.tension,
                    self.cable_states(),
                    self.at_lower_bound,
                    self.at_upper_bound,
                    self.taut,
                    strict=True,
                )
            ],
        }

    def _names(self) -> tuple[str, ...]:
        if len(self.cable_names) == self.tension.shape[0]:
            return self.cable_names
        return tuple(f"cable{i + 1}" for i in range(self.tension.shape[0]))

    def __str__(self) -> str:
        verdict = "feasible" if self.feasible else "INFEASIBLE"
        lines = [
            f"Equilibrium ({self.method}): {verdict}, statics residual {self.residual:.3g}",
            f"  {self.message}",
        ]
        for name, f, state in zip(self._names(), self.tension, self.cable_states(), strict=True):
            lines.append(f"  {name:<12} {f:>12.6g} N  {state}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        """One line: method, feasibility, residual, taut cables (``str`` has the table)."""
        state = "feasible" if self.feasible else "INFEASIBLE"
        taut = int(np.count_nonzero(self.taut))
        return (
            f"<EquilibriumResult ({self.method}): {state}, statics residual "
            f"{self.residual:.3g}, {taut} of {self.tension.shape[0]} cables taut>"
        )

    def _repr_pretty_(self, printer, cycle: bool) -> None:
        """IPython's text of the result: its ``str`` (the notebook's html is too)."""
        printer.text(repr(self) if cycle else str(self))
