"""What the viewer and the picture show at one pose, without meshcat.

:func:`pose_state` computes the positions, tensions, cable states and POC
verdict at a pose as a :class:`PoseState`; the 3-D view
(:class:`cdpm.viewer.Viewer`), the headless picture (:mod:`cdpm.plotting.picture`)
and the text panel of :class:`cdpm.viewer.PoseInspector` all draw it.
:class:`PoseGeometry` gives the world positions they draw;
:func:`link_segments` the generated links (from each joint to its child
joints, :func:`skeleton_segments`, and to the points its link carries) and
:func:`centres_of_mass` their centres of mass; :func:`mesh_package_dirs`
the folders holding the URDF's meshes and :func:`meshes_outside` the meshes
the viewer refuses to load; :data:`COLORS` the colours (verdict
colours from :mod:`cdpm.verdicts`).

Pinocchio is imported when a :class:`PoseGeometry` is made, not here.
"""

from __future__ import annotations

import enum
import html
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium.statics import classify
from cdpm.dynamics.linearisation import linearise
from cdpm.dynamics.reach import reach_margins_at, reach_unit
from cdpm.errors import CdpmError, InputError
from cdpm.model.spec import WORLD_FRAME_NAMES, package_share_directory
from cdpm.verdicts import VERDICT_CODES, VERDICT_RGB, verdict_code
from cdpm.viewer.outputs import OutputDrawing, output_drawing

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = [
    "CableState",
    "PoseState",
    "PoseGeometry",
    "pose_state",
    "skeleton_segments",
    "link_segments",
    "centres_of_mass",
    "mesh_package_dirs",
    "meshes_outside",
    "default_pose",
    "tension_scale",
    "cable_colors",
    "tension_colors",
    "COLORS",
    "AXIS_RGB",
]

#: RGB colours (0..1) of the drawing, shared by the 3-D view and the picture:
#: cable states, links and points, and the verdicts (``"yes"``, ``"no"``,
#: ``"marginal"``, ``"not_analysed"``: :data:`cdpm.verdicts.VERDICT_RGB`).
COLORS: dict[str, tuple[float, float, float]] = {
    "slack": (0.890, 0.467, 0.761),  # pink
    "taut_low": (0.420, 0.682, 0.839),  # light blue (low tension)
    "taut_high": (0.031, 0.188, 0.420),  # navy (tension at the scale)
    "unavailable": (0.55, 0.55, 0.55),
    **{name: VERDICT_RGB[code] for name, code in VERDICT_CODES.items()},
    "link": (0.62, 0.64, 0.68),
    "joint": (0.35, 0.35, 0.38),
    "com": (0.15, 0.15, 0.15),
    "anchor": (0.10, 0.10, 0.10),
    "attachment": (0.35, 0.35, 0.35),
}

#: RGB colours (0..1) of a frame's x, y and z axes in an orientation output's triad.
AXIS_RGB: tuple[tuple[float, float, float], ...] = (
    (0.86, 0.13, 0.13),
    (0.13, 0.62, 0.20),
    (0.15, 0.33, 0.86),
)


class CableState(enum.StrEnum):
    """State of a cable at the displayed equilibrium."""

    TAUT = "taut"
    SLACK = "slack"
    UNAVAILABLE = "unavailable"


