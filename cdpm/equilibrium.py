"""Equilibrium cable tensions: which tensions hold the robot still at a pose.

At rest (q' = q'' = 0) the dynamics (seed paper eq 11) reduce to statics::

    L(q)^T f = -G(q) - w_ext,      f_min <= f <= f_max

with L the cable Jacobian (m, nv), G the generalised gravity and w_ext the
spec's constant generalised external force. With more cables than degrees
of freedom many tensions may hold the pose; :func:`equilibrium_tension`
picks one by a named method:

``zero``
    f = 0, feasible only when zero tension holds the pose (no gravity or
    external load there) and every cable allows zero tension (f_min = 0).
    The seed paper's case.
``min_norm``
    The tension of least 2-norm within the bounds: the cables work as
    little as possible, so cables not needed are slack at f_min. Gives
    exactly f = f_min when that holds the pose; in particular f = 0 for the
    paper's model (no gravity, f_min = 0). This is the default.
``pretension``
    The tension of least 2-norm with every cable at least
    ``max(f_min, pretension)``: a pretensioned robot, every cable taut.

The minimum-norm problems are small convex QPs, solved with DAQP (an exact
dual active-set solver); the solver's active set is then polished: cables
on a bound are set exactly to it and the statics are re-solved for the
others in closed form, so the result meets the bounds exactly and the
statics to round-off. A pose no tension in bounds can hold is a result with
``feasible = False`` and the smallest statics residual reachable within the
bounds, never an exception.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cdpm.errors import InputError, MissingExtraError, ModelError
from cdpm.numerics import STATICS_RANK_RTOL, STATICS_RTOL

__all__ = [
    "EQUILIBRIUM_METHODS",
    "DEFAULT_METHOD",
    "STATICS_RTOL",
    "EquilibriumResult",
    "EquilibriumWarning",
    "InfeasibleEquilibriumError",
    "equilibrium_tension",
    "check_equilibrium",
]

#: The equilibrium methods, each a way to choose among the tensions that hold
#: a pose (module docstring). Specs, maps and the command line accept these.
EQUILIBRIUM_METHODS = ("zero", "min_norm", "pretension")

#: Method used when neither the call nor the spec names one.
DEFAULT_METHOD = "min_norm"


class EquilibriumWarning(UserWarning):
    """An equilibrium request that is valid but probably not what was meant
    (e.g. the ``pretension`` method with a pretension of 0 N)."""


class InfeasibleEquilibriumError(ModelError):
    """No tension within the cable bounds holds the robot at the pose.

    The message says what to change, naming the Python arguments by
    default; a command line passes its own spelling of the options.

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
        method_option: str = "tension={!r}",
        pretension_option: str = "pretension={}",
    ):
        self.result = result
        min_norm = method_option.format("min_norm")
        bounds = "wider tension bounds for the cables in the spec"
        if result.method == "zero":
            fix = f"let the cables take the load ({min_norm}), or try another pose"
        elif result.method == "pretension":
            fix = (
                f"try a lower pretension ({pretension_option.format('N')}, now "
                f"{result.pretension:g} N), {min_norm}, another pose or {bounds}"
            )
        else:
            fix = f"try another pose or {bounds}"
        super().__init__(
            f"no equilibrium at this pose with method {result.method!r}: {result.message}. "
            f"To fix: {fix}"
        )


@dataclass(frozen=True)
class EquilibriumResult:
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

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(str(self))}</pre>"


# ---------------------------------------------------------------------------
# statics


