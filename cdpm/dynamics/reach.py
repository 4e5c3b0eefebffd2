"""The reach margin of a robot's poses: horizon, tension budget, bounds.

The reach margin r_T (:mod:`cdpm.analysis.reach`; docs/analysis.md) needs
three things a linear system does not carry: the horizon T, one for a whole
map so that margins compare across poses; the input box, which for a cable
is its tension deviation from equilibrium within its bounds,
``[f_min - f*, f_max - f*]``; and, for cables without an upper bound, a
tension budget: how much harder (or softer, down to its lower bound) than at
equilibrium such a cable may pull.

Defaults derive from the model (:func:`reach_settings`): with m the
robot's mass, g the gravity's magnitude and l its size (the largest
distance between two cable route points at the spec's first named pose),
the acceleration scale is ``a = max(g, 1 m/s^2)``, the budget
``F = m a`` (the robot's weight under gravity) and the horizon
``T = sqrt(2 (l / 10) / a)``: the time in which the budget's acceleration
moves the robot by a tenth of its size (a linearisation is a local model),
each to 3 significant digits. Where a mode of the linearisation at the
robot's reference pose (the spec's first named pose, as for l) grows fast,
so that e^{Re(lambda) T} would exceed REACH_DEFAULT_GROWTH, the default T
is shortened to the time in which it grows by that much (rounded down to 3
digits; :attr:`ReachSettings.shortened_from` keeps the first value), so
that r_T resolves there (a mode growing by more than REACH_GROWTH_MAX
within T leaves it NaN, "not resolvable"). A horizon the user gives is
kept as given.

Units: r_T is a radius in output space, in the outputs' common unit
(:func:`reach_unit`): metres for positions and lengths, radians for
rotations and revolute joints. When the outputs mix metres and radians
(a pose output x, y, z, rx, ry, rz) the ball is taken with one metre
counted as one radian ("m and rad, one to one"); a spec that wants another
exchange rate scales its outputs with a weighted sum (docs/outputs.md).
"""

from __future__ import annotations

import math
import warnings
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.errors import CdpmError, positive_number, round_down
from cdpm.numerics import (
    MAX_TENSION_BUDGET,
    MAX_TIME_SPAN,
    REACH_DEFAULT_GROWTH,
    REACH_MIN_ACCELERATION,
    REACH_SIZE_FRACTION,
    REACH_ZERO_RTOL,
)

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.linearisation import Linearisation, LinearisationBatch
    from cdpm.model.robot import CableRobot

__all__ = [
    "ReachSettings",
    "reach_settings",
    "reach_bounds",
    "reach_margins_at",
    "reach_unit",
]


@dataclass(frozen=True)
class ReachSettings:
    """Horizon and tension budget of the reach margin.

    Attributes:
        horizon: T [s], one for every pose.
        tension_budget: largest tension change [N] (up or down, within
            f >= f_min) of a cable without an upper bound.
        horizon_default: T is the model's default (not set by the user).
        budget_default: the budget is the model's default.
        budget_used: some cable has no upper bound (else the budget plays
            no part).
        shortened_from: the model's default T [s] before it was shortened
            for a fast-growing mode (module docstring), else None.
        growth_rate: that mode's rate Re(lambda) [1/s] at ``growth_pose``
            (when shortened), else None.
        growth_pose: the reference pose whose mode shortened T, else None.
    """

    horizon: float
    tension_budget: float
    horizon_default: bool = True
    budget_default: bool = True
    budget_used: bool = True
    shortened_from: float | None = None
    growth_rate: float | None = None
    growth_pose: str | None = None

    def describe(self) -> str:
        """One line: ``T = 0.775 s (model default); tension changes ...``;
        the budget is left out when every cable has an upper bound (it then
        plays no part). A default T shortened for a fast-growing mode says
        so: ``T = 0.0402 s (model default, shortened from 0.143 s: ...)``."""
        T = "model default" if self.horizon_default else "set"
        if self.horizon_default and self.shortened_from is not None:
            T += (
                f", shortened from {self.shortened_from:.3g} s: within it a mode of pose "
                f"{self.growth_pose!r} (Re lambda = {self.growth_rate:.3g} 1/s) grows by at "
                f"most {REACH_DEFAULT_GROWTH:g}, so that r_T resolves"
            )
        F = "model default" if self.budget_default else "set"
        text = f"T = {self.horizon:.3g} s ({T}); tension changes within the cables' bounds"
        if not self.budget_used:
            return text
        return text + (f", +-{self.tension_budget:.3g} N for cables without an upper bound ({F})")

    def as_dict(self) -> dict:
        return {
            "horizon": self.horizon,
            "tension_budget": self.tension_budget,
            "horizon_default": self.horizon_default,
            "budget_default": self.budget_default,
            "horizon_shortened_from": self.shortened_from,
        }


