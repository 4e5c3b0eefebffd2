"""Nonlinear simulation of a cable robot under given cable tensions.

:func:`simulate` integrates the full dynamics (seed paper eq 11, with the
URDF's viscous joint damping D and the spec's constant load w_ext)::

    M(q) q'' + C(q, q') q' + G(q) + D q' + w_ext = -L(q)^T f(t)

with Pinocchio's articulated-body algorithm (ABA) for q'' on the
configuration manifold: the state is written in a chart
``q = pin.integrate(q_c, delta)`` around a point q_c, where
``delta' = (d integrate / d delta)^-1 q'``, so free-flyers and other joints
with quaternions integrate exactly (no drift off the unit sphere); the chart
moves to every output sample. Robots whose joints are all plain vector
spaces (revolute, prismatic) need no chart and integrate each
piecewise-constant interval (or the whole span) in one go. Each piece is
solved by scipy's adaptive Dormand-Prince 8(5,3) method (``DOP853``) with
relative and absolute error tolerances ``rtol`` and ``atol``; a profile's
jumps never fall inside a step.

Tensions are either a :class:`TensionProfile` (knot times (K+1,) [s],
values (K, m) [N], value k held on [time[k], time[k+1])), a constant (m,),
or a feedback callable ``f(t, q, v) -> (m,)``. The result is a
:class:`Trajectory`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.errors import InputError, float_array, is_integer, positive_number, short_repr
from cdpm.model.coordinates import coordinate_units, joint_kind, velocity_names
from cdpm.numerics import MAX_TENSION, MAX_TIME_SPAN
from cdpm.printing import TextRepr

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = ["TensionProfile", "Trajectory", "simulate", "trajectory_labels"]

#: default error tolerances of the integrator (relative, absolute)
SIM_RTOL = 1e-10
SIM_ATOL = 1e-12
#: default output samples per second of simulated time, at least this many in all
SAMPLES_PER_SECOND = 200
MIN_SAMPLES = 50
#: largest start speed [rad/s or m/s] of a simulation (about 160,000 turns
#: a second): far beyond, the dynamics overflow, and near it no simulation
#: ends within its budget of evaluations
MAX_SPEED = 1e6
#: shortest steering or simulation [s] (shorter ones sample round-off)
MIN_DURATION = 1e-6
#: most output samples of one simulation (the default count is clipped to it)
MAX_SAMPLES = 1_000_000
#: default budget of evaluations of the dynamics (right-hand sides of the
#: ODE) of one simulation (about 25 s on a two-link robot here;
#: a simulated second of ordinary motion takes a few thousand); a motion too
#: fast for the tolerances (huge speeds or tensions) stops with an error
#: instead of running for hours
MAX_EVALUATIONS = 500_000

Feedback = Callable[[float, np.ndarray, np.ndarray], Any]


@dataclass(frozen=True)
class TensionProfile:
    """Piecewise-constant cable tensions.

    Attributes:
        time: knot times [s], shape (K+1,), strictly increasing.
        values: tensions [N], shape (K, m); value k is held on
            [time[k], time[k+1]) and the last one after time[K].
    """

    time: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        try:
            t = float_array(self.time, copy=True).reshape(-1)
            f = float_array(self.values, copy=True)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"tension profile: time and values must be real numbers: {exc}"
            ) from exc
        if f.ndim != 2 or t.shape[0] != f.shape[0] + 1 or f.shape[0] < 1:
            raise InputError(
                f"tension profile: time has {t.shape[0]} knots and values shape {f.shape}; "
                "give K+1 knot times [s] and (K, m) tensions [N] (one row per interval)"
            )
        if not np.all(np.isfinite(t)):
            raise InputError("tension profile: knot times must be finite")
        if not np.all(np.abs(f) <= MAX_TENSION):
            raise InputError(
                f"tension profile: values must be finite tensions of at most {MAX_TENSION:g} N"
            )
        if np.any(np.diff(t) <= 0):
            raise InputError("tension profile: knot times must be strictly increasing")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "values", f)

    @classmethod
    def make(cls, time: Any, values: Any, m: int) -> TensionProfile:
        """A validated profile (copies) for m cables, or an InputError naming
        the problem; one interval's values may be given as a flat (m,)."""
        if np.ndim(values) == 1 and np.size(values) == m and np.size(time) == 2:
            values = np.reshape(values, (1, m))
        profile = cls(time, values)  # the constructor checks shapes and values
        if profile.values.shape[1] != m:
            raise InputError(
                f"tension profile: values have {profile.values.shape[1]} columns; give one "
                f"per cable ({m})"
            )
        return profile

    def __call__(self, t: float) -> np.ndarray:
        """The tensions [N] held at time t, shape (m,)."""
        k = int(np.searchsorted(self.time, t, side="right")) - 1
        return self.values[min(max(k, 0), self.values.shape[0] - 1)]


