"""Text and JSON of steering on the nonlinear robot: a steering attempt
(:class:`~cdpm.steering.shooting.SteerResult`, ``cdpm steer``) and the
verification of a verdict by steering around a pose
(:class:`~cdpm.steering.verify.VerifyReport`, ``cdpm verify``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cdpm.dynamics.reach import reach_unit
from cdpm.printing import packed_lines, strict
from cdpm.steering.verify import RADIUS_FRACTION

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.simulation import Trajectory
    from cdpm.steering.shooting import SteerResult
    from cdpm.steering.verify import VerifyReport


# ------------------------------------------------------------------- steer


def tension_profile_text(result: SteerResult) -> str:
    """A steering attempt's tension profile as ``cdpm steer`` prints it
    after :func:`steer_text`: a row per interval, its start [s] and each
    cable's tension [N]."""
    names = result.trajectory.cable_names
    lines = [
        "  tension profile [N] (interval start [s], then one column per cable)",
        "  " + f"{'t':>8} " + " ".join(f"{n:>10}" for n in names),
    ]
    for t, row in zip(result.time[:-1], result.tension, strict=True):
        lines.append("  " + f"{t:>8.4g} " + " ".join(f"{x:>10.4g}" for x in row))
    return "\n".join(lines)


def steer_text(result: SteerResult) -> str:
    """The steering attempt as ``cdpm steer`` prints it: outcome, outputs
    (target, y0, y(T)), miss, peak tension, final velocity and, toward a
    blocked direction, how far any pull got along it."""
    word = "REACHED" if result.reached else "NOT REACHED"
    traj = result.trajectory
    unit = reach_unit(traj.units)
    names = ", ".join(f"{n} [{u}]" for n, u in zip(traj.output_names, traj.units, strict=True))
    lines = [
        f"Steering: {word} ({result.status})",
        f"  outputs ({names}):",
        f"    target {_row(result.target)}; from y0 {_row(result.y0)}; y(T) {_row(traj.y[-1])}",
        f"  miss {result.miss:.3g} {unit} (tolerance {result.tolerance:.3g} {unit}) after "
        f"{result.iterations} simulation(s); T = {result.duration:.4g} s, "
        f"{result.tension.shape[0]} intervals",
        f"  peak tension {result.peak_tension:.4g} N; tensions "
        f"{'inside' if result.within_bounds else 'OUTSIDE'} the bounds",
        *_velocity_lines(result.final_velocity, traj),
    ]
    if result.blocked_direction is not None:
        lines.append(
            f"  blocked direction v = {np.array2string(result.blocked_direction, precision=4)}; "
            f"pulling each cable in turn, v.(y - y0) reached at most "
            f"{result.blocked_progress:.3g}"
        )
    return "\n".join(lines)


def steer_json(result: SteerResult) -> dict:
    """Strict-JSON data of the steering attempt (``cdpm steer --json``)."""
    traj = result.trajectory
    return strict(
        {
            "reached": result.reached,
            "status": result.status,
            "target": result.target,
            "y0": result.y0,
            "y_final": traj.y[-1],
            "miss": result.miss,
            "tolerance": result.tolerance,
            "duration": result.duration,
            "iterations": result.iterations,
            "peak_tension": result.peak_tension,
            "within_bounds": result.within_bounds,
            "final_velocity": result.final_velocity,
            "velocity_names": list(traj.velocity_labels),
            "velocity_units": list(traj.velocity_units),
            "time": result.time,
            "tension": result.tension,
            "cable_names": list(traj.cable_names),
            "blocked_direction": result.blocked_direction,
            "blocked_progress": result.blocked_progress,
        }
    )


def _row(values: np.ndarray) -> str:
    """A vector on one line, to 6 decimals (numpy breaks a long one into
    lines of 75 characters, which in the printout started unindented, and
    mixed 2.000000e-03 with -8.194993e-09)."""
    shown = np.round(np.asarray(values, dtype=float), 6) + 0.0  # -8e-9 reads 0, not -0
    return np.array2string(shown, precision=6, suppress_small=True, max_line_width=10**6)


def _velocity_lines(v: np.ndarray, traj: Trajectory) -> list[str]:
    """The printout's lines on the final velocities ``v`` (nv,), each
    named and in its unit (``q1_dot 0.012 rad/s``; the trajectory's
    ``velocity_labels`` and ``velocity_units``: a free-flyer's in its body
    frame), as many to a line as fit (:func:`cdpm.printing.packed_lines`)."""
    items = [
        f"{name} {value + 0.0:.3g} {unit}"
        for name, value, unit in zip(traj.velocity_labels, v, traj.velocity_units, strict=True)
    ]
    return packed_lines("  final velocity (the robot still moves at T):", items)


# ------------------------------------------------------------------ verify


