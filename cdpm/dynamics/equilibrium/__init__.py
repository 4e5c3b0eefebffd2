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

:func:`solve_equilibria` solves many poses at once (the box's least-norm
corner, then a batched semismooth Newton method on the dual, then the exact
QP solver DAQP for the few poses Newton leaves undecided); the per-pose
:func:`equilibrium_tension` is that function on a batch of one, plus the
words that explain its result. Results meet the bounds exactly and the
statics to round-off. A pose no tension in bounds can hold is a result
with ``feasible = False`` and the smallest statics residual reachable
within the bounds, never an exception.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium.methods import (
    DEFAULT_METHOD,
    EQUILIBRIUM_METHODS,
    HOW,
    EquilibriumBatch,
    EquilibriumMethod,
    solve_equilibria,
)
from cdpm.dynamics.equilibrium.qp import closest_in_bounds, min_norm_in_bounds
from cdpm.dynamics.equilibrium.result import (
    PYTHON_OPTIONS,
    EquilibriumResult,
    EquilibriumWarning,
    InfeasibleEquilibriumError,
    NotAnEquilibriumError,
    ZeroPretensionWarning,
)
from cdpm.errors import InputError, float_array, float_scalar
from cdpm.numerics import GIVEN_TENSION_BOUND_RTOL, MAX_TENSION, STATICS_RTOL

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.kinematics import BatchKinematics
    from cdpm.model.robot import CableRobot

__all__ = [
    "EQUILIBRIUM_METHODS",
    "DEFAULT_METHOD",
    "STATICS_RTOL",
    "EquilibriumMethod",
    "EquilibriumBatch",
    "EquilibriumResult",
    "EquilibriumWarning",
    "InfeasibleEquilibriumError",
    "NotAnEquilibriumError",
    "ZeroPretensionWarning",
    "PYTHON_OPTIONS",
    "equilibrium_tension",
    "equilibrium_tensions",
    "check_equilibrium",
    "checked_tensions",
    "given_tensions",
    "onto_bounds",
    "tension_bound_tolerance",
    "solve_equilibria",
    "resolve_method",
    "statics",
]


def resolve_method(robot: CableRobot, method: str | None, pretension: float | None):
    """(method name, pretension [N]) of a request, validated: None takes the
    spec's method and pretension.

    Raises:
        InputError: unknown method, or a negative or non-finite pretension.
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
    return method, checked_pretension(pretension)


def checked_pretension(pretension: Any) -> float:
    """A pretension [N] as a float in [0, MAX_TENSION].

    Raises:
        InputError: not a number, negative, too large or not finite.
    """
    try:
        value = float_scalar(pretension)
    except (TypeError, ValueError) as exc:
        raise InputError(f"pretension must be a number of newtons, got {pretension!r}") from exc
    if not (math.isfinite(value) and 0 <= value <= MAX_TENSION):
        raise InputError(
            f"pretension must be finite, >= 0 and <= {MAX_TENSION:g} N, got {pretension}"
        )
    return value


def statics(robot: CableRobot, kin: BatchKinematics) -> tuple[np.ndarray, np.ndarray]:
    """(L^T (N, nv, m), load = -G - w_ext (N, nv)) of batch kinematics with
    dynamics: what every equilibrium of cdpm balances, in one layout."""
    return np.swapaxes(kin.jacobian, 1, 2), -kin.gravity - robot.external_wrench


def _statics(robot: CableRobot, q: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, L^T (1, nv, m), load (1, nv)) at q, as :func:`statics` on a batch of one."""
    q = robot.kinematics(q).q  # validates q; raises on a zero-length segment
    LT, load = statics(robot, robot.kinematics_batch(q[None], dynamics=True))
    return q, LT, load