@dataclass(frozen=True)
class PoseState:
    """Everything the viewer and the picture show at one pose (world frame).

    Attributes:
        q: configuration vector, shape (nq,).
        natural: natural coordinates, shape (nv,) [rad or m].
        coordinate_names: names of the nv natural coordinates.
        cable_names: names of the m cables.
        cable_points: world positions of each cable's route points [m], one
            array of shape (k_i, 3) per cable.
        cable_states: :class:`CableState` of each cable, shape (m,).
        tension: equilibrium tensions f* [N], shape (m,), or None when unavailable.
        output_names: names of the p outputs.
        output: outputs y, shape (p,), each in its unit (``output_units``):
            the robot's own (:meth:`~cdpm.model.robot.CableRobot.output`).
        output_units: unit of each output (``"m"``, ``"rad"``, or the spec's).
        output_kinds: kind of each output: ``position``, ``rotation``,
            ``joint``, ``cable`` or ``sum``
            (:func:`~cdpm.viewer.outputs.output_kind`).
        output_definitions: each output as a formula (``tip.x``,
            ``platform.rz``, ``joint joint2``, ``cable c1``,
            ``0.5 link1.x + 0.5 tip.x``).
        output_frames: frame of each point at which outputs are drawn
            (:class:`~cdpm.viewer.outputs.OutputPoint`: each distinct point
            once, in the order of the outputs; a frame carrying two points
            appears twice; joint and cable outputs have none).
        output_frame_positions: world positions [m] of those output points
            (an output's ``point`` in its frame, not the frame's origin),
            shape (n_output_points, 3).
        verdict: POC verdict (:class:`cdpm.analysis.Verdict`) or None when unavailable.
        margin: reach margin r_T in :attr:`margin_unit`
            (:mod:`cdpm.dynamics.reach`; positive when POC
            within the model's horizon) or None.
        reason: why tensions or the verdict are unavailable, else None.
    """

    q: np.ndarray
    natural: np.ndarray
    coordinate_names: tuple[str, ...]
    cable_names: tuple[str, ...]
    cable_points: tuple[np.ndarray, ...]
    cable_states: tuple[CableState, ...]
    tension: np.ndarray | None
    output_names: tuple[str, ...]
    output: np.ndarray
    output_units: tuple[str, ...]
    output_kinds: tuple[str, ...]
    output_definitions: tuple[str, ...]
    output_frames: tuple[str, ...]
    output_frame_positions: np.ndarray
    verdict: Any
    margin: float | None
    reason: str | None

    @property
    def margin_unit(self) -> str:
        """The unit of the reach margin: the outputs' common unit (``"m"``,
        ``"rad"``), else e.g. ``"m and rad, one to one"``
        (:func:`cdpm.dynamics.reach.reach_unit`)."""

        return reach_unit(self.output_units)

    @property
    def verdict_key(self) -> str:
        """``"yes"``, ``"no"``, ``"marginal"`` or ``"unavailable"``."""
        return "unavailable" if self.verdict is None else self.verdict.value

    @property
    def verdict_code(self) -> int:
        """The verdict's code in :mod:`cdpm.verdicts` (``NOT_ANALYSED`` when unavailable)."""
        return verdict_code(self.verdict)

    @property
    def verdict_rgb(self) -> tuple[float, float, float]:
        """Colour (r, g, b in 0..1) of the verdict: the output marker's, the
        map overlay's and the plots' (:data:`cdpm.verdicts.VERDICT_RGB`)."""
        return VERDICT_RGB[self.verdict_code]

    @property
    def slack_cables(self) -> tuple[str, ...]:
        """Names of the cables at their lower tension bound."""
        return tuple(
            n
            for n, s in zip(self.cable_names, self.cable_states, strict=True)
            if s is CableState.SLACK
        )

    def as_dict(self) -> dict:
        """JSON-serialisable content."""
        return {
            "q": self.q.tolist(),
            "coordinates": dict(zip(self.coordinate_names, self.natural.tolist(), strict=True)),
            "output": dict(zip(self.output_names, self.output.tolist(), strict=True)),
            "output_units": dict(zip(self.output_names, self.output_units, strict=True)),
            "verdict": self.verdict_key,
            "margin": self.margin,
            "reason": self.reason,
            "cables": [
                {
                    "name": name,
                    "state": state.value,
                    "tension": None if self.tension is None else float(self.tension[i]),
                    "points": self.cable_points[i].tolist(),
                }
                for i, (name, state) in enumerate(
                    zip(self.cable_names, self.cable_states, strict=True)
                )
            ],
        }

    def _verdict_line(self) -> str:
        if self.verdict is None:
            return f"POC: unavailable ({self.reason})"
        margin = ""
        if self.margin is not None:
            margin = f" (reach margin {with_unit(f'{self.margin:.4g}', self.margin_unit)})"
        return f"POC: {str(self.verdict).upper()}{margin}"

    def __str__(self) -> str:
        coords = ", ".join(
            f"{n} = {v:.4f}" for n, v in zip(self.coordinate_names, self.natural, strict=True)
        )
        lines = [self._verdict_line(), f"pose: {coords}", f"outputs: {self.outputs_text()}"]
        for i, (name, state) in enumerate(zip(self.cable_names, self.cable_states, strict=True)):
            f = "    -" if self.tension is None else f"{self.tension[i]:9.4g} N"
            lines.append(f"  {name:<10} {f}  {state.value}")
        slack = ", ".join(self.slack_cables) or "none"
        lines.append(f"slack cables: {slack}")
        return "\n".join(lines)

    def outputs_text(self) -> str:
        """The outputs with their units, ``tip_x = 0.8660 m, elbow = 1.0472 rad
        (joint joint2)``: the formula of each output that is not one point
        coordinate (an orientation, joint or cable output, a sum)."""
        return (
            ", ".join(
                output_line(*row)
                for row in zip(
                    self.output_names,
                    self.output,
                    self.output_units,
                    self.output_kinds,
                    self.output_definitions,
                    strict=True,
                )
            )
            or "(none)"
        )

    def _repr_html_(self) -> str:
        r, g, b = (int(255 * c) for c in self.verdict_rgb)
        head = html.escape(self._verdict_line())
        body = html.escape("\n".join(str(self).splitlines()[1:]))
        return (
            f'<div><b style="color: rgb({r},{g},{b})">{head}</b>'
            f'<pre style="margin: 0.3em 0">{body}</pre></div>'
        )


