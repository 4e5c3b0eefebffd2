"""Headless picture of a pose: a matplotlib projection saved as PNG, PDF or SVG.

:func:`render_pose` draws what :class:`cdpm.viewer.Viewer` shows, in 2-D
and without a browser (for papers, the README, CI artefacts): the links
(joint to joint, joints as rings, centres of mass as dots), base anchors
(black squares), attachment points, the cables coloured by state (taut:
solid, blue to navy with tension; slack: dashed pink; unavailable: dotted
grey), the output frame (a star coloured by the POC verdict) and the
verdict in the title. matplotlib is imported only here
(``pip install "cdpm[viz]"``); no GUI backend is used.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError, MissingExtraError
from cdpm.viewer import (
    COLORS,
    CableState,
    PoseState,
    _coms,
    _default_pose,
    _Geometry,
    _skeleton,
    cable_colors,
    pose_state,
    tension_scale,
)

__all__ = ["render_pose", "PLANES"]

#: Projection planes: name -> (horizontal axis, vertical axis) indices.
PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}

_CABLE_STYLE = {
    CableState.TAUT: "-",
    CableState.SLACK: (0, (5, 3)),
    CableState.UNAVAILABLE: ":",
}


def _import_matplotlib():
    try:
        import matplotlib  # noqa: F401
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise MissingExtraError(
            f'pictures need matplotlib ({exc}); install it with: pip install "cdpm[viz]"'
        ) from exc
    return Figure, FigureCanvasAgg


def _choose_plane(plane: str, points: np.ndarray) -> str:
    if plane != "auto":
        if plane not in PLANES:
            raise InputError(f"plane={plane!r}; use 'auto', {', '.join(map(repr, PLANES))}")
        return plane
    normal = int(np.argmin(np.ptp(points, axis=0)))
    return {2: "xy", 1: "xz", 0: "yz"}[normal]


def render_pose(
    robot,
    q: Any = None,
    path: str | os.PathLike | None = None,
    *,
    plane: str = "auto",
    title: str | None = None,
    ax=None,
    figsize: tuple[float, float] = (6.4, 5.0),
    dpi: int = 110,
    state: PoseState | None = None,
):
    """Draw the robot, its cables and the POC verdict at q, projected on a plane.

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: a pose name, configuration vector (nq,) or natural coordinates
            (nv,); default the spec's first pose, else neutral.
        path: write the figure there (format from the suffix: .png, .pdf, .svg).
        plane: ``"xy"``, ``"xz"``, ``"yz"`` (world axes) or ``"auto"``: the
            plane across the scene's thinnest world axis.
        title: figure title; default names the model, the pose and the verdict.
        ax: draw into this matplotlib Axes instead of a new figure.
        figsize, dpi: size [in] and resolution of a new figure.
        state: a :class:`~cdpm.viewer.PoseState` already computed at q.

    Returns:
        The matplotlib ``Figure``.

    Raises:
        MissingExtraError: matplotlib is not installed.
        InputError: unknown plane or unsupported file suffix.
    """
    Figure, FigureCanvasAgg = _import_matplotlib()
    pose_name = q if isinstance(q, str) else None
    q = robot.as_q(_default_pose(robot) if q is None else q)
    geometry = _Geometry(robot)
    state = state if state is not None else pose_state(robot, q, geometry)
    geometry.update(state.q)
    placements = geometry.joint_placements()
    bones = [
        (
            placements[j][:3, :3] @ a + placements[j][:3, 3],
            placements[j][:3, :3] @ b + placements[j][:3, 3],
        )
        for j, a, b in _skeleton(robot.model)
    ]
    joints = np.array([T[:3, 3] for T in placements[1:]]).reshape(-1, 3)
    coms = np.array(
        [placements[j][:3, :3] @ c + placements[j][:3, 3] for j, c in _coms(robot.model)]
    ).reshape(-1, 3)
    cable_points = state.cable_points
    everything = np.concatenate(
        [joints, state.output_frame_positions, *cable_points, np.zeros((1, 3))]
    )
    plane = _choose_plane(plane, everything)
    h, v = PLANES[plane]

    if ax is None:
        fig = Figure(figsize=figsize, dpi=dpi)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
    else:
        fig = ax.figure

    scale = tension_scale(robot, state.tension)
    colors = cable_colors(state, scale)
    for bone in bones:
        ax.plot(
            [bone[0][h], bone[1][h]],
            [bone[0][v], bone[1][v]],
            color=COLORS["link"],
            lw=7,
            solid_capstyle="round",
            zorder=2,
        )
    ax.scatter(
        joints[:, h],
        joints[:, v],
        s=60,
        facecolor="white",
        edgecolor=COLORS["joint"],
        linewidth=1.8,
        zorder=4,
    )
    if len(coms):
        ax.scatter(coms[:, h], coms[:, v], s=14, color=COLORS["com"], zorder=4)

    seen_states: dict[CableState, Any] = {}
    fixed = geometry.point_joint == 0
    offset = 0
    for i, (name, route, rgb, cstate) in enumerate(
        zip(state.cable_names, cable_points, colors, state.cable_states, strict=True)
    ):
        (line,) = ax.plot(
            route[:, h], route[:, v], color=rgb, lw=2.2, linestyle=_CABLE_STYLE[cstate], zorder=3
        )
        seen_states.setdefault(cstate, line)
        on_world = fixed[offset : offset + len(route)]
        offset += len(route)
        ax.scatter(
            route[on_world, h],
            route[on_world, v],
            marker="s",
            s=42,
            color=COLORS["anchor"],
            zorder=5,
        )
        ax.scatter(
            route[~on_world, h], route[~on_world, v], s=18, color=COLORS["attachment"], zorder=5
        )
        label_at = route[0] if on_world[0] else route[-1]
        label = name if cstate is not CableState.TAUT else f"{name} ({state.tension[i]:.3g} N)"
        ax.annotate(
            label,
            (label_at[h], label_at[v]),
            xytext=(-6, 4),
            textcoords="offset points",
            ha="right",
            fontsize=9,
            color="0.15",
        )

    verdict_rgb = COLORS[state.verdict_key]
    out = state.output_frame_positions
    marker = ax.scatter(
        out[:, h],
        out[:, v],
        marker="*",
        s=260,
        color=verdict_rgb,
        edgecolor="0.1",
        linewidth=0.8,
        zorder=6,
    )
    for name, p in zip(state.output_frames, out, strict=True):
        ax.annotate(name, (p[h], p[v]), xytext=(8, -12), textcoords="offset points", fontsize=9)

    handles = [seen_states[s] for s in CableState if s in seen_states]
    labels = [_state_label(s, scale) for s in CableState if s in seen_states]
    handles.append(marker)
    labels.append(f"output: POC {_verdict_text(state)}")
    ax.legend(handles, labels, loc="best", fontsize=8, framealpha=0.9)

    axes = "xyz"
    ax.set_xlabel(f"{axes[h]} [m]")
    ax.set_ylabel(f"{axes[v]} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="0.9", linewidth=0.6)
    ax.margins(0.08)
    if title is None:
        coords = ", ".join(
            f"{n}={x:.3g}" for n, x in zip(state.coordinate_names, state.natural, strict=True)
        )
        where = f", pose {pose_name!r}" if pose_name else ""
        title = f"{robot.spec.path.stem}{where}: {coords}\nPOC {_verdict_text(state)}"
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    if path is not None:
        target = Path(path)
        suffix = target.suffix.lower()
        if suffix not in (".png", ".pdf", ".svg"):
            raise InputError(f"picture file {target.name!r}: use a .png, .pdf or .svg name")
        fig.savefig(target, dpi=dpi)
    return fig


def _verdict_text(state: PoseState) -> str:
    if state.verdict is None:
        return "unavailable"
    margin = "" if state.margin is None else f" (margin {state.margin:.3g})"
    return f"{str(state.verdict).upper()}{margin}"


def _state_label(s: CableState, scale: float) -> str:
    if s is CableState.TAUT:
        return f"taut (darker: more tension, navy = {scale:.3g} N)"
    if s is CableState.SLACK:
        return "slack (at lower tension bound)"
    return "no equilibrium / not linearised"