def _verify_rows(report: VerifyReport) -> list[dict]:
    """One dict per run: direction, reached, miss, miss/R, peak tension,
    duration, simulations."""
    return [
        {
            "direction": d.tolist(),
            "reached": bool(r.reached),
            "miss": float(r.miss),
            "relative_miss": float(r.miss / report.radius),
            "peak_tension": r.peak_tension,
            "within_bounds": bool(r.within_bounds),
            "duration": r.duration,
            "simulations": int(r.iterations),
            "status": r.status,
        }
        for d, r in zip(report.directions, report.runs, strict=True)
    ]


def verify_text(report: VerifyReport) -> str:
    """The verification as ``cdpm verify`` prints it: the targets, the
    blocked direction at a NO pose, one row per run (direction, reached,
    miss/R, peak tension, duration, simulations) and what shows on the
    robot."""
    where = f"pose {report.pose_name!r}" if report.pose_name else "the given q"
    names = report.runs[0].trajectory.output_names if report.runs else ()
    how = (
        "given"
        if report.radius_given
        else f"{RADIUS_FRACTION:g} x the robot's size {report.robot_size:.4g} m"
    )
    lines = [
        f"cdpm verify: {report.model_name}, {where}: POC {report.verdict.upper()}",
        f"  targets at R = {report.radius:.4g} {report.unit} ({how}) from y0 = "
        + (
            ", ".join(f"{n} {v:.6g}" for n, v in zip(names, report.y0, strict=True))
            if len(names) == len(report.y0)
            else np.array2string(report.y0, precision=6)
        ),
    ]
    if report.blocked_direction is not None:
        lines.append(
            f"  blocked direction v = {direction_text(report.blocked_direction, names)}"
            f"; pulling each cable in turn, v.(y - y0) reached at most "
            f"{report.blocked_progress():.3g} R"
        )
    lines.append(
        f"  {'direction':<28} {'reached':>7} {'miss/R':>10} {'peak [N]':>10} "
        f"{'T [s]':>7} {'sims':>5}"
    )
    for row in _verify_rows(report):
        d = direction_text(np.array(row["direction"]), names)
        lines.append(
            f"  {d:<28} {'yes' if row['reached'] else 'NO':>7} {row['relative_miss']:>10.2e} "
            f"{row['peak_tension']:>10.4g} {row['duration']:>7.3g} {row['simulations']:>5}"
        )
    if report.runs:
        ok = "all tensions inside the cable bounds at every instant"
        if not all(r.within_bounds for r in report.runs):
            ok = "SOME TENSIONS OUTSIDE THE CABLE BOUNDS"
        n = sum(r.reached for r in report.runs)
        lines.append(f"  {n} of {len(report.runs)} targets reached; {ok}")
        if report.verdict == "yes":
            outcome = "every target reached" if report.demonstrated else "SOME TARGETS MISSED"
        elif report.verdict == "no":
            outcome = (
                "the blocked direction stays out of reach"
                if report.demonstrated
                else "NOT SHOWN (a pull moved the output along v; try a smaller --radius)"
            )
        else:
            outcome = "a MARGINAL verdict shows nothing definite"
        lines.append(f"  on the robot: {outcome}")
    return "\n".join(lines)


def verify_json(report: VerifyReport) -> dict:
    """Strict-JSON data of the verification (``cdpm verify --json``), one
    entry per run in ``runs``."""
    return strict(
        {
            "model": report.model_name,
            "pose": report.pose_name,
            "verdict": report.verdict,
            "radius": report.radius,
            "robot_size": report.robot_size,
            "y0": report.y0,
            "all_reached": report.all_reached,
            "worst_relative_miss": report.worst_relative_miss,
            "blocked_direction": report.blocked_direction,
            "blocked_progress_relative": report.blocked_progress(),
            "demonstrated": report.demonstrated,
            "runs": _verify_rows(report),
        }
    )


def direction_text(d: np.ndarray, names: tuple[str, ...]) -> str:
    """An output-space direction in words: ``"+tip_x"``, ``"-tip_z"`` or
    ``"0.71 tip_x - 0.71 tip_z"`` (components below 1e-9 left out)."""
    terms = [(float(c), n) for c, n in zip(d, names, strict=False) if abs(c) > 1e-9]
    if not names or len(names) != len(d):
        return np.array2string(np.asarray(d) + 0.0, precision=2)
    if not terms:
        return "0"
    if len(terms) == 1 and abs(abs(terms[0][0]) - 1.0) < 1e-9:
        return ("+" if terms[0][0] > 0 else "-") + terms[0][1]
    text = " ".join(f"{'-' if c < 0 else '+'} {abs(c):.2g} {n}" for c, n in terms)
    return text[2:] if text.startswith("+ ") else "-" + text[2:]
