"""Headless picture of a pose: a matplotlib projection saved as PNG, PDF or SVG.

:func:`render_pose` draws what :class:`cdpm.viewer.Viewer` shows, in 2-D
and without a browser (for papers, the README, CI artefacts): the links
(from each joint to its child joints and to the cable attachments and
output points it carries; joints as rings, centres of mass as dots), base
anchors (black squares), attachment points, the cables coloured by state
(taut: solid, blue to navy with tension; slack: dashed pink; unavailable:
dotted grey), the outputs (:mod:`cdpm.viewer.outputs`: a star coloured by
the POC verdict on each output point, named by the outputs drawn there; the
axes of the frame of an orientation output, x red, y green, z blue; a halo
in the verdict colour along a cable whose length is an output; a joint
output's name beside its joint; the values of joint and cable outputs in
the legend) and the verdict in the title. matplotlib is imported only here (``pip install
"cdpm[viz]"``); no GUI backend is used.
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError, short_str
from cdpm.plotting import check_dpi, check_image_path
from cdpm.plotting._common import matplotlib_parts
from cdpm.plotting.map_plot import MAX_DPI
from cdpm.viewer.state import (
    AXIS_RGB,
    COLORS,
    CableState,
    PoseGeometry,
    PoseState,
    cable_colors,
    centres_of_mass,
    default_pose,
    link_segments,
    pose_state,
    tension_scale,
    with_unit,
)

__all__ = [
    "render_pose",
    "check_picture_path",
    "check_picture_dpi",
    "check_picture_title",
    "PLANES",
    "MIN_PICTURE_DPI",
    "MAX_TITLE_CHARS",
]

#: lowest resolution of a pose picture [dots per inch]: below it the
#: 10-point text is under three pixels tall (and at a few dpi FreeType
#: refuses to draw it)
MIN_PICTURE_DPI = 20

#: longest custom title [characters]: about a dozen lines at the default width
MAX_TITLE_CHARS = 1000

#: Projection planes: name -> (horizontal axis, vertical axis) indices.
PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}

_CABLE_STYLE = {
    CableState.TAUT: "-",
    CableState.SLACK: (0, (5, 3)),
    CableState.UNAVAILABLE: ":",
}
#: a taut cable is drawn wider, so a slack one on the same line shows inside it
_CABLE_WIDTH = {CableState.TAUT: 3.2, CableState.SLACK: 1.8, CableState.UNAVAILABLE: 1.8}
#: length of an orientation output's axes, as a fraction of the scene's extent
_TRIAD_SIZE = 0.15


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
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: a pose name, configuration vector (nq,) or natural coordinates
            (nv,); default the spec's first pose, else neutral.
        path: write the figure there (format from the suffix: .png, .pdf,
            .svg, .jpg or any other matplotlib writes; none: .png added).
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
        InputError: unknown plane, unsupported file suffix, a dpi outside
            [MIN_PICTURE_DPI, MAX_DPI] or a title longer than MAX_TITLE_CHARS
            (checked before anything is computed).
    """
    _, Figure = matplotlib_parts("pictures", extra="viz")
    # optional: cdpm[viz/maps]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    dpi = check_picture_dpi(dpi)
    if title is not None:
        title = check_picture_title(title)
    target = None if path is None else check_picture_path(path)
    pose_name = q if isinstance(q, str) else None
    q = robot.as_q(default_pose(robot) if q is None else q)
    geometry = PoseGeometry(robot)
    state = state if state is not None else pose_state(robot, q, geometry)
    geometry.update(state.q)
    placements = geometry.joint_placements()
    cable_points = state.cable_points
    out, out_labels = geometry.output_positions(), geometry.output_labels
    # links from each joint to its child joints and to the points it carries
    bones = [
        tuple(placements[j][:3, :3] @ end + placements[j][:3, 3] for end in (a, b))
        for j, a, b in link_segments(robot)
    ]
    joints = np.array([T[:3, 3] for T in placements[1:]]).reshape(-1, 3)
    coms = np.array(
        [placements[j][:3, :3] @ c + placements[j][:3, 3] for j, c in centres_of_mass(robot.model)]
    ).reshape(-1, 3)
    everything = np.concatenate([joints, out, *cable_points, np.zeros((1, 3))])
    plane = _choose_plane(plane, everything)
    h, v = PLANES[plane]
    drawing = geometry.drawing

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
    # taut cables in order of tension, the heaviest on top (cables whose
    # projections coincide, e.g. an upper and a lower one seen from above,
    # showed the lighter one's colour); a slack one above them all
    m = len(state.cable_names)
    tension = np.zeros(m) if state.tension is None else np.nan_to_num(state.tension)
    rank = np.argsort(np.argsort(tension, kind="stable"), kind="stable")
    taut_z = 3.0 + 0.09 * rank / max(m - 1, 1)
    offset = 0
    # cable names at their anchors; cables whose anchors coincide in this
    # projection (e.g. an upper and a lower cable seen from above) share one label
    tol = 1e-6 * max(float(np.ptp(everything[:, [h, v]])), 1.0)
    groups: dict[tuple[int, ...], tuple[np.ndarray, list[tuple[int, str]]]] = {}
    for i, (name, route, rgb, cstate) in enumerate(
        zip(state.cable_names, cable_points, colors, state.cable_states, strict=True)
    ):
        (line,) = ax.plot(
            route[:, h],
            route[:, v],
            color=rgb,
            lw=_CABLE_WIDTH[cstate],
            linestyle=_CABLE_STYLE[cstate],
            zorder=taut_z[i] if cstate is CableState.TAUT else 3.1,
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
        label_at = (route[0] if on_world[0] else route[-1])[[h, v]]
        key = tuple(int(k) for k in np.round(label_at / tol))
        label = name if cstate is not CableState.TAUT else f"{name} ({state.tension[i]:.3g} N)"
        if i in drawing.cables:  # its length is an output: a halo
            (halo,) = ax.plot(
                route[:, h],
                route[:, v],
                color=state.verdict_rgb,
                lw=11,
                alpha=0.35,
                solid_capstyle="round",
                zorder=2.5,
            )
        groups.setdefault(key, (label_at, []))[1].append((i, label))

    marker = None  # a star on each output point (joint and cable outputs have none)
    if len(out):
        marker = ax.scatter(
            out[:, h],
            out[:, v],
            marker="*",
            s=260,
            color=state.verdict_rgb,
            edgecolor="0.1",
            linewidth=0.8,
            zorder=6,
        )
    frame_labels = [
        ax.annotate(
            name,
            (p[h], p[v]),
            xytext=(8, -12),
            textcoords="offset points",
            fontsize=9,
            parse_math=False,
        )
        for name, p in zip(out_labels, out, strict=True)
    ]
    extent = max(float(np.ptp(everything[:, [h, v]], axis=0).max()), 1e-9)
    triads = [
        _draw_triad(ax, T, _TRIAD_SIZE * extent, h, v)
        for T, turns in zip(
            geometry.output_placements(), geometry.output_point_rotation, strict=True
        )
        if turns
    ]
    frame_labels += [label for axes in triads for label in axes]
    for joint, names in drawing.joints.items():
        at = placements[robot.model.getJointId(joint)][:3, 3]
        frame_labels.append(
            ax.annotate(
                ", ".join(names),
                (at[h], at[v]),
                xytext=(9, 7),
                textcoords="offset points",
                fontsize=9,
                parse_math=False,
                color="0.15",
                zorder=7,
                bbox={"boxstyle": "round,pad=0.1", "facecolor": "white", "edgecolor": "none"},
            )
        )

    axes = "xyz"
    ax.set_xlabel(f"{axes[h]} [m]")
    ax.set_ylabel(f"{axes[v]} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="0.9", linewidth=0.6)
    ax.margins(0.08)
    if title is None:
        # one line for the pose if it fits, else the name above the coordinates
        head = f"{robot.spec.path.stem}" + (f", pose {pose_name!r}" if pose_name else "")
        coords, verdict = _coordinates_text(state), f"POC {_verdict_text(state)}"
        titles = [f"{head}: {coords}\n{verdict}", f"{head}\n{coords}\n{verdict}"]
    else:
        titles = [title]
    handles = [seen_states[s] for s in CableState if s in seen_states]
    legend_labels = [_state_label(s, scale) for s in CableState if s in seen_states]
    handles += _marker_handles(len(coms) > 0)
    legend_labels += [h.get_label() for h in handles[len(legend_labels) :]]
    if marker is not None:
        handles.append(marker)
        legend_labels.append(f"output point: POC {_verdict_text(state)}")
    if triads:
        handles.append(tuple(_axis_handles()))
        legend_labels.append("orientation output: its frame's axes x, y, z")
    # joint and cable outputs: their values (the picture shows where, not how much)
    for k, out in enumerate(robot.spec.outputs):
        kinds = {term.kind for term in out.terms}
        if kinds & {"joint", "cable"}:
            handles.append(halo if "cable" in kinds else _no_handle())
            legend_labels.append(
                f"{out.name} = {_number(state.output[k])} {state.output_units[k]}: "
                f"{state.output_definitions[k]}"
            )
    # under the axes: inside, any spot covers a cable, a link or a label somewhere
    legend = _legend(ax, handles, legend_labels, ncol=2)
    renderer = _renderer(fig)
    if renderer is not None and legend.get_window_extent(renderer).width > fig.bbox.width:
        legend.remove()
        legend = _legend(ax, handles, legend_labels, ncol=1)
    centre = 0.5 * (everything[:, [h, v]].min(axis=0) + everything[:, [h, v]].max(axis=0))
    labels = _CableLabels(ax, list(groups.values()), centre, frame_labels)
    for _ in range(3):  # the layout moves the axes; labels, limits and legend follow
        _fit_title(ax, titles, renderer)
        _put_under_axes(legend, renderer)
        fig.tight_layout()
        labels.settle(renderer)
    _put_under_axes(legend, renderer)
    if target is not None:
        fig.savefig(target, dpi=dpi)
    return fig


def _draw_triad(ax, T: np.ndarray, length: float, h: int, v: int) -> list:
    """The axes of a frame at its world placement T (4, 4), projected on
    the plane (h, v): arrows of ``length`` [m], x red, y green, z blue, each
    named at its tip; an axis seen end-on is named beside the origin, with
    ``(out)`` or ``(in)``: towards or away from the viewer. Returns the names."""
    origin = T[:3, 3]
    toward = np.cross(np.eye(3)[h], np.eye(3)[v])  # out of the picture
    labels = []
    for k, (name, rgb) in enumerate(zip("xyz", AXIS_RGB, strict=True)):
        axis = T[:3, k]
        tip = origin + length * axis
        if np.hypot(axis[h], axis[v]) > 0.25:
            ax.annotate(
                "",
                xy=(tip[h], tip[v]),
                xytext=(origin[h], origin[v]),
                arrowprops={"arrowstyle": "-|>", "color": rgb, "lw": 2.2, "mutation_scale": 12},
                zorder=6.5,
            )
            text, at, offset = name, (tip[h], tip[v]), (3, 3)
        else:
            side = "out" if float(axis @ toward) > 0 else "in"
            text, at, offset = f"{name} ({side})", (origin[h], origin[v]), (-8, 8)
        labels.append(
            ax.annotate(
                text,
                at,
                xytext=offset,
                textcoords="offset points",
                ha="right" if offset[0] < 0 else "left",
                fontsize=8,
                color=rgb,
                fontweight="bold",
                zorder=7,
                bbox={
                    "boxstyle": "round,pad=0.05",
                    "facecolor": "white",
                    "edgecolor": "none",
                    "alpha": 0.7,
                },
            )
        )
    return labels


def _marker_handles(coms: bool) -> list:
    """Legend entries of the picture's markers: joints, anchors on the
    base, attachment points on the links and (``coms``) centres of mass."""
    # optional: cdpm[viz/maps]
    from matplotlib.lines import Line2D

    def point(label: str, **style) -> Line2D:
        return Line2D([], [], ls="", label=label, **style)

    handles = [
        point("joint", marker="o", ms=7, mfc="white", mec=COLORS["joint"], mew=1.8),
        point("cable anchor on the base", marker="s", ms=6, color=COLORS["anchor"]),
        point("cable attachment on a link", marker="o", ms=4, color=COLORS["attachment"]),
    ]
    if coms:
        handles.append(point("link centre of mass", marker="o", ms=3, color=COLORS["com"]))
    return handles


def _axis_handles() -> list:
    """Legend handles of a triad: three short lines in the axes' colours."""
    # optional: cdpm[viz/maps]
    from matplotlib.lines import Line2D

    return [Line2D([], [], color=rgb, lw=2.0) for rgb in AXIS_RGB]


def _no_handle():
    """A legend handle that draws nothing (an entry that is only text)."""
    # optional: cdpm[viz/maps]
    from matplotlib.lines import Line2D

    return Line2D([], [], linestyle="none")


def _legend(ax, handles: list, labels: list[str], ncol: int):
    # optional: cdpm[viz/maps]
    from matplotlib.legend_handler import HandlerTuple

    legend = ax.legend(
        handles,
        labels,
        loc="upper center",
        fontsize=8,
        ncol=ncol,
        frameon=False,
        handler_map={tuple: HandlerTuple(ndivide=None, pad=0.0)},
    )
    for text in legend.get_texts():  # names are drawn as written, never as maths
        text.set_parse_math(False)
    return legend


def check_picture_dpi(dpi: Any) -> float:
    """``dpi`` as a float, when it is a resolution a picture can be drawn at.

    Raises:
        InputError: it is not a number from MIN_PICTURE_DPI to MAX_DPI.
    """
    value = check_dpi(dpi)
    if value < MIN_PICTURE_DPI:
        raise InputError(
            f"dpi={short_str(dpi, 40)} is too low for a picture: its text would be under three "
            "pixels tall; "
            f"give {MIN_PICTURE_DPI} to {MAX_DPI} dots per inch (the default is 110)"
        )
    return value


def check_picture_title(title: Any) -> str:
    """``title`` as a string, when it is short enough to show on a picture.

    Raises:
        InputError: it has more than MAX_TITLE_CHARS characters.
    """
    text = str(title)
    if len(text) > MAX_TITLE_CHARS:
        raise InputError(
            f"the title has {len(text):,} characters, more than the {MAX_TITLE_CHARS:,} a "
            "picture can show; shorten it"
        )
    return text


def check_picture_path(path: str | os.PathLike) -> Path:
    """The file a picture saved at ``path`` is written to: as a map plot
    (:func:`cdpm.plotting.check_image_path`, the one list of image formats:
    every extension matplotlib writes, .png, .pdf, .svg, .jpg, ...; none
    adds .png).

    Raises:
        MissingExtraError: matplotlib is not installed.
        InputError: ``path`` is a folder, its folder does not exist or is not
            writable, or matplotlib cannot write its extension (the message
            lists those it can).
    """
    matplotlib_parts("pictures", extra="viz")  # its hint names this extra
    return check_image_path(path)


def _put_under_axes(legend, renderer) -> None:
    """Anchor a legend just below its axes' tick labels and x label."""
    ax = legend.axes
    y = -0.13  # without a renderer: about one label's height
    if renderer is not None:
        bottom = ax.xaxis.get_tightbbox(renderer).y0 - 2
        y = ax.transAxes.inverted().transform((0, bottom))[1]
    legend.set_bbox_to_anchor((0.5, y), transform=ax.transAxes)


def _renderer(fig):
    """The figure's renderer, or None when its canvas has none (no fitting then)."""
    get = getattr(fig.canvas, "get_renderer", None)
    return get() if get is not None else None


def _number(x: float) -> str:
    return f"{float(x) + 0.0:.3g}"  # + 0.0: no "-0"


def _coordinates_text(state: PoseState) -> str:
    """``q1=0.524, q2=1.05``; coordinates of one joint (``joint.x``, ...) are
    grouped: ``joint: x=0, y=0, z=1, roll=0, pitch=0, yaw=0``."""
    parts: list[str] = []
    joint = None
    for name, value in zip(state.coordinate_names, state.natural, strict=True):
        prefix, dot, component = name.rpartition(".")
        if dot and prefix == joint:
            parts[-1] += f", {component}={_number(value)}"
        elif dot:
            parts.append(f"{prefix}: {component}={_number(value)}")
        else:
            parts.append(f"{name}={_number(value)}")
        joint = prefix if dot else None
    grouped = any("." in name for name in state.coordinate_names)
    return ("; " if grouped else ", ").join(parts)


def _fit_title(ax, titles: list[str], renderer, fontsize: float = 10) -> None:
    """Set the first of ``titles`` that fits the figure's width, else the
    last one wrapped (at spaces) until it fits."""

    def fits() -> bool:
        box, figure = ax.title.get_window_extent(renderer), ax.figure.bbox
        return box.x0 >= figure.x0 and box.x1 <= figure.x1

    for title in titles:
        ax.set_title(title, fontsize=fontsize, parse_math=False)
        if renderer is None or fits():
            return
    lines = titles[-1].splitlines()
    width = max(len(line) for line in lines)
    while width > 12 and not fits():
        box = ax.title.get_window_extent(renderer)
        # at least 12: a word longer than a line does not shrink the box, and
        # the width would otherwise fall to 0
        width = max(12, min(width - 1, int(width * ax.figure.bbox.width / box.width * 0.95)))
        wrapped = (
            textwrap.fill(line, width, break_long_words=False, break_on_hyphens=False)
            for line in lines
        )
        ax.set_title("\n".join(wrapped), fontsize=fontsize, parse_math=False)


#: most cable names one merged label lists before "and N more"
LABEL_MAX_NAMES = 4


class _CableLabels:
    """Cable names at their anchors (above those in the upper half of the
    scene, below the others, running towards the middle); labels whose boxes
    overlap are merged into one, and the axis limits grow until every label
    is inside the axes.

    Args:
        ax: the axes.
        groups: (projected point, [(cable index, label text), ...]) per anchor.
        centre: projected centre of the scene.
        obstacles: other texts the labels must not cover (output frame names).
    """

    def __init__(self, ax, groups, centre, obstacles) -> None:
        self.ax, self.centre, self.obstacles = ax, np.asarray(centre), obstacles
        self.groups = [(np.asarray(p, dtype=float), list(names)) for p, names in groups]
        self.texts = [self._annotate(p, names) for p, names in self.groups]

    def _annotate(self, point, names):
        # above an anchor in the upper half, below one in the lower half, and
        # running towards the middle: labels stay clear of the frame
        d = point - self.centre
        scale = max(float(np.abs(d).max()), 1e-12)
        inward = 0 if abs(d[0]) < 0.05 * scale else -int(np.sign(d[0]))
        up = 1 if d[1] >= -0.05 * scale else -1
        texts = [text for _, text in sorted(names)]
        if len(texts) > LABEL_MAX_NAMES:  # a long line would run off the figure
            texts = texts[: LABEL_MAX_NAMES - 1] + [f"and {len(texts) - LABEL_MAX_NAMES + 1} more"]
        return self.ax.annotate(
            ", ".join(texts),
            tuple(point),
            parse_math=False,
            xytext=(-3 * inward, 6 * up),
            textcoords="offset points",
            ha={1: "left", 0: "center", -1: "right"}[inward],
            va="bottom" if up > 0 else "top",
            fontsize=9,
            color="0.15",
            zorder=7,
            bbox={
                "boxstyle": "round,pad=0.1",
                "facecolor": "white",
                "edgecolor": "none",
                "alpha": 0.7,
            },
        )

    def _merge_one(self, renderer) -> bool:
        boxes = [t.get_window_extent(renderer) for t in self.texts]
        for i in range(len(boxes)):
            for j in range(i):
                if boxes[i].overlaps(boxes[j]):
                    (pi, ni), (pj, nj) = self.groups[i], self.groups[j]
                    for k in (i, j):  # i > j: remove the later one first
                        self.texts.pop(k).remove()
                        self.groups.pop(k)
                    merged = ((len(ni) * pi + len(nj) * pj) / (len(ni) + len(nj)), nj + ni)
                    self.groups.append(merged)
                    self.texts.append(self._annotate(*merged))
                    return True
        return False

    def _fit_limits(self, renderer) -> bool:
        ax = self.ax
        ax.apply_aspect()
        frame = ax.get_window_extent(renderer)
        boxes = [t.get_window_extent(renderer) for t in self.texts + self.obstacles]
        # a label wider or taller than half the axes cannot be brought inside by
        # growing the limits (its size is in points): it is left to overflow
        boxes = [b for b in boxes if b.width < frame.width / 2 and b.height < frame.height / 2]
        if all(frame.containsx(b.x0) and frame.containsx(b.x1) for b in boxes) and all(
            frame.containsy(b.y0) and frame.containsy(b.y1) for b in boxes
        ):
            return False
        inverse = ax.transData.inverted()
        corners = [inverse.transform([[b.x0, b.y0], [b.x1, b.y1]]) for b in boxes]
        ax.update_datalim(np.concatenate(corners))
        ax.autoscale_view()
        return True

    def settle(self, renderer) -> None:
        """Merge overlapping labels and grow the limits until neither changes."""
        if renderer is None:
            return
        for _ in range(4 * len(self.texts) + 8):
            if not (self._merge_one(renderer) or self._fit_limits(renderer)):
                return


def _verdict_text(state: PoseState) -> str:
    if state.verdict is None:
        return "unavailable"
    margin = ""
    if state.margin is not None and not np.isfinite(state.margin):
        margin = " (r_T not computed)"
    elif state.margin is not None:
        margin = f" (r_T {with_unit(_number(state.margin), state.margin_unit)})"
    return f"{str(state.verdict).upper()}{margin}"


def _state_label(s: CableState, scale: float) -> str:
    if s is CableState.TAUT:
        return f"taut (darker: more tension, navy = {scale:.3g} N)"
    if s is CableState.SLACK:
        return "slack (at lower tension bound)"
    return "no equilibrium / not linearised"
