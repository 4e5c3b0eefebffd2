"""Pull-only steering: tension profiles that move the nonlinear robot's
output to a target, with every cable inside its bounds at every instant.

:func:`steer` starts at rest at an equilibrium (q*, f*), plans on the
linearisation and corrects on the nonlinear simulation:

1. **Plan.** With piecewise-constant tension changes du_k on K intervals
   of [0, T], the linear state at T is ``x(T) = sum_k Phi^(K-1-k) Gamma du_k``
   (``Phi = e^{A h}``, ``Gamma = int_0^h e^{As} ds B``, exact for
   piecewise-constant inputs). One linear program (HiGHS through scipy)
   finds the du of least total change ``sum |du|`` with ``C x(T) = dy`` and
   ``f_min - f* <= du <= f_max - f*``: a slack cable (f* = f_min) can only
   pull harder, a taut one both ways.
2. **Correct.** The profile ``f* + du`` is simulated on the nonlinear robot
   (:func:`cdpm.simulate`); the miss ``y(T) - target`` is taken off the
   commanded change and the LP solved again (shooting), until the miss is
   below the tolerance. The miss is divided by a secant (Broyden) estimate
   of the nonlinear response per commanded change, starting from 1: where
   the robot answers a command more (or less) than the linearisation says,
   subtracting the miss itself overshoots (or creeps), and the shooting
   oscillated for dozens of iterations (the paper arm near a NO line
   answered 1.8 times its plan). A correction that does not lower the miss
   ends the estimate: the shooting goes on subtracting the miss itself.

When the LP has no solution (a NO pose steered toward its blocked
direction, or a target beyond what the bounds allow in time T), the best
attempt minimises the linear miss ``|C x(T) - dy|_1`` instead, is
simulated, and the result says why the target is not reached.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.linearisation import linearise
from cdpm.dynamics.simulation import TensionProfile, Trajectory, checked_duration, simulate
from cdpm.errors import (
    InputError,
    float_array,
    is_integer,
    positive_number,
    round_down,
    short_repr,
)
from cdpm.model.coordinates import MAX_COORDINATE
from cdpm.numerics import HORIZON_BOUND_RTOL, HORIZON_GIVEN_MAX_UNITS
from cdpm.printing import TextRepr
from cdpm.steering.output_range import outside_range

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.linearisation import Linearisation
    from cdpm.model.robot import CableRobot

__all__ = ["SteerResult", "TargetOutOfRangeError", "steer", "plan_profile", "default_duration"]

#: default number of piecewise-constant intervals of a steering profile
STEER_INTERVALS = 20
#: default miss tolerance, relative to the distance to the target
STEER_MISS_RTOL = 1e-3
#: shooting iterations at most
STEER_ITERATIONS = 12
#: most intervals a profile may have (one LP variable pair per cable and interval)
STEER_MAX_INTERVALS = 1000
#: default duration [s] when the linearisation has no time scale (A^2 = 0)
STEER_DURATION = 1.0
#: shooting: the secant estimate of the nonlinear gain is kept only while
#: its condition number stays below this ...
STEER_GAIN_MAX_CONDITION = 1e6
#: ... and one correction moves the command by at most this many times the miss
STEER_MAX_CORRECTION = 10.0
#: largest growth e^{Re(lambda) T} of the linearisation over a steering
#: time: beyond, the plan's entries span more than double precision's 16
#: digits (over 1000 s on two_link_vertical, numpy overflowed and the LP failed)
STEER_MAX_GROWTH = 1e16


class TargetOutOfRangeError(InputError):
    """A steering target that no pose of the robot has: an output past the
    bound of its range (:func:`~cdpm.steering.output_range.output_range`)."""


@dataclass(frozen=True)
class SteerResult(TextRepr):
    """A steering attempt.

    Printing it gives a short summary; :func:`cdpm.text.steer_text` (and
    :func:`cdpm.text.tension_profile_text`) prints it in full,
    :func:`cdpm.text.steer_json` gives its JSON data;
    :func:`cdpm.plotting.plot_trajectory` draws its trajectory.

    Attributes:
        time: knot times [s], shape (K+1,).
        tension: absolute tensions [N], shape (K, m), exactly as simulated
            (interval k holds ``tension[k]`` on [time[k], time[k+1])).
        trajectory: the nonlinear simulation of that profile.
        target: the output target, shape (p,).
        y0: the output at the equilibrium, shape (p,).
        miss: |y(T) - target| [output units].
        reached: miss <= tolerance.
        status: one line on the outcome (why not, when not reached).
        tolerance: the miss tolerance used.
        iterations: nonlinear simulations run (shooting iterations and, at
            a blocked direction, the single-cable pulls).
        equilibrium_tension: f* [N], shape (m,).
        blocked_direction: for a target the linearisation cannot reach,
            a unit v (p,) with v.(y - y0) unable to grow to first order
            (the POC certificate's separator when the pose is NO), else None.
        blocked_progress: with a blocked direction v: the largest
            v.(y(t) - y0) over every attempt made (the pulses of each cable
            that can pull harder, at the start, middle and end), in output
            units: at most of second order in the distance.
    """

    time: np.ndarray
    tension: np.ndarray
    trajectory: Trajectory
    target: np.ndarray
    y0: np.ndarray
    miss: float
    reached: bool
    status: str
    tolerance: float
    iterations: int
    equilibrium_tension: np.ndarray
    blocked_direction: np.ndarray | None = None
    blocked_progress: float | None = None

    @property
    def duration(self) -> float:
        """T [s]."""
        return float(self.time[-1] - self.time[0])

    @property
    def peak_tension(self) -> float:
        """Largest tension of the profile [N]."""
        return float(self.tension.max(initial=0.0))

    @property
    def final_velocity(self) -> np.ndarray:
        """Velocity at T (nv,); the robot is generally still moving."""
        return self.trajectory.v[-1]

    @property
    def within_bounds(self) -> bool:
        """Every tension inside its cable's bounds at every instant."""
        return self.trajectory.within_bounds

    def __str__(self) -> str:
        # a summary; cdpm.text.steer_text gives the outputs and velocities
        from cdpm.dynamics.reach import reach_unit

        unit = reach_unit(self.trajectory.units)
        return (
            f"Steering: {'REACHED' if self.reached else 'NOT REACHED'} ({self.status})\n"
            f"  miss {self.miss:.3g} {unit} (tolerance {self.tolerance:.3g} {unit}); "
            f"T = {self.duration:.4g} s; peak tension {self.peak_tension:.4g} N, "
            f"{'inside' if self.within_bounds else 'OUTSIDE'} the bounds"
        )

    def __repr__(self) -> str:
        # a few numbers: the profile and its simulation are arrays of many rows
        return (
            f"SteerResult(reached={self.reached}, miss={self.miss:.3g}, "
            f"tolerance={self.tolerance:.3g}, duration={self.duration:.4g} s, "
            f"intervals={self.tension.shape[0]}, iterations={self.iterations}, "
            f"peak_tension={self.peak_tension:.4g} N)"
        )


def _duration_bounds(lin: Linearisation) -> tuple[float, float, float]:
    """:func:`cdpm.analysis.margin.longest_horizon` of the linearisation
    with steering's growth, STEER_MAX_GROWTH: (HORIZON_GIVEN_MAX_UNITS of
    its time units [s]; the time [s] in which it grows by STEER_MAX_GROWTH;
    the rate Re lambda [1/s] of its fastest-growing mode)."""
    # scipy: loaded on first use
    from cdpm.analysis.margin import longest_horizon

    return longest_horizon(lin.A, lin.C.shape[0], math.log(STEER_MAX_GROWTH))


def longest_duration(lin: Linearisation) -> float:
    """The longest steering time [s] :func:`steer` accepts at the
    linearisation ``lin`` (inf when A = 0): its modes grow by at most
    STEER_MAX_GROWTH within it, and it spans at most
    HORIZON_GIVEN_MAX_UNITS of the linearisation's time units."""
    return min(_duration_bounds(lin)[:2])


def _checked_steer_duration(lin: Linearisation, duration: Any) -> float:
    """A given steering time [s]: :func:`checked_duration`, and at most
    :func:`longest_duration` (within HORIZON_BOUND_RTOL)."""
    T = checked_duration(duration)
    units, growing, rate = _duration_bounds(lin)
    longest = min(units, growing)
    if T > longest * (1.0 + HORIZON_BOUND_RTOL):
        why = (
            f"its fastest-growing mode (Re lambda = {rate:.4g} 1/s) grows by a factor of "
            f"e^{rate * T:.4g} over it, more than the {STEER_MAX_GROWTH:.0e} a plan resolves"
            if growing <= units
            else f"it spans more than {HORIZON_GIVEN_MAX_UNITS:g} of the linearisation's time units"
        )
        raise InputError(
            f"duration {T:g} s is too long to plan on the linearisation at this pose: {why}; "
            f"give at most {round_down(longest):g} s, or none (default "
            f"{default_duration(lin):.4g} s)"
        )
    return T


def default_duration(lin: Linearisation) -> float:
    """T [s]: STEER_DURATION, or a quarter period of the fastest mode of the
    stiffness block when that is shorter (fast modes: short, gentle moves)."""
    K = lin.stiffness
    if not np.any(K):
        return STEER_DURATION
    omega = math.sqrt(float(np.max(np.abs(np.linalg.eigvals(K)))))
    return min(STEER_DURATION, 0.5 * math.pi / omega) if omega > 0 else STEER_DURATION


def _transition(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma) = (e^{A h}, int_0^h e^{A s} ds B) from one exponential."""
    # scipy: loaded on first use
    from scipy.linalg import expm

    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n], aug[:n, n:] = A, B
    E = expm(aug * h)
    return E[:n, :n], E[:n, n:]


def _output_map(lin: Linearisation, T: float, K: int) -> np.ndarray:
    """The (p, K m) matrix taking the stacked changes du_k to C x(T)."""
    Phi, Gamma = _transition(lin.A, lin.B, T / K)
    blocks, P = [], Gamma
    for _ in range(K):
        blocks.append(lin.C @ P)
        P = Phi @ P
    return np.hstack(blocks[::-1])  # interval k is multiplied by Phi^(K-1-k)


def plan_profile(
    lin: Linearisation,
    dy: np.ndarray,
    T: float,
    K: int,
    fmin: np.ndarray,
    fmax: np.ndarray,
) -> tuple[np.ndarray | None, np.ndarray]:
    """The least total tension change reaching ``C x(T) = dy``, or, when no
    change within the bounds does, the one of least miss.

    Returns:
        (du (K, m) [N] or None when the exact target is out of reach,
        best-effort du (K, m) [N]).
    """
    # scipy: loaded on first use
    from scipy.optimize import linprog

    f0 = lin.tension
    m, p = f0.shape[0], dy.shape[0]
    G = _output_map(lin, T, K)  # (p, K m)
    lo = np.tile(fmin - f0, K)
    hi = np.tile(fmax - f0, K)
    # du = a - b with a in [0, max(hi, 0)], b in [0, max(-lo, 0)]
    a_hi, b_hi = np.maximum(hi, 0.0), np.maximum(-lo, 0.0)
    n = K * m
    bounds = [(0.0, x if math.isfinite(x) else None) for x in np.concatenate([a_hi, b_hi])]
    scale = max(float(np.abs(G).max()), 1e-300)
    res = linprog(
        np.ones(2 * n),
        A_eq=np.hstack([G, -G]) / scale,
        b_eq=dy / scale,
        bounds=bounds,
        method="highs",
    )
    exact = None
    if res.status == 0:
        exact = (res.x[:n] - res.x[n:]).reshape(K, m)
        return exact, exact
    # best effort: minimise |G du - dy|_1 (then effort, lightly)
    weight = 1e-6 / max(float(np.abs(dy).max()), 1e-300)
    c = np.concatenate([np.full(2 * n, weight), np.ones(2 * p)])
    A_eq = np.hstack([G, -G, -np.eye(p), np.eye(p)]) / scale
    res = linprog(
        c,
        A_eq=A_eq,
        b_eq=dy / scale,
        bounds=bounds + [(0.0, None)] * (2 * p),
        method="highs",
    )
    if res.status != 0:  # pragma: no cover - the best-effort LP is always feasible
        return None, np.zeros((K, m))
    return None, (res.x[:n] - res.x[n : 2 * n]).reshape(K, m)


def steer(
    robot: CableRobot,
    q: Any,
    target: Any,
    *,
    duration: float | None = None,
    intervals: int = STEER_INTERVALS,
    tension: Any = None,
    pretension: float | None = None,
    tolerance: float | None = None,
    max_iterations: int = STEER_ITERATIONS,
) -> SteerResult:
    """Move the nonlinear robot's output from its equilibrium at q to
    ``target`` with pull-only tensions inside the cable bounds.

    Args:
        robot: the robot.
        q: the equilibrium pose: a pose name, configuration (nq,) or natural
            coordinates (nv,).
        target: output target, shape (p,) [output units: m].
        duration: T [s]; default :func:`default_duration`.
        intervals: K piecewise-constant intervals.
        tension, pretension: the equilibrium tension (as for
            :func:`cdpm.linearise`).
        tolerance: largest acceptable miss; default STEER_MISS_RTOL times
            |target - y0| (at least 1e-12).
        max_iterations: nonlinear simulations at most (shooting).

    Returns:
        :class:`SteerResult` (``reached`` False with a status in words when
        the target is out of reach).

    Raises:
        InputError: a target of the wrong size or not finite, bad duration,
            intervals or tolerance.
        TargetOutOfRangeError: a target outside the outputs' range
            (:func:`~cdpm.steering.output_range.output_range`): no pose has
            that output, so nothing is simulated.
        InfeasibleEquilibriumError: no equilibrium at q.
    """

    lin = linearise(robot, q, tension=tension, pretension=pretension)
    p = robot.n_outputs
    try:
        goal = float_array(target, copy=True).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"target must be real numbers, one per output ({', '.join(robot.output_names)}): {exc}"
        ) from exc
    if goal.shape != (p,) or not np.all(np.abs(goal) <= MAX_COORDINATE):
        raise InputError(
            f"target must be finite numbers of at most {MAX_COORDINATE:g} in magnitude (m or "
            f"rad), one per output ({', '.join(robot.output_names)}); got {short_repr(target)}"
        )
    beyond = outside_range(robot, goal)
    if beyond is not None:
        raise TargetOutOfRangeError(
            f"target out of reach: {beyond} (a bound from the links' lengths and the joints' "
            "limits that no pose goes past), so no tension reaches it and nothing was "
            "simulated; give a target within that range"
        )
    if not (is_integer(intervals) and 1 <= intervals <= STEER_MAX_INTERVALS):
        raise InputError(
            f"intervals must be an integer from 1 to {STEER_MAX_INTERVALS}, got {intervals!r}"
        )
    if not (is_integer(max_iterations) and max_iterations >= 1):
        raise InputError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    T = default_duration(lin) if duration is None else _checked_steer_duration(lin, duration)
    y0 = lin.output.copy()
    dy = goal - y0
    if tolerance is None:
        tol = max(STEER_MISS_RTOL * np.linalg.norm(dy), 1e-12)
    else:
        message = f"tolerance must be a positive finite number, got {tolerance!r}"
        tol = positive_number(tolerance, message)
    fmin, fmax = robot.tension_min, robot.tension_max
    f0 = lin.tension
    time = np.linspace(0.0, T, intervals + 1)
    command = dy.copy()
    gain = np.eye(p)  # the nonlinear response y(T) - y0 per commanded change (secant estimate)
    previous = None  # (command, response, miss) of the last simulation
    secant = True  # the gain estimate is used while each correction lowers the miss
    best = None  # (values, trajectory, miss) of least miss
    blocked = None
    progress = None
    status = ""
    sims = 0
    for iteration in range(1, max_iterations + 1):
        du, attempt = plan_profile(lin, command, T, intervals, fmin, fmax)
        values = np.clip(f0 + attempt, fmin, fmax)
        traj = simulate(robot, lin.q, tension=TensionProfile(time, values))
        sims += 1
        miss = float(np.linalg.norm(traj.y[-1] - goal))
        if best is None or miss < best[2]:
            best = (values, traj, miss)
        if du is None:
            blocked = _blocked_direction(lin, dy)
            if blocked is not None:
                best, progress, probes = _probe_blocked(robot, lin, blocked, goal, time, fmin, fmax)
                sims += probes
                status = (
                    "POC NO: no pull moves the output along the blocked direction v to first "
                    "order; shown: the single-cable pull that got furthest along v"
                )
            else:
                what = "the target" if iteration == 1 else "the corrected target"
                status = (
                    f"the linearisation cannot reach {what} within the tension bounds in "
                    f"T = {T:.4g} s; a longer duration or a nearer target may help "
                    "(best attempt shown)"
                )
            break
        if miss <= tol:
            status = f"reached after {sims} simulation(s)"
            break
        response = traj.y[-1] - y0
        if previous is not None and secant:
            if miss < previous[2]:
                gain = _secant_gain(gain, command - previous[0], response - previous[1])
            else:  # the estimate did not help here: plain shooting from now on
                gain, secant = np.eye(p), False
        previous = (command.copy(), response, miss)
        command = command - _correction(gain, traj.y[-1] - goal)
    else:
        status = f"miss still above the tolerance after {sims} simulations (best attempt shown)"
    values, traj, miss = best
    reached = miss <= tol and blocked is None
    return SteerResult(
        time=time,
        tension=values,
        trajectory=traj,
        target=goal,
        y0=y0,
        miss=miss,
        reached=bool(reached),
        status=status,
        tolerance=float(tol),
        iterations=sims,
        equilibrium_tension=f0.copy(),
        blocked_direction=blocked,
        blocked_progress=progress,
    )


def _secant_gain(gain: np.ndarray, step: np.ndarray, change: np.ndarray) -> np.ndarray:
    """Broyden's update of the gain (p, p) from the nonlinear response's
    ``change`` to a commanded ``step``: the least change of the gain that
    maps step to change. Kept only while its eigenvalues have positive real
    parts and it is well conditioned (STEER_GAIN_MAX_CONDITION): a
    response that turned against the command (a fold of the output) keeps
    the last gain, so the correction never steps the wrong way."""
    size = float(step @ step)
    if not size > 0:
        return gain
    updated = gain + np.outer(change - gain @ step, step) / size
    if not np.all(np.isfinite(updated)):
        return gain
    if np.any(np.linalg.eigvals(updated).real <= 0):
        return gain
    if np.linalg.cond(updated) > STEER_GAIN_MAX_CONDITION:
        return gain
    return updated


def _correction(gain: np.ndarray, miss: np.ndarray) -> np.ndarray:
    """The change of the command that cancels ``miss`` (p,) under the gain:
    ``gain^-1 miss``, at most STEER_MAX_CORRECTION times |miss| long."""
    step = np.linalg.solve(gain, miss)
    limit = STEER_MAX_CORRECTION * float(np.linalg.norm(miss))
    length = float(np.linalg.norm(step))
    return step if length <= limit else step * (limit / length)


def _probe_blocked(robot, lin, v, goal, time, fmin, fmax):
    """At a NO pose, single-cable pulls toward the blocked direction v: each
    cable that can pull harder pulls for one interval (first, middle or
    last) with the tension change that would move the linear output by
    |goal - y0| (capped at its bound).

    Returns:
        ((values, trajectory, miss) of the pull that ends furthest along v,
        the largest v.(y(t) - y0) of any pull at any time, pulls simulated).
    """
    K, m = time.size - 1, lin.tension.shape[0]
    G = _output_map(lin, float(time[-1]), K).reshape(lin.C.shape[0], K, m)
    size = float(np.linalg.norm(goal - lin.output))
    room = fmax - lin.tension
    y0 = lin.output
    shown, progress, count = None, 0.0, 0
    for k in sorted({0, K // 2, K - 1}):
        for j in np.flatnonzero(room > 0):
            gain = float(np.linalg.norm(G[:, k, j]))
            values = np.tile(lin.tension, (K, 1))
            pull = size / gain if gain > 0 else room[j]
            values[k, j] = min(lin.tension[j] + pull, fmax[j])
            traj = simulate(robot, lin.q, tension=TensionProfile(time, values))
            count += 1
            miss = float(np.linalg.norm(traj.y[-1] - goal))
            progress = max(progress, float(np.max((traj.y - y0) @ v)))
            if shown is None or float(v @ traj.y[-1]) > float(v @ shown[1].y[-1]):
                shown = (values, traj, miss)
    if shown is None:  # no cable can pull harder: the equilibrium held
        values = np.tile(lin.tension, (K, 1))
        traj = simulate(robot, lin.q, tension=TensionProfile(time, values))
        shown, count = (values, traj, float(np.linalg.norm(traj.y[-1] - goal))), count + 1
    return shown, progress, count


def _blocked_direction(lin: Linearisation, dy: np.ndarray) -> np.ndarray | None:
    """The POC certificate's separator v when the pose is NO and the target
    change dy has a component along it (v.dy > 0), else None."""
    # scipy: loaded on first use
    from cdpm.analysis import Verdict, positive_output_controllability

    res = positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
    )
    v = getattr(res.certificate, "separator", None)
    if res.verdict is not Verdict.NO or v is None:
        return None
    v = np.asarray(v, dtype=float)
    v = v / np.linalg.norm(v)
    return v if float(v @ dy) > 0 else None