def given_tensions(robot: CableRobot, tension: Any) -> np.ndarray:
    """Caller-given tensions [N] as a new float array of shape (m,): one
    finite number of at most MAX_TENSION in magnitude per cable (a scalar
    for a robot of one cable). Bounds are not checked here
    (:func:`checked_tensions` does).

    Raises:
        InputError: not numbers, not one per cable (a list of another
            length, or an array of more than one axis), or entries that are
            not finite or beyond MAX_TENSION.
    """
    m = robot.n_cables
    names = ", ".join(robot.cable_names)
    give = f"give {m} finite tensions [N] of at most {MAX_TENSION:g} N, one per cable ({names})"
    try:
        f = float_array(tension, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(f"tension must be numbers: {exc}; {give}") from exc
    if f.ndim > 1:
        raise InputError(f"tension has shape {f.shape}, expected ({m},): {give}")
    f = f.reshape(-1)
    if f.shape[0] != m:
        entries = "entry" if f.shape[0] == 1 else "entries"
        raise InputError(
            f"tension has {f.shape[0]} {entries}, expected one per cable ({m}: {names}); give "
            f"{m} finite tensions [N] of at most {MAX_TENSION:g} N"
        )
    bad = np.flatnonzero(~(np.abs(f) <= MAX_TENSION))  # nan too
    if bad.size:
        values = ", ".join(f"{robot.cable_names[i]}={f[i]:g}" for i in bad)
        if bad.size == 1:
            what = f"entry {values} is not a finite tension"
        else:
            what = f"entries {values} are not finite tensions"
        raise InputError(f"tension {what} of at most {MAX_TENSION:g} N; {give}")
    return f


def tension_bound_tolerance(f: np.ndarray, force: float) -> float:
    """How far [N] given tensions f (m,) may pass a cable's bound and still
    be on it: GIVEN_TENSION_BOUND_RTOL max(force, max |f|), the round-off of
    tensions at their scale (:data:`cdpm.numerics.GIVEN_TENSION_BOUND_RTOL`;
    ``force``: the robot's force scale [N],
    :attr:`cdpm.model.robot.CableRobot.force_scale`)."""
    largest = float(np.max(np.abs(f), initial=0.0))
    return GIVEN_TENSION_BOUND_RTOL * max(force, largest)


def onto_bounds(
    f: np.ndarray, fmin: np.ndarray, fmax: np.ndarray, force: float
) -> tuple[np.ndarray, np.ndarray]:
    """The one rule for given tensions at the cable bounds: an entry beyond
    its bound by at most :func:`tension_bound_tolerance` is on it.

    Args:
        f: finite tensions [N], shape (m,) (:func:`given_tensions`).
        fmin, fmax: the cable bounds [N], each (m,) (fmax may be inf).
        force: the robot's force scale [N].

    Returns:
        (tensions, beyond): f with the entries within the tolerance of a
        bound put on it (a new array; entries beyond it are left as
        given), and the boolean mask (m,) of entries farther beyond.
    """
    tol = tension_bound_tolerance(f, force)
    beyond = (f < fmin - tol) | (f > fmax + tol)
    return np.where(beyond, f, np.clip(f, fmin, fmax)), beyond


def _beyond_text(robot: CableRobot, f: np.ndarray, beyond: np.ndarray) -> str:
    """``c1=-1 N is 1 N below its tension_min 0 N; ...`` for the entries
    of ``beyond``."""
    parts = []
    for i in np.flatnonzero(beyond):
        low = f[i] < robot.tension_min[i]
        bound = robot.tension_min[i] if low else robot.tension_max[i]
        side, name = ("below", "tension_min") if low else ("above", "tension_max")
        parts.append(
            f"{robot.cable_names[i]}={f[i]:.12g} N is {abs(f[i] - bound):.3g} N {side} its "
            f"{name} {bound:.12g} N"
        )
    return "; ".join(parts)


def checked_tensions(robot: CableRobot, tension: Any) -> np.ndarray:
    """Caller-given equilibrium tensions [N], checked against the cable
    bounds by the one rule of cdpm (:func:`cdpm.linearise`,
    :func:`cdpm.evaluate_poses`, maps): an entry beyond its bound by at most
    :func:`tension_bound_tolerance` (round-off) is on the bound and put
    there; farther beyond is an error. The statics are not checked here.

    Returns:
        The tensions, a new float array (m,), within the bounds.

    Raises:
        InputError: as :func:`given_tensions`, or an entry beyond its bound
            by more than the tolerance (the message names the cable, its
            bound and the fix).
    """
    f = given_tensions(robot, tension)
    clipped, beyond = onto_bounds(f, robot.tension_min, robot.tension_max, robot.force_scale)
    if beyond.any():
        raise InputError(
            f"tension outside the cable bounds: {_beyond_text(robot, f, beyond)}; give tensions "
            "within the spec's tension_min/tension_max (a tension within "
            f"{GIVEN_TENSION_BOUND_RTOL:g} x max({robot.force_scale:.3g} N (the robot's force "
            "scale), the largest tension) of a bound counts as on it) or a method name "
            f"({', '.join(EQUILIBRIUM_METHODS)})"
        )
    return clipped


def equilibrium_tensions(
    robot: CableRobot, LT: np.ndarray, load: np.ndarray, method: Any = None, pretension=None
) -> EquilibriumBatch:
    """Equilibrium tensions of many poses: :func:`solve_equilibria` with the
    robot's bounds and the method (or given tensions) resolved as in
    :func:`equilibrium_tension`.

    Args:
        robot: the robot (bounds, spec defaults).
        LT: L^T at each pose, shape (N, nv, m).
        load: -G - w_ext at each pose, shape (N, nv) [N or N m].
        method: None (the spec's), a method name, or tensions [N] (m,).
        pretension: [N]; None takes the spec's.
    """
    if method is not None and not isinstance(method, str):
        # given tensions: round-off beyond a bound is on it (onto_bounds);
        # farther beyond, the batch is infeasible
        fmin, fmax, force = robot.tension_min, robot.tension_max, robot.force_scale
        f, _ = onto_bounds(given_tensions(robot, method), fmin, fmax, force)
        return solve_equilibria(LT, load, fmin, fmax, f, force=force)
    method, pretension = resolve_method(robot, method, pretension)
    return solve_equilibria(
        LT, load, robot.tension_min, robot.tension_max, method, pretension, force=robot.force_scale
    )


def _result(robot: CableRobot, q, load, batch: EquilibriumBatch, message: str) -> EquilibriumResult:
    return EquilibriumResult(
        q=q.copy(),
        tension=batch.tension[0],
        feasible=bool(batch.feasible[0]),
        residual=float(batch.residual[0]),
        method=batch.method,
        pretension=batch.pretension,
        at_lower_bound=batch.at_lower_bound[0],
        at_upper_bound=batch.at_upper_bound[0],
        taut=batch.taut[0],
        load=load,
        message=message,
        cable_names=tuple(robot.cable_names),
        tension_min=robot.tension_min.copy(),
        tension_max=robot.tension_max.copy(),
    )


def check_equilibrium(robot: CableRobot, q: Any, tension: Any) -> EquilibriumResult:
    """Whether given tensions hold the robot at q (method ``given``).

    Tensions beyond a cable's bound by round-off (:func:`onto_bounds`, the
    rule of :func:`checked_tensions`) are on it: the result has them there.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: configuration (nq,), natural coordinates (nv,) or pose name.
        tension: cable tensions [N], shape (m,).

    Returns:
        The :class:`EquilibriumResult`: not feasible (its message naming
        the cables) where a tension lies beyond its bound by more than
        round-off, or where the tensions do not hold the pose.

    Raises:
        InputError: the tension has the wrong length, or entries that are
            not finite or larger than MAX_TENSION in magnitude.
    """
    given = given_tensions(robot, tension)
    force = robot.force_scale
    f, beyond = onto_bounds(given, robot.tension_min, robot.tension_max, force)
    q, LT, load = _statics(robot, q)
    batch = solve_equilibria(LT, load, robot.tension_min, robot.tension_max, f, force=force)
    if beyond.any():
        message = f"the given tensions leave the cable bounds: {_beyond_text(robot, f, beyond)}"
    elif batch.feasible[0]:
        message = "the given tensions hold the pose"
    else:
        message = f"the given tensions do not hold the pose (residual {batch.residual[0]:.3g})"
    return _result(robot, q, load[0], batch, message)


def equilibrium_tension(
    robot: CableRobot,
    q: Any,
    method: str | None = None,
    pretension: float | None = None,
) -> EquilibriumResult:
    """Cable tensions that hold the robot at rest at q.

    Solves ``L(q)^T f = -G(q) - w_ext`` with ``f_min <= f <= f_max`` (module
    docstring: methods ``zero``, ``min_norm``, ``pretension``): the batched
    :func:`solve_equilibria` on one pose.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: configuration (nq,), natural coordinates (nv,) or pose name.
        method: how to choose among the equilibria; None uses the spec's
            ``equilibrium.method`` (``min_norm`` when the spec names none).
        pretension: least tension [N] of every cable for the ``pretension``
            method; None uses the spec's ``equilibrium.pretension``. The
            other methods do not use it. With 0 N the ``pretension`` method
            is ``min_norm``, which a :class:`ZeroPretensionWarning` (an
            :class:`EquilibriumWarning`) points out.

    Returns:
        The :class:`EquilibriumResult`; ``feasible`` is False (with the
        smallest residual reachable within the bounds) when no tension in
        bounds holds the pose.

    Raises:
        InputError: unknown method, or a negative or non-finite pretension.
        ModelError: a cable has zero length at q.
    """
    method, pretension = resolve_method(robot, method, pretension)
    if method == "pretension" and pretension == 0:
        warnings.warn(ZeroPretensionWarning(), stacklevel=2)
    q, LT, load = _statics(robot, q)
    fmin, fmax = robot.tension_min, robot.tension_max
    batch = solve_equilibria(LT, load, fmin, fmax, method, pretension, force=robot.force_scale)
    how = int(batch.how[0])
    if batch.feasible[0]:
        if how == HOW["zero"]:
            message = "zero tension holds the pose (no load to balance)"
        elif how == HOW["box_corner"]:
            lower = batch.tension[0]
            what = "zero tension" if not np.any(lower) else "every cable at its lower bound"
            message = f"{what} holds the pose"
        else:
            n_free = int(np.count_nonzero(~batch.sign_constrained[0]))
            m = robot.n_cables
            message = f"least-norm tension in bounds; {n_free} of {m} cables inside their bounds"
        return _result(robot, q, load[0], batch, message)
    return _infeasible(robot, q, LT[0], load[0], batch, method, pretension)


def _infeasible(robot: CableRobot, q, lt, load, batch, method, pretension) -> EquilibriumResult:
    """The infeasible result: why, and the closest tensions in bounds."""
    fmin, fmax = robot.tension_min, robot.tension_max
    how = int(batch.how[0])
    names = robot.cable_names
    if how == HOW["zero"]:
        if np.any(fmin > 0):
            low = [names[i] for i in np.flatnonzero(fmin > 0)]
            return _result(
                robot,
                q,
                load,
                batch,
                f"zero tension is below the minimum tension of {', '.join(low)}",
            )
        message = f"zero tension leaves the load |G + w_ext| = {batch.residual[0]:.6g} unbalanced"
        return _result(robot, q, load, batch, message)
    lower, upper = EQUILIBRIUM_METHODS[method].box(fmin, fmax, pretension)
    if how == HOW["bound_conflict"]:
        over = [names[i] for i in np.flatnonzero(lower > upper)]
        message = f"pretension {pretension:g} N exceeds the maximum tension of {', '.join(over)}"
        return _result(robot, q, load, batch, message)
    # the exact QP says why (its exit flag), then the closest tensions in bounds
    force = robot.force_scale
    x, why = min_norm_in_bounds(lt, load, lower, upper, force)
    if x is not None:
        residual = float(np.linalg.norm(lt @ x - load))
        why = f"the QP solution misses the statics by {residual:.3g}"
    f = closest_in_bounds(lt, load, lower, upper)
    closest = solve_equilibria(lt[None], load[None], fmin, fmax, f, force=force)
    closest = dataclasses.replace(
        closest, feasible=np.zeros(1, bool), method=method, pretension=batch.pretension
    )
    message = f"{why}; closest tension in bounds leaves residual {closest.residual[0]:.6g}"
    return _result(robot, q, load, closest, message)
