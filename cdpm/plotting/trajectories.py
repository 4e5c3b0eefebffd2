"""Pictures of motions: a simulated trajectory's outputs and tensions
(:func:`plot_trajectory`) and the runs of a verification
(:func:`plot_verify_report`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cdpm.plotting._common import matplotlib_parts
from cdpm.text.steering import direction_text

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.simulation import Trajectory
    from cdpm.steering.verify import VerifyReport

__all__ = ["plot_trajectory", "plot_verify_report", "display_unit", "tension_panel"]


#: how outputs of small motions are shown: in thousandths of metres and radians
_MILLI = {"m": "mm", "rad": "mrad"}


def display_unit(unit: str) -> tuple[float, str]:
    """(factor, unit shown) of an output change in ``unit`` on a plot of a
    small motion: metres as mm, radians as mrad, an output mixing both
    (``"mixed"``, or ``reach_unit``'s ``"m and rad, one to one"``) as
    ``"mm, mrad"``; other units as they are."""
    if unit in _MILLI:
        return 1e3, _MILLI[unit]
    if unit in ("mixed", "m and rad, one to one"):
        return 1e3, "mm, mrad"
    return 1.0, unit


def tension_panel(ax, time, values, names, equilibrium=None) -> None:
    """Tensions [N] on ``ax``: a step line per cable of the profile
    ``values`` (K, m) on knots ``time`` (K + 1,), or of samples (K, m) at
    ``time`` (K,); with ``equilibrium`` (m,), each cable's f* dotted in its
    colour. Cables at 0 N throughout are named in the title, and cables
    with the same tensions throughout share one line (``c1 = c2``), instead
    of being drawn on top of each other; the legend goes right of the axes."""
    values = np.asarray(values, dtype=float)
    stepped = len(time) == values.shape[0] + 1
    f_eq = np.zeros(len(names)) if equilibrium is None else np.asarray(equilibrium, dtype=float)
    idle = [n for j, n in enumerate(names) if not np.any(values[:, j]) and f_eq[j] == 0]
    groups: dict[tuple, list[int]] = {}  # cables with equal tensions and f*: one line
    for j, name in enumerate(names):
        if name not in idle:
            groups.setdefault((values[:, j].tobytes(), f_eq[j]), []).append(j)
    for members in groups.values():
        j, label = members[0], " = ".join(names[k] for k in members)
        if stepped:
            held = np.append(values[:, j], values[-1, j])
            (line,) = ax.step(time, held, where="post", label=label)
        else:
            (line,) = ax.plot(time, values[:, j], label=label)
        if equilibrium is not None:
            ax.axhline(f_eq[j], color=line.get_color(), ls=":", lw=1.0)
    ax.set_ylabel("cable tension [N]")
    ax.grid(alpha=0.3)
    title = "tensions" + ("; dotted: equilibrium f*" if equilibrium is not None else "")
    if idle:
        title += f"\nat 0 N throughout: {', '.join(idle)}"
    ax.set_title(title, fontsize=9, parse_math=False)
    if len(idle) < len(names):
        legend = ax.legend(
            fontsize=7,
            loc="center left",
            bbox_to_anchor=(1.01, 0.5),
            frameon=False,
            ncol=1 + (len(groups) - 1) // 9,
        )
        for text in legend.get_texts():  # cable names as written, never as maths
            text.set_parse_math(False)


def plot_trajectory(
    trajectory: Trajectory,
    path=None,
    *,
    title: str | None = None,
    target=None,
    equilibrium=None,
):
    """A :class:`~cdpm.dynamics.simulation.Trajectory`'s outputs y(t)
    (change from the start; metres as mm, radians as mrad) and tensions
    f(t) in two panels; with ``path``, saved there.
    ``target`` (p,) draws the outputs' targets, ``equilibrium`` (m,) the
    cables' equilibrium tensions f* [N]. Returns the matplotlib Figure."""
    _, Figure = matplotlib_parts()
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax_y, ax_f = fig.subplots(2, 1, sharex=True)
    dy = trajectory.y - trajectory.y[0]
    shown = [display_unit(u) for u in trajectory.units]
    for i, name in enumerate(trajectory.output_names):
        factor, unit = shown[i]
        (line,) = ax_y.plot(trajectory.t, dy[:, i] * factor, label=f"{name} [{unit}]")
        if target is not None:
            ax_y.axhline(
                (target[i] - trajectory.y[0, i]) * factor,
                color=line.get_color(),
                ls="--",
                lw=0.8,
                label=f"{name} target",
            )
    units = ", ".join(dict.fromkeys(unit for _, unit in shown))
    ax_y.set_ylabel(f"output change y - y(0) [{units}]")
    # beside the panel, as the tensions' (inside, it covered the curves)
    ax_y.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8, frameon=False)
    ax_y.grid(alpha=0.3)
    if trajectory.profile is None:
        tension_panel(ax_f, trajectory.t, trajectory.f, trajectory.cable_names, equilibrium)
    else:
        profile = trajectory.profile
        tension_panel(ax_f, profile.time, profile.values, trajectory.cable_names, equilibrium)
    ax_f.set_xlabel("time [s]")
    if title:
        fig.suptitle(title, fontsize=10)
    if path is not None:
        fig.savefig(path, dpi=100)
    return fig


def plot_verify_report(report: VerifyReport, path=None):
    """A :class:`~cdpm.steering.verify.VerifyReport`'s output change and
    tensions of every run (one row per run); with ``path``, saved there. Returns the Figure."""

    _, Figure = matplotlib_parts()
    n = len(report.runs)
    factor, unit = display_unit(report.unit)
    fig = Figure(figsize=(9.5, 2.4 * max(n, 1) + 0.8), layout="constrained")
    axes = fig.subplots(max(n, 1), 2, squeeze=False)
    for i, (d, run) in enumerate(zip(report.directions, report.runs, strict=True)):
        traj = run.trajectory
        ax_y, ax_f = axes[i]
        ax_y.plot(traj.t, ((traj.y - report.y0) @ d) * factor, color="k", label="progress")
        ax_y.axhline(report.radius * factor, color="k", ls="--", lw=0.8, label="target (R)")
        ax_y.set_ylabel(f"progress along d [{unit}]")
        word = "reached" if run.reached else "NOT reached"
        ax_y.set_title(
            f"d = {direction_text(d, traj.output_names)}: {word}, "
            f"miss {run.miss * factor:.2g} {unit}",
            fontsize=9,
        )
        ax_y.grid(alpha=0.3)
        tension_panel(ax_f, run.time, run.tension, traj.cable_names, run.equilibrium_tension)
        if i == 0:
            ax_y.legend(fontsize=7, loc="best")
    axes[-1][0].set_xlabel("time [s]")
    axes[-1][1].set_xlabel("time [s]")
    title = (
        f"{report.model_name}, {report.pose_name or 'q'}: POC {report.verdict.upper()}, "
        f"targets at R = {report.radius * factor:.3g} {unit}"
    )
    if report.blocked_direction is not None:
        names = report.runs[0].trajectory.output_names if report.runs else ()
        title += (
            f"\nblocked direction v = {direction_text(report.blocked_direction, names)}: shown, "
            "the pull of one cable that moved the output furthest along v"
        )
        progress = report.blocked_progress()
        if progress is not None and progress <= 0:
            title += " (none moved it along v)"
    fig.suptitle(title, fontsize=10)
    if path is not None:
        fig.savefig(path, dpi=100)
    return fig