def _one_unit(units: tuple[str, ...], coordinate: str) -> str:
    """The unit of a variable whose components have ``units``: the one
    they share, else a pointer to the ``coordinate`` that gives each."""
    distinct = set(units)
    return units[0] if len(distinct) == 1 else f"per component, see {coordinate}"


@dataclass(frozen=True)
class Trajectory(TextRepr):
    """A simulated motion, sampled at times t.

    Attributes:
        t: sample times [s], shape (T,).
        q: configurations, shape (T, nq).
        v: velocities (tangent space), shape (T, nv).
        f: cable tensions applied at each sample [N], shape (T, m).
        y: outputs, shape (T, p), each in its unit (``output_units``).
        lengths: cable lengths [m], shape (T, m).
        tension_min, tension_max: the cables' bounds [N], each (m,).
        cable_names, output_names, coordinate_names: labels.
        profile: the piecewise-constant profile simulated, or None for a
            feedback law.
        output_units: each output's unit (``"m"``, ``"rad"``, ``"mixed"``
            or a spec's ``unit:``); empty: metres.
        coordinate_units: each coordinate's unit (``"m"`` or ``"rad"``),
            which gives each tangent velocity's (``velocity_units``); empty:
            not recorded.
        velocity_names: each component of ``v``
            (:func:`cdpm.model.coordinates.velocity_names`: ``q1_dot``, or a
            free-flyer's body-frame ``joint.v_x`` ... ``joint.w_z``); empty:
            ``name_dot`` of each coordinate.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    f: np.ndarray
    y: np.ndarray
    lengths: np.ndarray
    tension_min: np.ndarray
    tension_max: np.ndarray
    cable_names: tuple[str, ...]
    output_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    profile: TensionProfile | None = None
    output_units: tuple[str, ...] = ()
    coordinate_units: tuple[str, ...] = ()
    velocity_names: tuple[str, ...] = ()

    @property
    def units(self) -> tuple[str, ...]:
        """Each output's unit (``output_units``, metres when not given)."""
        return self.output_units or ("m",) * len(self.output_names)

    @property
    def velocity_units(self) -> tuple[str, ...]:
        """Each tangent velocity's unit (``"rad/s"`` or ``"m/s"``), in the
        order of ``coordinate_names``; ``"rad/s or m/s"`` each when the
        coordinates' units were not recorded."""
        if len(self.coordinate_units) == self.v.shape[1]:
            return tuple(f"{u}/s" for u in self.coordinate_units)
        return ("rad/s or m/s",) * self.v.shape[1]

    @property
    def out_of_bounds(self) -> np.ndarray:
        """True where a cable's applied tension leaves [f_min, f_max], shape
        (T, m). A profile's knots are samples, so every interval it played
        is checked (at its first sample)."""
        return (self.f < self.tension_min) | (self.f > self.tension_max)

    @property
    def within_bounds(self) -> bool:
        """Every tension inside its cable's bounds at every instant."""
        return not bool(self.out_of_bounds.any())

    @property
    def velocity_labels(self) -> tuple[str, ...]:
        """The name of each component of ``v`` (``velocity_names``, else
        ``name_dot`` of each coordinate, else ``v[i]``)."""
        nv = self.v.shape[1]
        if len(self.velocity_names) == nv:
            return tuple(self.velocity_names)
        if len(self.coordinate_names) == nv:
            return tuple(f"{c}_dot" for c in self.coordinate_names)
        return tuple(f"v[{i}]" for i in range(nv))

    def to_dataset(self):
        """The trajectory as an ``xarray.Dataset`` (dims time, cable, output,
        velocity (its components, ``velocity_labels``, each unit in the
        coordinate ``velocity_unit``) and q_index (Pinocchio's configuration
        vector); units in the attributes)."""
        # xarray: loaded on first use
        import xarray as xr

        return xr.Dataset(
            {
                "tension": (("time", "cable"), self.f, {"units": "N"}),
                "cable_length": (("time", "cable"), self.lengths, {"units": "m"}),
                "y": (
                    ("time", "output"),
                    self.y,
                    {"long_name": "outputs", "units": ", ".join(dict.fromkeys(self.units))},
                ),
                "v": (
                    ("time", "velocity"),
                    self.v,
                    {
                        "long_name": "tangent velocity",
                        "units": _one_unit(self.velocity_units, "velocity_unit"),
                    },
                ),
                "q": (
                    ("time", "q_index"),
                    self.q,
                    {"long_name": "configuration vector (Pinocchio's q, nq entries)"},
                ),
                "out_of_bounds": (("time", "cable"), self.out_of_bounds),
            },
            coords={
                "time": ("time", self.t, {"units": "s"}),
                "cable": list(self.cable_names),
                "output": list(self.output_names),
                "output_unit": ("output", list(self.units)),
                "velocity": list(self.velocity_labels),
                "velocity_unit": ("velocity", list(self.velocity_units)),
                "tension_min": ("cable", self.tension_min, {"units": "N"}),
                "tension_max": ("cable", self.tension_max, {"units": "N"}),
            },
            attrs={"within_bounds": int(self.within_bounds)},
        )

    def __str__(self) -> str:
        bounds = "inside" if self.within_bounds else "OUTSIDE"
        lines = [
            f"Trajectory: {self.t.size} samples over {self.t[-1] - self.t[0]:.4g} s; "
            f"tensions {bounds} the cable bounds",
            f"  y(0) = {np.array2string(self.y[0], precision=6)}",
            f"  y(T) = {np.array2string(self.y[-1], precision=6)}",
            f"  peak tension {float(np.max(self.f, initial=0.0)):.4g} N",
        ]
        return "\n".join(lines)

    def __repr__(self) -> str:
        # a few numbers: the arrays are thousands of samples (print shows the summary)
        return (
            f"Trajectory(samples={self.t.size}, t=[{self.t[0]:.4g}, {self.t[-1]:.4g}] s, "
            f"cables={self.cable_names}, outputs={self.output_names}, "
            f"within_bounds={self.within_bounds})"
        )