def with_unit(value: str, unit: str) -> str:
    """``"0.15 m"``; with a unit of several (``"m and rad, one to one"``)
    ``"0.15 [m and rad, one to one]"``."""
    return f"{value} [{unit}]" if "," in unit else f"{value} {unit}"


def output_line(name: str, value: float, unit: str, kind: str, definition: str) -> str:
    """``tip_x = 0.8660 m``; an output of another kind than ``position``
    (:func:`~cdpm.viewer.outputs.output_kind`) with its formula:
    ``elbow = 1.0472 rad (joint joint2)``."""
    text = f"{name} = {value:.4f} {unit}"
    return text if kind == "position" else f"{text} ({definition})"


class PoseGeometry:
    """World positions the drawings need at one pose.

    Route points are read from the spec (frame + point in frame), so this
    never fails, not even at poses where a cable has zero length. The output
    points and outputs are the robot's own
    (:meth:`~cdpm.model.robot.CableRobot.kinematics_batch`, the points
    :attr:`~cdpm.model.robot.CableRobot.output_points` names); an output point is
    where outputs are drawn (:mod:`cdpm.viewer.outputs`): a position
    output's point, an orientation output's frame origin, a sum's first
    position or orientation term; joint and cable outputs have none. Call
    :meth:`update` with a configuration, then read the positions.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.

    Attributes:
        model: the robot's Pinocchio model; ``data`` its data at the last update.
        route_slices: for each cable, its route points' rows in :meth:`points`.
        point_frames: frame id of each route point (-1: the world), shape (n_points,).
        point_local: each route point in its frame [m], shape (n_points, 3).
        point_joint: parent joint of each route point's frame (0: fixed to
            the world, an anchor), shape (n_points,).
        drawing: how each output is drawn
            (:class:`~cdpm.viewer.outputs.OutputDrawing`).
        output_frames: frame of each output point (outputs of the same
            frame and point share one).
        output_labels: per output point, the names of the outputs drawn
            there (``"tip_y, tip_z"``).
        output_point_names: a distinct name per output point: its frame's
            name, ``"<frame>.<k>"`` for the k-th point of a frame (k >= 2).
        output_point_rotation: per output point, whether an orientation
            output is drawn there (with its frame's axes).
        output_frame_ids: frame id of each output point's frame (-1: the world).
        output: outputs y at the last update, shape (p,), each in its unit
            (:attr:`~cdpm.model.robot.CableRobot.output_units`).
    """

    def __init__(self, robot: CableRobot) -> None:
        # pinocchio: loaded on first use
        import pinocchio as pin

        self._pin = pin
        self._robot = robot
        self.model = robot.model
        self.data = self.model.createData()
        frames: list[int] = []  # -1: world
        local: list[np.ndarray] = []
        self.route_slices: list[slice] = []
        for cable in robot.spec.cables:
            start = len(frames)
            for point in cable.route:
                frames.append(self._frame_id(point.frame))
                local.append(np.array(point.point_in_frame, dtype=float))
            self.route_slices.append(slice(start, len(frames)))
        self.point_frames = np.array(frames, dtype=int)
        self.point_local = np.array(local, dtype=float).reshape(-1, 3)
        self.drawing: OutputDrawing = output_drawing(robot)
        marks = self.drawing.points
        self.output_frames = tuple(point.frame for point in marks)
        self.output_point_names = tuple(point.name for point in marks)
        self.output_labels = tuple(point.label for point in marks)
        self.output_point_rotation = tuple(point.rotation for point in marks)
        self.output_frame_ids = [self._frame_id(n) for n in self.output_frames]
        self._output_tracked = np.array([point.tracked for point in marks], dtype=int)
        self._output_world = np.zeros((len(marks), 3))
        self.output = np.zeros(len(robot.spec.outputs))
        # a route point is fixed to the world when its frame's parent joint is the universe
        self.point_joint = np.array(
            [0 if f < 0 else int(self.model.frames[f].parentJoint) for f in frames], dtype=int
        )

    def _frame_id(self, name: str) -> int:
        return -1 if name in WORLD_FRAME_NAMES else int(self.model.getFrameId(name))

    def update(self, q: np.ndarray) -> None:
        """Forward kinematics, frame placements and output points at q (nq,)."""
        self._pin.framesForwardKinematics(self.model, self.data, q)
        # the robot's tracked points: route points, then output points
        kin = self._robot.kinematics_batch(np.asarray(q, dtype=float)[None, :])
        self._output_world = np.array(kin.point_positions[0, self._output_tracked]).reshape(-1, 3)
        self.output = np.array(kin.output[0], dtype=float)

    def _place(self, frame: int, local: np.ndarray) -> np.ndarray:
        if frame < 0:
            return local.copy()
        oMf = self.data.oMf[frame]
        return oMf.rotation @ local + oMf.translation

    def points(self) -> np.ndarray:
        """World positions of all route points [m], shape (n_points, 3)."""
        out = np.empty_like(self.point_local)
        for k, (f, p) in enumerate(zip(self.point_frames, self.point_local, strict=True)):
            out[k] = self._place(int(f), p)
        return out

    def output_positions(self) -> np.ndarray:
        """World positions of the output points [m], shape (n_output_points, 3):
        the points the position outputs measure, the frame origins of
        orientation outputs."""
        return self._output_world.copy()

    def output_placements(self) -> list[np.ndarray]:
        """Homogeneous world placements (4, 4) of the output points: the
        orientation of the output's frame, the origin on the output point."""
        placements = []
        for f, position in zip(self.output_frame_ids, self.output_positions(), strict=True):
            T = np.eye(4) if f < 0 else np.array(self.data.oMf[f].homogeneous)
            T[:3, 3] = position
            placements.append(T)
        return placements

    def joint_placements(self) -> list[np.ndarray]:
        """Homogeneous world placement (4, 4) of every joint (index 0: universe)."""
        return [np.asarray(self.data.oMi[j].homogeneous) for j in range(self.model.njoints)]