def _positive(name: str, value: Any, unit: str, largest: float) -> float:
    text = value.strip() if isinstance(value, str) else value
    message = f"{name} must be a positive number of at most {largest:g} {unit}, got {text!r}"
    return positive_number(value, message, largest)


def reach_settings(
    robot: CableRobot, horizon: Any = None, tension_budget: Any = None
) -> ReachSettings:
    """The reach margin's horizon and tension budget: given, or the model's
    defaults (module docstring).

    Args:
        robot: the robot.
        horizon: T [s] (> 0), or None for the default.
        tension_budget: [N] (> 0), or None for the default.

    Raises:
        InputError: a value that is not a positive finite number.
    """
    if isinstance(horizon, ReachSettings):
        return horizon
    T = F = None
    if horizon is not None:
        T = _positive("the reach horizon", horizon, "s", MAX_TIME_SPAN)
    if tension_budget is not None:
        F = _positive("the tension budget", tension_budget, "N", MAX_TENSION_BUDGET)
    shortened: dict[str, Any] = {}
    if T is None or F is None:
        T0, F0 = _model_scales(robot)[:2]
        F = F0 if F is None else F
        if T is None:
            T = T0
            rate, pose = _reference_growth(robot)
            if rate > 0 and rate * T0 > math.log(REACH_DEFAULT_GROWTH):
                T = round_down(math.log(REACH_DEFAULT_GROWTH) / rate, 3)
                shortened = {"shortened_from": T0, "growth_rate": rate, "growth_pose": pose}
    unbounded = bool(np.any(~np.isfinite(robot.tension_max)))
    return ReachSettings(
        float(T), float(F), horizon is None, tension_budget is None, unbounded, **shortened
    )


#: robot -> (rate, pose) of :func:`_reference_growth` (one linearisation per robot)
_GROWTH: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _reference_growth(robot: CableRobot) -> tuple[float, str | None]:
    """(Re(lambda) [1/s] of the fastest-growing mode, 0 when none grows;
    the pose's name) of the linearisation at the robot's reference pose:
    the spec's first named pose (None, rate 0, without one or where that
    pose has no equilibrium: the default horizon then stays as derived)."""
    if robot in _GROWTH:
        return _GROWTH[robot]
    found: tuple[float, str | None] = (0.0, None)
    if robot.poses:
        # pinocchio: loaded on first use
        from cdpm.dynamics.linearisation import linearise

        pose = next(iter(robot.poses))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the pose's own analysis warns
                A = linearise(robot, pose).A
        except CdpmError:
            A = None
        if A is not None and A.size and np.all(np.isfinite(A)):
            found = (max(float(np.linalg.eigvals(A).real.max()), 0.0), pose)
    _GROWTH[robot] = found
    return found


def _model_scales(robot: CableRobot) -> tuple[float, float, float, float]:
    """(default horizon [s], default budget [N], size l [m], mass m [kg])
    of the robot (mass 1 kg if the model has none)."""
    mass = robot.mass
    g = float(np.linalg.norm(robot.gravity))
    a = max(g, REACH_MIN_ACCELERATION)
    size = robot.size
    T = _round3(math.sqrt(2 * REACH_SIZE_FRACTION * size / a))
    # the budget is the robot's force scale (its weight, or mass times a)
    return (T, _round3(robot.force_scale), size, mass if mass > 0 else 1.0)


def _round3(x: float) -> float:
    return float(f"{x:.3g}")


def reach_bounds(
    robot: CableRobot, tension: np.ndarray, tension_budget: float
) -> tuple[np.ndarray, np.ndarray]:
    """The input box of the reach margin: tension changes from the
    equilibrium ``tension`` (N, m) [N] within the cables' bounds,
    ``[f_min - f*, f_max - f*]``; a cable without an upper bound gets the
    budget F both ways, ``[max(f_min - f*, -F), F]`` (so that margins
    compare across poses: what a change of F does, not what releasing the
    huge tension of a near-singular pose does).

    Returns:
        (lower, upper), each (N, m) [N], ``lower <= 0 <= upper`` (clipped
        there: a tension a round-off outside its bounds counts as on it).
    """
    fmin, fmax = robot.tension_min, robot.tension_max
    bounded = np.isfinite(fmax)
    lower = np.where(bounded, fmin - tension, np.maximum(fmin - tension, -tension_budget))
    upper = np.where(bounded, fmax - tension, tension_budget)
    return np.minimum(lower, 0.0), np.maximum(upper, 0.0)