def _as_tension(robot: CableRobot, tension: Any) -> TensionProfile | Feedback | np.ndarray:
    m = robot.n_cables
    if isinstance(tension, TensionProfile):
        return TensionProfile.make(tension.time, tension.values, m)
    if callable(tension):
        return tension
    if isinstance(tension, tuple) and len(tension) == 2 and np.ndim(tension[0]) == 1:
        return TensionProfile.make(tension[0], tension[1], m)
    try:
        f = float_array(tension, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(
            "tension must be a TensionProfile, (time, values), a constant (m,) [N] of real "
            f"numbers or a callable f(t, q, v); got {short_repr(tension)}"
        ) from exc
    if f.shape != (m,) or not np.all(np.abs(f) <= MAX_TENSION):
        raise InputError(
            f"a constant tension needs {m} finite values [N] of at most {MAX_TENSION:g} N, got "
            f"{short_repr(tension)}"
        )
    return f


class _Dynamics:
    """q'' of the robot, and the chart ODE for (delta, v)."""

    def __init__(self, robot: CableRobot):
        # pinocchio: loaded on first use
        import pinocchio as pin

        self.robot, self.pin = robot, pin
        self.model = robot.model
        self.data = robot.model.createData()
        self.damping = robot.joint_damping
        self.w_ext = robot.external_wrench

        # every joint a plain vector space: the chart is q = q_c + delta
        self.flat = robot.nq == robot.nv and all(
            joint_kind(self.model.joints[j]) == "euclidean" for j in range(1, self.model.njoints)
        )

    def acceleration(self, q, v, f) -> np.ndarray:
        L = self.robot._kinematics(q)[0].jacobian  # q is valid: no re-validation
        tau = -L.T @ f - self.damping * v - self.w_ext
        return self.pin.aba(self.model, self.data, q, v, tau)

    def chart_rhs(self, qc, tension, t0):
        nv, pin, model = self.robot.nv, self.pin, self.model
        arg1 = pin.ArgumentPosition.ARG1

        def rhs(t, state):
            delta, v = state[:nv], state[nv:]
            q = qc + delta if self.flat else pin.integrate(model, qc, delta)
            f = tension(t0 + t, q, v)
            a = self.acceleration(q, v, f)
            if self.flat:
                ddelta = v
            else:
                ddelta = np.linalg.solve(pin.dIntegrate(model, qc, delta, arg1), v)
            return np.concatenate([ddelta, a])

        return rhs


class _BudgetSpent(Exception):
    """The integrator asked for more evaluations than its budget."""


class _Budget:
    """Counts the evaluations of the dynamics of one simulation (over all
    its pieces); past ``limit`` the next one raises _BudgetSpent, with the
    time [s] and the largest speed [rad/s or m/s] of the state it was asked
    at recorded."""

    def __init__(self, limit: int, nv: int):
        self.limit, self.nv = limit, nv
        self.count, self.t, self.speed = 0, 0.0, 0.0

    def counted(self, rhs, t0: float):
        """``rhs(t, state)`` of the piece starting at ``t0`` [s], counted."""

        def counted_rhs(t, state):
            self.count += 1
            if self.count > self.limit:
                self.t = t0 + t
                self.speed = float(np.abs(state[self.nv :]).max(initial=0.0))
                raise _BudgetSpent
            return rhs(t, state)

        return counted_rhs


def checked_duration(duration) -> float:
    """A steering or simulation time [s] as a float in [MIN_DURATION,
    MAX_TIME_SPAN], or an InputError."""
    message = (
        f"duration must be a time from {MIN_DURATION:g} to {MAX_TIME_SPAN:g} s, got "
        f"{short_repr(duration)}"
    )
    return positive_number(duration, message, largest=MAX_TIME_SPAN, smallest=MIN_DURATION)


def simulate(
    robot: CableRobot,
    q0: Any,
    v0: Any = None,
    *,
    tension: Any,
    duration: float | None = None,
    samples: int | None = None,
    rtol: float = SIM_RTOL,
    atol: float = SIM_ATOL,
    max_evaluations: int = MAX_EVALUATIONS,
) -> Trajectory:
    """Simulate the nonlinear robot from (q0, v0) under cable tensions.

    Args:
        robot: the robot.
        q0: start configuration (nq,), natural coordinates (nv,) or a pose name.
        v0: start velocity (nv,) [rad/s or m/s]; default rest.
        tension: a :class:`TensionProfile` or ``(time, values)`` (knots (K+1,)
            [s], tensions (K, m) [N]), a constant (m,) [N], or a feedback
            law ``f(t, q, v) -> (m,)`` [N].
        duration: simulated time [s]; default the profile's last knot
            (required for constants and feedback laws).
        samples: output samples (default 200 per second, at least 50 and
            at most MAX_SAMPLES = 1,000,000); a profile's knots are always
            samples too.
        rtol, atol: the integrator's error tolerances (relative; absolute
            in rad, m, rad/s, m/s).
        max_evaluations: the most evaluations of the dynamics the
            integrator may make (default MAX_EVALUATIONS = 500,000); a
            motion that needs more (speeds or tensions far too large for
            the tolerances, or a very long span) stops with an InputError
            that says how far it got.

    Returns:
        :class:`Trajectory`.

    Raises:
        InputError: bad start state, tensions, duration, tolerances or
            samples, or the budget of evaluations is spent.
        ModelError: a cable reaches zero length on the way.
    """
    # scipy: loaded on first use
    from scipy.integrate import solve_ivp

    q = robot.as_q(q0)
    nv, m = robot.nv, robot.n_cables
    try:
        v = np.zeros(nv) if v0 is None else float_array(v0, copy=True).reshape(-1)
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (nv,) or not np.all(np.abs(v) <= MAX_SPEED):
        raise InputError(
            f"v0 must be {nv} finite real velocities [rad/s or m/s] of at most {MAX_SPEED:g} in "
            f"magnitude, got {short_repr(v0)}"
        )
    law = _as_tension(robot, tension)
    profile = law if isinstance(law, TensionProfile) else None
    t_start = float(profile.time[0]) if profile is not None else 0.0
    if duration is None:
        if profile is None:
            raise InputError("give duration= [s] for a constant tension or a feedback law")
        duration = float(profile.time[-1] - t_start)
    duration = checked_duration(duration)
    rtol = positive_number(
        rtol,
        f"rtol must be a relative tolerance in (0, 1), got {short_repr(rtol)}",
        largest=math.nextafter(1.0, 0.0),
    )
    atol = positive_number(
        atol, f"atol must be a positive finite tolerance, got {short_repr(atol)}"
    )
    t_end = t_start + duration
    if samples is not None and not (is_integer(samples) and 2 <= samples <= MAX_SAMPLES):
        raise InputError(
            f"samples must be an integer from 2 (start and end) to {MAX_SAMPLES:,}, got {samples!r}"
        )
    if not (is_integer(max_evaluations) and max_evaluations >= 1):
        raise InputError(
            f"max_evaluations must be a positive integer (default {MAX_EVALUATIONS:,}), got "
            f"{max_evaluations!r}"
        )
    n = samples or min(
        MAX_SAMPLES, max(MIN_SAMPLES, int(math.ceil(SAMPLES_PER_SECOND * duration)) + 1)
    )
    times = np.linspace(t_start, t_end, n)
    if not np.all(np.diff(times) > 0):
        raise InputError(
            f"{n} samples from t = {t_start:g} s to {t_end:.17g} s fall on the same floating-point "
            "times: give a longer duration or fewer samples"
        )
    if profile is not None:
        inside = profile.time[(profile.time > t_start) & (profile.time < t_end)]
        times = np.unique(np.concatenate([times, inside]))

    if profile is not None:

        def value(t, q_, v_):
            return profile(t)

    elif callable(law):

        def value(t, q_, v_):
            out = law(t, q_, v_)
            try:
                f = float_array(out).reshape(-1)
            except (TypeError, ValueError):
                f = None
            if f is None or f.shape != (m,) or not np.all(np.abs(f) <= MAX_TENSION):
                raise InputError(
                    f"the feedback law returned {short_repr(out)} at t = {t:g} s; it must return "
                    f"{m} finite tensions [N] of at most {MAX_TENSION:g} N"
                )
            return f

    else:
        constant = law

        def value(t, q_, v_):
            return constant

    dyn = _Dynamics(robot)
    budget = _Budget(int(max_evaluations), nv)
    qs, vs, fs = [q.copy()], [v.copy()], [value(times[0], q, v)]
    # pieces integrated in one go: a profile's intervals (its jumps never
    # inside a step) or the whole span; on a manifold, one chart per sample
    if not dyn.flat:
        cuts = times
    elif profile is not None:
        cuts = np.unique(np.concatenate([[t_start, t_end], inside]))
    else:
        cuts = np.array([t_start, t_end])
    for t0, t1 in zip(cuts[:-1], cuts[1:], strict=True):
        if profile is not None:
            held = profile(t0)  # the interval's value, also exactly at its end

            def piece(t, q_, v_, held=held):
                return held
        else:
            piece = value
        rhs = budget.counted(dyn.chart_rhs(q, piece, t0), t0)
        out_t = times[(times > t0) & (times <= t1)]
        try:
            sol = solve_ivp(
                rhs,
                (0.0, t1 - t0),
                np.concatenate([np.zeros(nv), v]),
                method="DOP853",
                t_eval=out_t - t0,
                rtol=rtol,
                atol=atol,
            )
        except _BudgetSpent:
            raise InputError(
                f"the simulation needs more than max_evaluations = {budget.limit:,} "
                f"evaluations of the dynamics: it got to t = {budget.t:.6g} s of "
                f"[{t_start:g}, {t_end:g}] s, with speeds of up to {budget.speed:.3g} rad/s "
                f"or m/s there; the motion is too fast or too long for rtol = {rtol:g}, atol = "
                f"{atol:g}: lower v0 or the tensions, shorten the duration, loosen rtol and "
                "atol, or raise max_evaluations"
            ) from None
        if not sol.success:
            raise InputError(f"the integrator stopped at t = {t0:g} s: {sol.message}")
        for j, t in enumerate(out_t):
            delta, v = sol.y[:nv, j], sol.y[nv:, j].copy()
            qj = q + delta if dyn.flat else dyn.pin.integrate(robot.model, q, delta)
            qs.append(qj.copy())
            vs.append(v.copy())
            fs.append(value(t, qj, v))
        q = qs[-1]
    qs, vs, fs = np.array(qs), np.array(vs), np.array(fs)
    kin = robot.kinematics_batch(qs)
    return Trajectory(
        t=times,
        q=qs,
        v=vs,
        f=fs,
        y=np.array(kin.output),
        lengths=np.array(kin.lengths),
        profile=profile,
        **trajectory_labels(robot),
    )


def trajectory_labels(robot: CableRobot) -> dict:
    """What a :class:`Trajectory` of ``robot`` records besides its samples:
    the cables' bounds [N], and the names and units of its cables, outputs,
    coordinates and velocities (keyword arguments of Trajectory)."""

    return {
        "tension_min": robot.tension_min.copy(),
        "tension_max": robot.tension_max.copy(),
        "cable_names": tuple(robot.cable_names),
        "output_names": tuple(robot.output_names),
        "coordinate_names": tuple(robot.coordinate_names),
        "output_units": tuple(robot.output_units),
        "coordinate_units": tuple(coordinate_units(robot.model)),
        "velocity_names": tuple(velocity_names(robot.model)),
    }