def _statics(robot, q: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, L^T (nv, m), load = -G - w_ext (nv,)) at q."""
    kin = robot.kinematics(q)
    q = kin.q
    load = -robot.gravity_torque(q) - robot.external_wrench
    return q, kin.jacobian.T.copy(), load


def _tolerance(lt: np.ndarray, load: np.ndarray, f: np.ndarray) -> float:
    scale = max(1.0, float(np.linalg.norm(load)))
    if f.size and np.all(np.isfinite(f)):
        scale = max(scale, float(np.linalg.norm(lt, 2) * np.linalg.norm(f)))
    return STATICS_RTOL * scale


def _classify(f, fmin, fmax) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    scale = np.maximum(1.0, np.abs(f))
    at_lower = f <= fmin + STATICS_RTOL * scale
    # a cable with f_min = f_max is pinned; it is reported at its lower bound
    at_upper = np.isfinite(fmax) & (f >= fmax - STATICS_RTOL * scale) & ~at_lower
    return at_lower, at_upper, f > 0


def _result(robot, q, f, lt, load, method, pretension, message, feasible=None):
    residual = float(np.linalg.norm(lt @ f - load))
    in_bounds = bool(np.all(f >= robot.tension_min) and np.all(f <= robot.tension_max))
    if feasible is None:
        feasible = in_bounds and residual <= _tolerance(lt, load, f)
    at_lower, at_upper, taut = _classify(f, robot.tension_min, robot.tension_max)
    return EquilibriumResult(
        q=q.copy(),
        tension=f,
        feasible=bool(feasible),
        residual=residual,
        method=method,
        pretension=float(pretension),
        at_lower_bound=at_lower,
        at_upper_bound=at_upper,
        taut=taut,
        load=load,
        message=message,
        cable_names=tuple(robot.cable_names),
        tension_min=robot.tension_min.copy(),
        tension_max=robot.tension_max.copy(),
    )


def check_equilibrium(robot, q: Any, tension: Any) -> EquilibriumResult:
    """Whether given tensions hold the robot at q (method ``given``).

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: configuration (nq,), natural coordinates (nv,) or pose name.
        tension: cable tensions [N], shape (m,).

    Raises:
        InputError: the tension has the wrong length or non-finite entries.
    """
    try:
        f = np.array(tension, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"tension must be a vector of {robot.n_cables} numbers: {exc}") from exc
    if f.shape[0] != robot.n_cables:
        raise InputError(
            f"tension has {f.shape[0]} entries, expected one per cable "
            f"({robot.n_cables}: {', '.join(robot.cable_names)})"
        )
    if not np.all(np.isfinite(f)):
        raise InputError(f"tension has non-finite entries: {f}")
    q, lt, load = _statics(robot, q)
    result = _result(robot, q, f, lt, load, "given", 0.0, "")
    if result.feasible:
        message = "the given tensions hold the pose"
    elif not np.all((f >= robot.tension_min) & (f <= robot.tension_max)):
        message = "the given tensions leave the cable bounds"
    else:
        message = f"the given tensions do not hold the pose (residual {result.residual:.3g})"
    return _with_message(result, message)


def _with_message(result: EquilibriumResult, message: str) -> EquilibriumResult:
    import dataclasses

    return dataclasses.replace(result, message=message)


# ---------------------------------------------------------------------------
# solvers


def _closest_in_bounds(lt, load, lower, upper) -> np.ndarray:
    """Tensions within [lower, upper] minimising |L^T f - load| (BVLS)."""
    from scipy.optimize import lsq_linear

    pinned = lower >= upper
    f = lower.copy()
    free = ~pinned
    if not free.any():
        return f
    rhs = load - lt[:, pinned] @ lower[pinned]
    sol = lsq_linear(lt[:, free], rhs, bounds=(lower[free], upper[free]), method="bvls")
    f[free] = np.clip(sol.x, lower[free], upper[free])
    return f


def _polish(lt, load, lower, upper, x) -> np.ndarray:
    """Fix the cables the solver left on a bound exactly at it and solve the
    statics for the others in least norm (their closed-form optimum)."""
    m = x.shape[0]
    tol = STATICS_RTOL * max(1.0, float(np.max(np.abs(x), initial=0.0)))
    at_lower = x <= lower + tol
    at_upper = np.isfinite(upper) & (x >= upper - tol) & ~at_lower
    f = x.copy()
    for _ in range(m + 1):
        f[at_lower] = lower[at_lower]
        f[at_upper] = upper[at_upper]
        free = ~(at_lower | at_upper)
        if free.any():
            rhs = load - lt[:, ~free] @ f[~free]
            f[free] = np.linalg.lstsq(lt[:, free], rhs, rcond=None)[0]
        low = free & (f < lower)
        high = free & (f > upper)
        if not (low.any() or high.any()):
            return f
        at_lower |= low
        at_upper |= high
    return np.clip(f, lower, upper)  # pragma: no cover - the loop adds a cable each pass


#: What DAQP's negative exit flags mean, in words (DAQP's documentation).
_DAQP_FAILURES = {
    -2: "cycled between working sets",
    -3: "found the problem unbounded",
    -4: "reached its iteration limit",
    -5: "found the problem not convex",
    -6: "started from an overdetermined working set",
}


def _solver_failure(exitflag: int) -> str:
    """Why the least-norm QP gave no tension, in plain words (the solver's
    exit flag kept as a detail)."""
    if exitflag == -1:
        return (
            "no tension within the cable bounds balances the load (the QP solver proved "
            "it infeasible; DAQP exit flag -1)"
        )
    what = _DAQP_FAILURES.get(exitflag, "failed")
    return f"the QP solver stopped without a tension: it {what} (DAQP exit flag {exitflag})"


def _min_norm_in_bounds(lt, load, lower, upper) -> tuple[np.ndarray | None, str]:
    """Least-norm f with L^T f = load and lower <= f <= upper, or None."""
    try:
        import daqp
    except ImportError as exc:  # pragma: no cover - daqp is a core dependency
        raise MissingExtraError(
            "the equilibrium solver needs the 'daqp' package: pip install daqp"
        ) from exc
    from ctypes import c_int

    m = lt.shape[1]
    # Equalities in an orthonormal basis of the row space of L^T, so the QP
    # solver never sees dependent or badly scaled equality rows.
    u, s, vt = np.linalg.svd(lt, full_matrices=False)
    rank = int(np.count_nonzero(s > STATICS_RANK_RTOL * (s[0] if s.size else 0.0)))
    outside = load - u[:, :rank] @ (u[:, :rank].T @ load)
    if np.linalg.norm(outside) > _tolerance(lt, load, np.zeros(0)):
        return None, "the load has a component no cable can balance (L^T lacks rank there)"
    eq_matrix = vt[:rank]
    eq_rhs = (u[:, :rank].T @ load) / s[:rank]
    sense = np.array([0] * m + [5] * rank, dtype=c_int)
    x, _, exitflag, _ = daqp.solve(
        np.eye(m),
        np.zeros(m),
        np.ascontiguousarray(eq_matrix),
        np.concatenate([upper, eq_rhs]),
        np.concatenate([lower, eq_rhs]),
        sense,
    )
    if exitflag < 1:
        return None, _solver_failure(int(exitflag))
    return _polish(lt, load, lower, upper, np.asarray(x, dtype=float)), ""


def equilibrium_tension(
    robot,
    q: Any,
    method: str | None = None,
    pretension: float | None = None,
) -> EquilibriumResult:
    """Cable tensions that hold the robot at rest at q.

    Solves ``L(q)^T f = -G(q) - w_ext`` with ``f_min <= f <= f_max`` (module
    docstring: methods ``zero``, ``min_norm``, ``pretension``).

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: configuration (nq,), natural coordinates (nv,) or pose name.
        method: how to choose among the equilibria; None uses the spec's
            ``equilibrium.method`` (``min_norm`` when the spec names none).
        pretension: least tension [N] of every cable for the ``pretension``
            method; None uses the spec's ``equilibrium.pretension``. The
            other methods do not use it. With 0 N the ``pretension`` method
            is ``min_norm``, which an :class:`EquilibriumWarning` points out.

    Returns:
        The :class:`EquilibriumResult`; ``feasible`` is False (with the
        smallest residual reachable within the bounds) when no tension in
        bounds holds the pose.

    Raises:
        InputError: unknown method, or a negative or non-finite pretension.
        ModelError: a cable has zero length at q.
    """
    spec = robot.spec
    if method is None:
        method = getattr(spec, "equilibrium_method", None) or DEFAULT_METHOD
    if method not in EQUILIBRIUM_METHODS:
        raise InputError(
            f"unknown equilibrium method {method!r}; use one of {', '.join(EQUILIBRIUM_METHODS)}"
        )
    if pretension is None:
        pretension = float(getattr(spec, "pretension", 0.0) or 0.0)
    try:
        pretension = float(pretension)
    except (TypeError, ValueError) as exc:
        raise InputError(f"pretension must be a number of newtons, got {pretension!r}") from exc
    if not (math.isfinite(pretension) and pretension >= 0):
        raise InputError(f"pretension must be finite and >= 0 N, got {pretension}")
    if method == "pretension" and pretension == 0:
        import warnings

        warnings.warn(
            "the 'pretension' method with a pretension of 0 N is the 'min_norm' method "
            "(cables the load does not need stay slack); give a pretension > 0 N "
            "(pretension=N or the spec's equilibrium.pretension) to keep every cable taut",
            EquilibriumWarning,
            stacklevel=2,
        )

    q, lt, load = _statics(robot, q)
    fmin, fmax = robot.tension_min.copy(), robot.tension_max.copy()
    m = robot.n_cables

    if method == "zero":
        f = np.zeros(m)
        result = _result(robot, q, f, lt, load, method, 0.0, "")
        if np.any(fmin > 0):
            names = [robot.cable_names[i] for i in np.flatnonzero(fmin > 0)]
            message = f"zero tension is below the minimum tension of {', '.join(names)}"
            return _with_message(_result(robot, q, f, lt, load, method, 0.0, "", False), message)
        if result.feasible:
            return _with_message(result, "zero tension holds the pose (no load to balance)")
        return _with_message(
            result,
            f"zero tension leaves the load |G + w_ext| = {result.residual:.6g} unbalanced",
        )

    lower = fmin if method == "min_norm" else np.maximum(fmin, pretension)
    if np.any(lower > fmax):
        names = [robot.cable_names[i] for i in np.flatnonzero(lower > fmax)]
        f = np.minimum(lower, fmax)
        message = f"pretension {pretension:g} N exceeds the maximum tension of {', '.join(names)}"
        return _with_message(_result(robot, q, f, lt, load, method, pretension, "", False), message)

    # f = lower is the least-norm point of the box: the answer whenever it
    # holds the pose (exactly f = 0 without load when f_min = 0).
    result = _result(robot, q, lower.copy(), lt, load, method, pretension, "")
    if result.feasible:
        what = "zero tension" if not np.any(lower) else "every cable at its lower bound"
        return _with_message(result, f"{what} holds the pose")

    f, why = _min_norm_in_bounds(lt, load, lower, fmax)
    if f is not None:
        result = _result(robot, q, f, lt, load, method, pretension, "")
        if result.feasible:
            n_taut = int(np.count_nonzero(result.free))
            return _with_message(
                result,
                f"least-norm tension in bounds; {n_taut} of {m} cables inside their bounds",
            )
        why = f"the QP solution misses the statics by {result.residual:.3g}"
    f = _closest_in_bounds(lt, load, lower, fmax)
    result = _result(robot, q, f, lt, load, method, pretension, "", False)
    return _with_message(
        result, f"{why}; closest tension in bounds leaves residual {result.residual:.6g}"
    )