def reach_unit(output_units: Any) -> str:
    """The unit of r_T, a radius in output space, from the outputs' units:
    their common unit (``"m"``, ``"rad"``, or a spec's ``unit:``), else
    e.g. ``"m and rad, one to one"`` (a metre counted as a radian; an output
    whose terms mix both, unit ``"mixed"``, counts as both)."""
    found = {u for unit in output_units for u in (("m", "rad") if unit == "mixed" else (unit,))}
    others = [u for u in dict.fromkeys(output_units) if u in found and u not in ("m", "rad")]
    units = [u for u in ("m", "rad") if u in found] + others
    if len(units) == 1:
        return units[0]
    if not units:
        return "m"
    return f"{' and '.join(units)}, one to one"


def reach_scale(robot: CableRobot, settings: ReachSettings) -> float:
    """The scale of r_T [its unit, :func:`reach_unit`]: ``(F / m) T^2 / 2``
    [m], how far the budget's force moves the robot's mass from rest in T
    (the defaults make it a tenth of the robot's size), for outputs in
    metres; for outputs in radians that distance divided by the robot's
    size l [m] (the angle it turns a body of size l by). With several
    outputs, the least of their scales (:attr:`CableRobot.output_scales` divided by
    l, times the metre scale), so that a round-off floor taken from it is
    below every output's real motion."""
    mass = _model_scales(robot)[3]
    metres = settings.tension_budget / mass * settings.horizon**2 / 2
    scales = robot.output_scales
    if not scales.size:
        return metres
    return metres * (float(scales.min()) / robot.size)


def reach_margins_at(
    robot: CableRobot,
    lin: LinearisationBatch | Linearisation,
    settings: ReachSettings | None = None,
    verdict_no: Any = None,
):
    """r_T of the linearisations ``lin`` of N poses, at their tensions f*.

    Args:
        robot: the robot.
        lin: a :class:`~cdpm.dynamics.linearisation.LinearisationBatch`, or one
            :class:`~cdpm.dynamics.linearisation.Linearisation` (N = 1).
        settings: horizon and budget; default the model's.
        verdict_no: (N,) bool, True where the POC verdict is NO: a certified
            direction that no input ever reaches, so r_T = 0 there exactly
            (the quadrature would leave round-off).

    Values below REACH_ZERO_RTOL times :func:`reach_scale` (in the
    outputs' unit: metres, or radians through the robot's size) are
    round-off (e.g. a folded arm whose output Jacobian is round-off) and
    read 0.

    Returns:
        :class:`cdpm.analysis.reach.ReachMargins` (value [the outputs' unit,
        :func:`reach_unit`],
        error bound, intervals), each (N,).
    """
    # scipy: loaded on first use
    from cdpm.analysis.reach import ReachMargins, reach_margins

    settings = reach_settings(robot, settings)
    A, B, C, f = lin.A, lin.B, lin.C, np.asarray(lin.tension, dtype=float)
    if A.ndim == 2:
        A, B, C, f = A[None], B[None], C[None], f[None]
    lower, upper = reach_bounds(robot, f, settings.tension_budget)
    k = A.shape[0]
    no = np.zeros(k, dtype=bool) if verdict_no is None else np.asarray(verdict_no, dtype=bool)
    # NO poses: r_T = 0 exactly, with no quadrature (whose zonotope may have
    # many more outputs than the state has dimensions)
    value, error, intervals = np.zeros(k), np.zeros(k), np.ones(k, dtype=int)
    todo = np.flatnonzero(~no)
    if todo.size:
        r = reach_margins(A[todo], B[todo], C[todo], lower[todo], upper[todo], settings.horizon)
        value[todo], error[todo], intervals[todo] = r.value, r.error, r.intervals
    zero = value < REACH_ZERO_RTOL * reach_scale(robot, settings)
    # a value read as 0 widens its error bound by itself
    error = np.where(zero & (value > 0), error + value, error)
    return ReachMargins(np.where(zero, 0.0, value), error, intervals)