def skeleton_segments(model) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """Generated link geometry: segments (joint, start, end) in the joint's frame.

    A joint gets a segment to each child joint and, when it has none, to its
    farthest frame (e.g. a tool tip), so a serial arm draws as a chain.

    Args:
        model: a Pinocchio model (``robot.model``).

    Returns:
        ``(joint index, start (3,), end (3,))`` per segment; start and end
        [m] in the frame of that joint (world = its placement at the pose).
    """
    children: dict[int, list[int]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[int(model.parents[j])].append(j)
    bones: list[tuple[int, np.ndarray, np.ndarray]] = []
    for j in range(model.njoints):
        ends = [np.array(model.jointPlacements[c].translation) for c in children[j]]
        if not ends and j > 0:
            tips = [
                np.array(f.placement.translation) for f in model.frames if int(f.parentJoint) == j
            ]
            if tips:
                ends = [max(tips, key=lambda p: float(np.linalg.norm(p)))]
        for end in ends:
            if np.linalg.norm(end) > 1e-9:
                bones.append((j, np.zeros(3), end))
    return bones


def _carried_points(robot: CableRobot) -> list[tuple[int, np.ndarray]]:
    """(joint, point in the joint's frame [m]) of every cable route point
    and point of a position or orientation output term, in spec order (joint
    0: fixed to the world)."""

    model = robot.model
    named = [(p.frame, p.point_in_frame) for c in robot.spec.cables for p in c.route]
    named += [
        (t.frame, t.point_in_frame)
        for o in robot.spec.outputs
        for t in o.terms
        if t.kind in ("position", "rotation")
    ]
    carried = []
    for frame_name, point in named:
        local = np.array(point, dtype=float)
        if frame_name in WORLD_FRAME_NAMES:
            carried.append((0, local))
            continue
        frame = model.frames[model.getFrameId(frame_name)]
        carried.append((int(frame.parentJoint), np.asarray(frame.placement.act(local))))
    return carried


def link_segments(robot: CableRobot) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """Generated link geometry: the segments that draw each link.

    Each link is drawn from its joint to its child joints (or, with none,
    to its farthest frame: :func:`skeleton_segments`) and to every point it
    carries (cable attachments, output points), so a link with no child
    joint, e.g. the last link of a chain, still shows. The 3-D view and the
    picture both draw these.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.

    Returns:
        ``(joint index, start (3,), end (3,))`` per segment; start and end
        [m] in the frame of that joint (world = its placement at the pose).
    """
    segments = skeleton_segments(robot.model)
    drawn = {(j, *np.round(end, 9)) for j, _, end in segments}
    for j, point in _carried_points(robot):
        key = (j, *np.round(point, 9))
        if j > 0 and key not in drawn and np.linalg.norm(point) > 1e-9:
            drawn.add(key)
            segments.append((j, np.zeros(3), point))
    return segments


def centres_of_mass(model) -> list[tuple[int, np.ndarray]]:
    """(joint, centre of mass in the joint's frame) of every joint carrying mass.

    Args:
        model: a Pinocchio model (``robot.model``).

    Returns:
        ``(joint index, centre of mass (3,) [m] in that joint's frame)`` for
        each joint whose body has a positive mass.
    """
    return [
        (j, np.array(model.inertias[j].lever))
        for j in range(1, model.njoints)
        if model.inertias[j].mass > 0
    ]


def mesh_package_dirs(urdf_path: str | Path) -> list[Path]:
    """Folders in which Pinocchio looks for the URDF's meshes.

    A mesh ``package://NAME/REL`` is found at ``DIR/NAME/REL`` for one of
    these folders: the URDF's own folder, and for each package the URDF
    names, the folder holding that package (its installed share directory,
    :func:`cdpm.model.spec.package_share_directory`, e.g. example-robot-data's
    ``cmeel.prefix/share``, or $ROS_PACKAGE_PATH / $AMENT_PREFIX_PATH; or an
    enclosing folder of the URDF named after the package).

    Args:
        urdf_path: the URDF file.

    Returns:
        The folders, each once, the URDF's own first.
    """

    urdf = Path(urdf_path).resolve()
    dirs = [urdf.parent]
    text = urdf.read_text(errors="replace")
    for name in dict.fromkeys(re.findall(r"package://([^/\"'\s]+)/", text)):
        share = package_share_directory(name)
        if share is not None:
            dirs.append(share.parent)
        dirs += [folder.parent for folder in urdf.parents if folder.name == name]
    return list(dict.fromkeys(dirs))


def _within(path: Path, folders: list[Path]) -> bool:
    """Whether ``path`` (symbolic links resolved) lies in one of ``folders``."""
    real = path.resolve()
    return any(real.is_relative_to(folder.resolve()) for folder in folders)


def meshes_outside(urdf_path: str | Path, model_dirs: list[Path]) -> list[str]:
    """The URDF's visual meshes the viewer refuses to load, one sentence each.

    A mesh is loaded (read and sent to the browser) only from the model's
    folders or from the package a ``package://`` path names: its file,
    found as Pinocchio finds it (the first of :func:`mesh_package_dirs`,
    then $ROS_PACKAGE_PATH, that holds it), with symbolic links and ``..``
    resolved, must lie in

    - ``package://NAME/REL`` (or ``model://``): the folder of package NAME
      it was found in;
    - a relative path, an absolute path or ``file://``: one of ``model_dirs``.

    Any other scheme (``http://``) is refused too. A mesh that is not found
    anywhere is not listed (loading it fails and says so).

    Args:
        urdf_path: the URDF file.
        model_dirs: the model's folders (the spec's and the URDF's).

    Returns:
        One sentence per refused mesh (once however many links use it),
        naming its path and where it leads.
    """
    urdf = Path(urdf_path).resolve()
    try:
        root = ET.parse(urdf).getroot()
    except (ET.ParseError, OSError):
        return []  # not ours to report: the robot was loaded from it
    dirs = mesh_package_dirs(urdf)
    dirs += [Path(d) for d in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if d]
    folders = ", ".join(str(d) for d in dict.fromkeys(model_dirs))
    problems = []
    for mesh in root.iterfind(".//visual/geometry/mesh"):
        name = (mesh.get("filename") or "").strip()
        scheme, sep, rest = name.partition("://")
        if not sep:
            scheme, rest = "", name
        if scheme in ("package", "model"):
            package = rest.split("/", 1)[0]
            found = next((d for d in dirs if (d / rest).exists()), None)
            if found is not None and not _within(found / rest, [found / package]):
                problems.append(
                    f"mesh {name!r} leads outside its package's folder {found / package} "
                    f"(to {(found / rest).resolve()})"
                )
        elif scheme in ("", "file"):
            if scheme == "file" or os.path.isabs(rest):
                path = Path(rest)
            else:
                path = next((d / rest for d in dirs if (d / rest).exists()), None)
            if path is not None and path.exists() and not _within(path, model_dirs):
                problems.append(
                    f"mesh {name!r} lies outside the model's folder ({folders}): {path.resolve()}"
                )
        else:
            problems.append(f"mesh {name!r} is not a file: use a path or package://")
    return list(dict.fromkeys(problems))  # a mesh several links use, once


def _analyse(robot: CableRobot, q: np.ndarray):
    """Equilibrium tension, cable states and POC verdict at q.

    :func:`cdpm.linearise` finds the equilibrium tension (the
    spec's method via :func:`cdpm.dynamics.equilibrium.equilibrium_tension`, zero
    tension where that module is absent) and the input cone.

    Returns:
        (tension (m,), slack mask (m,), verdict, reach margin r_T [m] with
        the model's horizon and budget, reason); the first four are None
        when the pose cannot be linearised (reason says why).
    """
    try:
        lin = linearise(robot, q)
    except CdpmError as exc:
        return None, None, None, None, str(exc)
    # slack: at the lower bound, the tension can only grow (a cable at its
    # upper bound is sign-constrained too, but taut)
    slack = np.asarray(lin.input_sign > 0, dtype=bool)
    # scipy: loaded on first use
    from cdpm.analysis import positive_output_controllability

    try:
        poc = positive_output_controllability(
            lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
        )
    except CdpmError as exc:
        return lin.tension, slack, None, None, str(exc)
    # scipy: loaded on first use
    from cdpm.analysis import Verdict

    margin = reach_margins_at(robot, lin, None, [poc.verdict is Verdict.NO]).value[0]
    return lin.tension, slack, poc.verdict, float(margin), None


def _from_report(report) -> tuple:
    """:func:`_analyse`'s tuple from a :class:`cdpm.PoseReport` (no new analysis)."""
    lin = report.linearisation
    slack = np.asarray(lin.input_sign > 0, dtype=bool)
    return lin.tension, slack, report.poc.verdict, float(report.reach_margin[0]), None


def pose_state(
    robot: CableRobot,
    q: Any,
    geometry: PoseGeometry | None = None,
    *,
    report: Any = None,
    reason: str | None = None,
) -> PoseState:
    """What the viewer shows at q: positions, tensions, cable states, verdict.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: a pose name, a configuration vector (nq,) or natural coordinates (nv,).
        geometry: reuse a :class:`PoseGeometry` (the viewer keeps one); built if None.
        report: the :class:`cdpm.PoseReport` of :func:`cdpm.analyze_pose` at
            q (with the spec's tension method and the model's reach
            settings): its tensions, cable states, verdict and reach margin
            are shown instead of analysing the pose again.
        reason: the pose could not be analysed, for this reason (e.g. the
            message of the error :func:`cdpm.analyze_pose` raised): its
            cables and verdict are shown ``unavailable`` without analysing
            again. Not with ``report``.

    Returns:
        The :class:`PoseState`. A pose that cannot be linearised is not an
        error: its cables and verdict are ``unavailable`` with the reason.

    Raises:
        InputError: both ``report`` and ``reason`` are given, or the report
            is of another pose.
    """
    if report is not None and reason is not None:
        raise InputError("pose_state takes a report or a reason, not both")
    q = robot.as_q(q)
    geometry = geometry or PoseGeometry(robot)
    geometry.update(q)
    points = geometry.points()
    if report is not None:
        if not np.allclose(report.linearisation.q, q, rtol=0.0, atol=1e-12):
            raise InputError("the report is of another pose than q; analyse q itself")
        tension, slack, verdict, margin, reason = _from_report(report)
    elif reason is not None:
        tension, slack, verdict, margin = None, None, None, None
    else:
        tension, slack, verdict, margin, reason = _analyse(robot, q)
    if tension is None:
        states = (CableState.UNAVAILABLE,) * robot.n_cables
    else:
        states = tuple(CableState.SLACK if s else CableState.TAUT for s in slack)
    return PoseState(
        q=q.copy(),
        natural=robot.to_natural(q),
        coordinate_names=tuple(robot.coordinate_names),
        cable_names=tuple(robot.cable_names),
        cable_points=tuple(points[s].copy() for s in geometry.route_slices),
        cable_states=states,
        tension=None if tension is None else np.array(tension, dtype=float),
        output_names=tuple(robot.output_names),
        output=geometry.output.copy(),
        output_units=tuple(robot.output_units),
        output_kinds=geometry.drawing.kinds,
        output_definitions=geometry.drawing.definitions,
        output_frames=geometry.output_frames,
        output_frame_positions=geometry.output_positions(),
        verdict=verdict,
        margin=margin,
        reason=reason,
    )


def tension_scale(robot: CableRobot, tension: np.ndarray | None) -> float:
    """Tension [N] drawn in the darkest taut colour: the largest finite upper
    bound of the cables, else the largest tension at the pose (at least 1e-9)."""
    upper = robot.tension_max[np.isfinite(robot.tension_max)]
    if upper.size == robot.n_cables and upper.size:
        return float(max(upper.max(), 1e-9))
    if tension is None or not tension.size:
        return 1.0
    return float(max(np.max(np.abs(tension)), 1e-9))


def _taut_color(tension: float, scale: float, levels: int) -> tuple[float, float, float]:
    t = min(max(float(tension) / scale, 0.0), 1.0)
    t = round(t * (levels - 1)) / (levels - 1)
    low, high = np.array(COLORS["taut_low"]), np.array(COLORS["taut_high"])
    return tuple(float(c) for c in low + t * (high - low))


def cable_colors(
    state: PoseState, scale: float, levels: int = 32
) -> list[tuple[float, float, float]]:
    """RGB colour (0..1) of each cable: taut cables shade from light blue to
    navy as tension goes from 0 to ``scale`` [N] (in ``levels`` steps, so a
    small tension change does not resend a material)."""
    colors = []
    for i, s in enumerate(state.cable_states):
        if s is CableState.TAUT:
            colors.append(_taut_color(state.tension[i], scale, levels))
        else:
            colors.append(COLORS[s.value])
    return colors


def tension_colors(
    tension: np.ndarray,
    tension_min: np.ndarray,
    tension_max: np.ndarray,
    scale: float,
    levels: int = 32,
) -> list[tuple[float, float, float]]:
    """RGB colour (0..1) of cables pulled with given tensions (not an equilibrium).

    The scale of :func:`cable_colors`: a cable at its lower bound (zero
    tension by default; the bound test of
    :func:`cdpm.dynamics.equilibrium.statics.classify`) is slack pink, any other
    shades from light blue to navy as its tension goes from 0 to ``scale``.
    :meth:`cdpm.viewer.Viewer.play` colours a trajectory's cables with it.

    Args:
        tension: the cables' tensions [N], shape (m,).
        tension_min, tension_max: their bounds [N], each (m,).
        scale: tension [N] drawn in the darkest taut colour.
        levels: shades from light blue to navy.
    """

    f = np.asarray(tension, dtype=float)
    # the colour scale stands for the robot's force scale of the bound test
    at_lower, _, _ = classify(f, np.asarray(tension_min), np.asarray(tension_max), scale)
    return [
        COLORS["slack"] if slack else _taut_color(fi, scale, levels)
        for fi, slack in zip(f, at_lower, strict=True)
    ]


def default_pose(robot: CableRobot) -> np.ndarray:
    """The spec's first named pose, else the neutral configuration."""
    if robot.poses:
        return next(iter(robot.poses.values())).copy()
    return robot.neutral()
