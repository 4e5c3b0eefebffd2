"""Look at a pose: a meshcat 3-D view and interactive pose inspection.

:class:`Viewer` draws a cable robot in meshcat (a WebGL viewer served on
127.0.0.1 and opened in a browser): the URDF's visual geometry (or generated
links when the URDF has none), the base anchors and attachment points, the
cables coloured by state, and the output frame with a marker whose colour
gives the positive output controllability (POC) verdict at the displayed
pose. :meth:`Viewer.display` moves everything to a new pose;
:meth:`Viewer.show_map` overlays a workspace map as a point cloud.

:func:`pose_state` computes what is drawn (positions, tensions, cable
states, verdict) without meshcat, so the headless picture
(:mod:`cdpm.picture`) and the text panel of :class:`PoseInspector` share it.

Cable states (:class:`CableState`), from the linearisation at the pose:

- ``taut``: the equilibrium tension is above the cable's lower bound, so the
  tension can change both ways; drawn in blue, darker with more tension.
- ``slack``: the cable sits at its lower bound (zero tension by default);
  it can only pull more (a sign-constrained input); drawn in pink.
- ``unavailable``: no equilibrium or linearisation at this pose (e.g. gravity
  without an equilibrium, a zero-length cable); drawn in grey, verdict grey.

meshcat, ipywidgets and matplotlib are optional (``pip install "cdpm[viz]"``)
and imported only when a viewer, a widget or a picture is made.
"""

from __future__ import annotations

import contextlib
import enum
import html
import io
import math
import os
import subprocess
import sys
import tempfile
import time
import warnings
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import CdpmError, InputError, MissingExtraError, ModelError
from cdpm.linearisation import linearise

__all__ = [
    "CableState",
    "PoseState",
    "pose_state",
    "coordinate_ranges",
    "Viewer",
    "PoseInspector",
    "check_map_spec",
    "check_port",
    "LOOPBACK",
    "COLORS",
    "VERDICT_CODES",
]

#: The only address the viewer's servers listen on.
LOOPBACK = "127.0.0.1"

#: RGB colours (0..1) of the drawing, shared by the 3-D view and the picture.
COLORS: dict[str, tuple[float, float, float]] = {
    "slack": (0.890, 0.467, 0.761),  # pink
    "taut_low": (0.420, 0.682, 0.839),  # light blue (low tension)
    "taut_high": (0.031, 0.188, 0.420),  # navy (tension at the scale)
    "unavailable": (0.55, 0.55, 0.55),
    "yes": (0.122, 0.659, 0.227),  # green
    "no": (0.839, 0.153, 0.157),  # red
    "marginal": (1.0, 0.690, 0.0),  # amber
    "not_analysed": (0.70, 0.70, 0.70),
    "link": (0.62, 0.64, 0.68),
    "joint": (0.35, 0.35, 0.38),
    "com": (0.15, 0.15, 0.15),
    "anchor": (0.10, 0.10, 0.10),
    "attachment": (0.35, 0.35, 0.35),
}

#: Codes of the ``poc`` variable of a workspace map (``flag_values``).
VERDICT_CODES = {1: "yes", 0: "no", 2: "marginal", -1: "not_analysed"}

#: Colour Pinocchio gives URDF visuals that have no material.
_PIN_DEFAULT_COLOR = (0.9, 0.9, 0.9, 1.0)

#: Seconds to wait for the meshcat server to start or to answer.
SERVER_TIMEOUT = 20.0


class CableState(enum.StrEnum):
    """State of a cable at the displayed equilibrium."""

    TAUT = "taut"
    SLACK = "slack"
    UNAVAILABLE = "unavailable"


# --------------------------------------------------------------------------
# what is drawn: pose state (no meshcat)


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
        output: outputs y [m], shape (p,).
        output_frames: names of the frames the outputs measure (each once).
        output_frame_positions: their world positions [m], shape (n_frames, 3).
        verdict: POC verdict (:class:`cdpm.analysis.Verdict`) or None when unavailable.
        margin: POC margin (positive when POC) or None.
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
    output_frames: tuple[str, ...]
    output_frame_positions: np.ndarray
    verdict: Any
    margin: float | None
    reason: str | None

    @property
    def verdict_key(self) -> str:
        """``"yes"``, ``"no"``, ``"marginal"`` or ``"unavailable"`` (a key of :data:`COLORS`)."""
        return "unavailable" if self.verdict is None else self.verdict.value

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
        margin = "" if self.margin is None else f" (margin {self.margin:.4g})"
        return f"POC: {str(self.verdict).upper()}{margin}"

    def __str__(self) -> str:
        coords = ", ".join(
            f"{n} = {v:.4f}" for n, v in zip(self.coordinate_names, self.natural, strict=True)
        )
        outputs = ", ".join(
            f"{n} = {v:.4f}" for n, v in zip(self.output_names, self.output, strict=True)
        )
        lines = [self._verdict_line(), f"pose: {coords}", f"outputs: {outputs or '(none)'}"]
        for i, (name, state) in enumerate(zip(self.cable_names, self.cable_states, strict=True)):
            f = "    -" if self.tension is None else f"{self.tension[i]:9.4g} N"
            lines.append(f"  {name:<10} {f}  {state.value}")
        slack = ", ".join(self.slack_cables) or "none"
        lines.append(f"slack cables: {slack}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        r, g, b = (int(255 * c) for c in COLORS[self.verdict_key])
        head = html.escape(self._verdict_line())
        body = html.escape("\n".join(str(self).splitlines()[1:]))
        return (
            f'<div><b style="color: rgb({r},{g},{b})">{head}</b>'
            f'<pre style="margin: 0.3em 0">{body}</pre></div>'
        )


class _Geometry:
    """World positions the drawings need, from one forward-kinematics pass.

    Route points are read from the spec (frame + point in frame), so this
    never fails, not even at poses where a cable has zero length.
    """

    def __init__(self, robot) -> None:
        import pinocchio as pin

        self._pin = pin
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
        names: list[str] = []
        for out in robot.spec.outputs:
            if out.frame not in names:
                names.append(out.frame)
        self.output_frames = tuple(names)
        self.output_frame_ids = [self._frame_id(n) for n in names]
        # a route point is fixed to the world when its frame's parent joint is the universe
        self.point_joint = np.array(
            [0 if f < 0 else int(self.model.frames[f].parentJoint) for f in frames], dtype=int
        )

    def _frame_id(self, name: str) -> int:
        from cdpm.spec import WORLD_FRAME_NAMES

        return -1 if name in WORLD_FRAME_NAMES else int(self.model.getFrameId(name))

    def update(self, q: np.ndarray) -> None:
        """Forward kinematics and frame placements at q (nq,)."""
        self._pin.framesForwardKinematics(self.model, self.data, q)

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
        """World positions of the output frames [m], shape (n_frames, 3)."""
        return np.array(
            [self._place(f, np.zeros(3)) for f in self.output_frame_ids], dtype=float
        ).reshape(-1, 3)

    def output_placements(self) -> list[np.ndarray]:
        """Homogeneous world placements (4, 4) of the output frames."""
        return [
            np.eye(4) if f < 0 else np.asarray(self.data.oMf[f].homogeneous)
            for f in self.output_frame_ids
        ]

    def joint_placements(self) -> list[np.ndarray]:
        """Homogeneous world placement (4, 4) of every joint (index 0: universe)."""
        return [np.asarray(self.data.oMi[j].homogeneous) for j in range(self.model.njoints)]


def _skeleton(model) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """Generated link geometry: segments (joint, start, end) in the joint's frame.

    A joint gets a segment to each child joint and, when it has none, to its
    farthest frame (e.g. a tool tip), so a serial arm draws as a chain.
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


def _coms(model) -> list[tuple[int, np.ndarray]]:
    """(joint, centre of mass in the joint's frame) of every joint carrying mass."""
    return [
        (j, np.array(model.inertias[j].lever))
        for j in range(1, model.njoints)
        if model.inertias[j].mass > 0
    ]


def _analyse(robot, q: np.ndarray):
    """Equilibrium tension, cable states and POC verdict at q.

    :func:`cdpm.linearise` finds the equilibrium tension (the
    spec's method via :func:`cdpm.equilibrium.equilibrium_tension`, zero
    tension where that module is absent) and the input cone.

    Returns:
        (tension (m,), slack mask (m,), verdict, margin, reason); the first
        four are None when the pose cannot be linearised (reason says why).
    """
    try:
        lin = linearise(robot, q)
    except CdpmError as exc:
        return None, None, None, None, str(exc)
    # slack: at the lower bound, the tension can only grow (a cable at its
    # upper bound is sign-constrained too, but taut)
    slack = np.asarray(lin.input_sign > 0, dtype=bool)
    from cdpm.analysis import positive_output_controllability

    try:
        poc = positive_output_controllability(
            lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
        )
    except CdpmError as exc:
        return lin.tension, slack, None, None, str(exc)
    return lin.tension, slack, poc.verdict, float(poc.margin), None


def pose_state(robot, q: Any, geometry: _Geometry | None = None) -> PoseState:
    """What the viewer shows at q: positions, tensions, cable states, verdict.

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: a pose name, a configuration vector (nq,) or natural coordinates (nv,).
        geometry: reuse a ``_Geometry`` (the viewer keeps one); built if None.

    Returns:
        The :class:`PoseState`. A pose that cannot be linearised is not an
        error: its cables and verdict are ``unavailable`` with the reason.
    """
    q = robot.as_q(q)
    geometry = geometry or _Geometry(robot)
    geometry.update(q)
    points = geometry.points()
    tension, slack, verdict, margin, reason = _analyse(robot, q)
    if tension is None:
        states = (CableState.UNAVAILABLE,) * robot.n_cables
    else:
        states = tuple(CableState.SLACK if s else CableState.TAUT for s in slack)
    outputs = geometry.output_positions()
    return PoseState(
        q=q.copy(),
        natural=robot.to_natural(q),
        coordinate_names=tuple(robot.coordinate_names),
        cable_names=tuple(robot.cable_names),
        cable_points=tuple(points[s].copy() for s in geometry.route_slices),
        cable_states=states,
        tension=None if tension is None else np.array(tension, dtype=float),
        output_names=tuple(robot.output_names),
        output=_outputs_from_frames(robot, geometry, outputs),
        output_frames=geometry.output_frames,
        output_frame_positions=outputs,
        verdict=verdict,
        margin=margin,
        reason=reason,
    )


def _outputs_from_frames(robot, geometry: _Geometry, positions: np.ndarray) -> np.ndarray:
    from cdpm.spec import OUTPUT_COMPONENTS

    return np.array(
        [
            positions[geometry.output_frames.index(o.frame), OUTPUT_COMPONENTS[o.component]]
            for o in robot.spec.outputs
        ],
        dtype=float,
    )


def tension_scale(robot, tension: np.ndarray | None) -> float:
    """Tension [N] drawn in the darkest taut colour: the largest finite upper
    bound of the cables, else the largest tension at the pose (at least 1e-9)."""
    upper = robot.tension_max[np.isfinite(robot.tension_max)]
    if upper.size == robot.n_cables and upper.size:
        return float(max(upper.max(), 1e-9))
    if tension is None or not tension.size:
        return 1.0
    return float(max(np.max(np.abs(tension)), 1e-9))


def cable_colors(
    state: PoseState, scale: float, levels: int = 32
) -> list[tuple[float, float, float]]:
    """RGB colour (0..1) of each cable: taut cables shade from light blue to
    navy as tension goes from 0 to ``scale`` [N] (in ``levels`` steps, so a
    small tension change does not resend a material)."""
    colors = []
    for i, s in enumerate(state.cable_states):
        if s is CableState.TAUT:
            t = min(max(float(state.tension[i]) / scale, 0.0), 1.0)
            t = round(t * (levels - 1)) / (levels - 1)
            low, high = np.array(COLORS["taut_low"]), np.array(COLORS["taut_high"])
            colors.append(tuple(float(c) for c in low + t * (high - low)))
        else:
            colors.append(COLORS[s.value])
    return colors


def coordinate_ranges(robot, natural: Any = None) -> dict[str, tuple[float, float]]:
    """Slider range of each natural coordinate, from the URDF joint limits.

    Finite limits (``robot.model.lowerPositionLimit``/``upperPositionLimit``)
    are used as they are; an angle without them gets [-pi, pi] (pitch of a
    ball joint [-pi/2, pi/2]); a length without them gets the current value
    +- 1 m. The range always contains the current value.

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        natural: current natural coordinates (nv,); default the neutral pose.

    Returns:
        ``{coordinate name: (low, high)}`` in the order of ``robot.coordinate_names``.
    """
    model = robot.model
    natural = robot.to_natural(robot.neutral() if natural is None else robot.as_q(natural))
    lower, upper = np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)
    names = list(robot.coordinate_names)
    ranges: dict[str, tuple[float, float]] = {}
    for j in range(1, model.njoints):
        joint = model.joints[j]
        kind = joint.shortname()
        for k in range(joint.nv):
            iv = joint.idx_v + k
            name = names[iv]
            suffix = name.rsplit(".", 1)[-1] if "." in name else ""
            # JointModelPX/PY/PZ/PrismaticUnaligned, Translation: lengths
            prismatic = kind.startswith(("JointModelP", "JointModelTranslation"))
            is_length = (joint.nq == joint.nv and prismatic) or (
                joint.nq != joint.nv and suffix in ("x", "y", "z")
            )
            if joint.nq == joint.nv or (joint.nq != joint.nv and is_length):
                lo, hi = float(lower[joint.idx_q + k]), float(upper[joint.idx_q + k])
            else:
                lo, hi = -math.inf, math.inf
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                if is_length:
                    lo, hi = natural[iv] - 1.0, natural[iv] + 1.0
                elif suffix == "pitch":
                    lo, hi = -math.pi / 2, math.pi / 2
                else:
                    lo, hi = -math.pi, math.pi
            ranges[name] = (min(lo, float(natural[iv])), max(hi, float(natural[iv])))
    return ranges


def _default_pose(robot) -> np.ndarray:
    """The spec's first named pose, else the neutral configuration."""
    if robot.poses:
        return next(iter(robot.poses.values())).copy()
    return robot.neutral()


# --------------------------------------------------------------------------
# meshcat


def _import_meshcat():
    try:
        import meshcat
        import meshcat.geometry
        import meshcat.servers.zmqserver  # noqa: F401
        import meshcat.visualizer
    except ImportError as exc:
        raise MissingExtraError(
            f'the 3-D viewer needs meshcat ({exc}); install it with: pip install "cdpm[viz]"'
        ) from exc
    return meshcat


def _rgb_int(rgb: tuple[float, float, float]) -> int:
    r, g, b = (int(round(255 * min(max(c, 0.0), 1.0))) for c in rgb)
    return (r << 16) | (g << 8) | b


def _segment_transform(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Transform taking meshcat's unit cylinder (height 1 along y, centred)
    to the segment a -> b (4, 4)."""
    d = b - a
    length = float(np.linalg.norm(d))
    T = np.eye(4)
    T[:3, 3] = 0.5 * (a + b)
    if length < 1e-12:
        T[:3, :3] = np.diag([1.0, 1e-6, 1.0])
        return T
    y = d / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, y * length, z
    return T


def _translation(p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _serve(argv: list[str] | None = None) -> None:
    """Run a meshcat server whose zmq and web ports listen on 127.0.0.1 only.

    meshcat 0.3.2's ``ZMQWebSocketBridge`` binds zmq to its ``host``
    (127.0.0.1 by default) but calls tornado's ``Application.listen(port)``
    without an address, which listens on every interface; the web app's
    ``listen`` is pinned to the loopback address here.
    """
    import argparse
    import functools

    import tornado.ioloop
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    parser = argparse.ArgumentParser(prog="python -m cdpm.viewer")
    parser.add_argument(
        "--port", type=int, default=None, help="web port (default: first free from 7000)"
    )
    args = parser.parse_args(argv)

    class LoopbackBridge(ZMQWebSocketBridge):
        def make_app(self):
            app = super().make_app()
            app.listen = functools.partial(app.listen, address=LOOPBACK)
            return app

    bridge = LoopbackBridge(host=LOOPBACK, port=args.port)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    # stop when the process that started us is gone (e.g. a killed kernel)
    parent = os.getppid()

    def check_parent() -> None:
        if os.getppid() != parent:
            bridge.ioloop.stop()

    tornado.ioloop.PeriodicCallback(check_parent, 1000).start()
    with contextlib.suppress(KeyboardInterrupt):
        bridge.run()


def check_port(port: Any) -> int:
    """``port`` as an int when it is a TCP port (1-65535).

    Raises:
        InputError: it is not.
    """
    try:
        value = int(str(port).strip())
    except ValueError:
        value = 0
    if not 1 <= value <= 65535:
        raise InputError(
            f"port {port} is not a TCP port; use 1-65535 (or omit it: the first free from 7000)"
        )
    return value


class _Server:
    """A meshcat server subprocess (see :func:`_serve`) and its log file."""

    def __init__(self, port: int | None) -> None:
        self.log = tempfile.NamedTemporaryFile(prefix="cdpm-meshcat-", suffix=".log", delete=False)
        args = [sys.executable, "-u", "-m", "cdpm.viewer"]
        if port is not None:
            args += ["--port", str(int(port))]
        self.process = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=self.log,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # Ctrl-C in a terminal or notebook reaches us, not it
        )
        self.zmq_url, self.web_url = self._wait_for_urls(port)

    def _wait_for_urls(self, port: int | None) -> tuple[str, str]:
        deadline = time.monotonic() + SERVER_TIMEOUT
        while time.monotonic() < deadline:
            text = Path(self.log.name).read_text(errors="replace")
            urls = dict(
                line.split("=", 1)
                for line in text.splitlines()
                if line.startswith(("zmq_url=", "web_url="))
            )
            if "zmq_url" in urls and "web_url" in urls:
                return urls["zmq_url"], urls["web_url"]
            if self.process.poll() is not None:
                self.close()
                hint = (
                    f"; is port {port} in use? choose another port or omit it"
                    if port is not None and "Address already in use" in text
                    else ""
                )
                raise CdpmError(f"the meshcat server exited at start{hint}:\n{text.strip()}")
            time.sleep(0.02)
        self.close()
        raise CdpmError(f"the meshcat server did not start within {SERVER_TIMEOUT:g} s")

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()
        with contextlib.suppress(OSError):
            os.unlink(self.log.name)


class Viewer:
    """meshcat view of a cable robot, its cables and the POC verdict.

    Starts a meshcat server (web and zmq ports on 127.0.0.1 only) in a
    subprocess, or connects to a running one with ``zmq_url``; open
    :meth:`url` in a browser. The scene is built once; :meth:`display`
    then only sends transforms, and materials of cables whose colour changed.

    Scene (meshcat paths under ``/meshcat/cdpm``): ``robot`` (URDF visuals or
    generated links), ``anchors`` (route points fixed to the world, dark
    spheres), ``attachments`` (route points on links, grey spheres),
    ``cables/<name>/<k>`` (segment k of a cable: taut blue by tension, slack
    pink, unavailable grey), ``output/<frame>`` (output frame marker: green
    YES, red NO, amber MARGINAL, grey unavailable), ``map`` (workspace map).

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: first pose (name, configuration or natural coordinates); default
            the spec's first pose, else neutral.
        port: web port of the started server, 1-65535 (default: first free
            from 7000).
        zmq_url: connect to this running meshcat server instead of starting one.
        geometry: ``"auto"`` (URDF visuals when the URDF has some, else
            generated), ``"urdf"`` or ``"generated"``.
        tension_scale: tension [N] drawn in the darkest taut colour (default
            :func:`tension_scale`).

    Raises:
        MissingExtraError: meshcat is not installed.
        InputError: a port outside 1-65535 or an unknown geometry.
        CdpmError: the server could not start (e.g. the port is in use).
    """

    def __init__(
        self,
        robot,
        q: Any = None,
        *,
        port: int | None = None,
        zmq_url: str | None = None,
        geometry: str = "auto",
        tension_scale: float | None = None,
    ) -> None:
        if port is not None:
            port = check_port(port)
        meshcat = _import_meshcat()
        if geometry not in ("auto", "urdf", "generated"):
            raise InputError(f"geometry={geometry!r}; use 'auto', 'urdf' or 'generated'")
        if tension_scale is not None and not (math.isfinite(tension_scale) and tension_scale > 0):
            raise InputError(
                f"tension_scale={tension_scale!r} must be a positive number of newtons"
            )
        self.robot = robot
        self._g = meshcat.geometry
        self._server = _Server(port) if zmq_url is None else None
        self._finalizer = weakref.finalize(self, Viewer._shutdown, self._server)
        url = zmq_url or self._server.zmq_url
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL
                window = meshcat.visualizer.ViewerWindow(url, False, None)
            import zmq

            window.zmq_socket.setsockopt(zmq.RCVTIMEO, int(SERVER_TIMEOUT * 1000))
            window.zmq_socket.setsockopt(zmq.LINGER, 0)
            self._window = window
            self._root = meshcat.Visualizer(window=window)
        except Exception:
            self.close()
            raise
        self._web_url = window.web_url
        self._zmq = zmq
        self._geometry = _Geometry(robot)
        self._tension_scale = tension_scale
        self._cable_colors: list[tuple[float, float, float] | None] = []
        self._marker_color: tuple[float, float, float] | None = None
        self.state: PoseState | None = None
        #: seconds spent in the last :meth:`display`: ``analysis`` and ``draw``
        self.last_display_seconds: dict[str, float] = {}
        q0 = robot.as_q(_default_pose(robot) if q is None else q)
        self._geometry.update(q0)
        self._size = self._scene_size()
        self._pin_viz = None
        self.geometry = self._build_robot(geometry)
        self._build_points()
        self._build_cables()
        self._build_outputs()
        self._set_camera()
        self.display(q0)

    # ------------------------------------------------------------ lifecycle

    @staticmethod
    def _shutdown(server: _Server | None) -> None:
        if server is not None:
            server.close()

    def close(self) -> None:
        """Stop the meshcat server this viewer started (if any)."""
        window = getattr(self, "_window", None)
        if window is not None:
            window.zmq_socket.close(linger=0)
        self._finalizer()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    @property
    def server_pid(self) -> int | None:
        """Process id of the meshcat server this viewer started, else None."""
        return None if self._server is None else self._server.process.pid

    @property
    def zmq_url(self) -> str:
        """zmq address of the meshcat server (tcp://127.0.0.1:PORT)."""
        return self._window.zmq_url

    def url(self) -> str:
        """URL of the viewer page (http://127.0.0.1:PORT/static/)."""
        return self._web_url

    def __repr__(self) -> str:
        return f"Viewer({self.robot.spec.path.name!r}, url={self.url()!r})"

    def _repr_html_(self) -> str:
        url = html.escape(self.url(), quote=True)
        return (
            f'<div style="height: 420px; width: 100%; resize: both; overflow: hidden">'
            f'<iframe src="{url}" style="width: 100%; height: 100%; border: none"></iframe></div>'
        )

    def _send(self, path: str, method: str, *args) -> None:
        try:
            getattr(self._root[path], method)(*args)
        except self._zmq.error.Again as exc:
            raise CdpmError(
                f"the meshcat server at {self.zmq_url} did not answer within "
                f"{SERVER_TIMEOUT:g} s; close this viewer and make a new one"
            ) from exc

    # ------------------------------------------------------------ building

    def _scene_size(self) -> float:
        pts = [self._geometry.points(), self._geometry.output_positions()]
        pts += [T[None, :3, 3] for T in self._geometry.joint_placements()]
        allp = np.concatenate([p.reshape(-1, 3) for p in pts])
        return float(max(np.ptp(allp, axis=0).max(), 0.1))

    def _build_robot(self, mode: str) -> str:
        """Draw the links; returns ``"urdf"`` or ``"generated"``."""
        if mode in ("auto", "urdf"):
            visual = self._visual_model(required=mode == "urdf")
            if visual is not None and visual.ngeoms > 0:
                from pinocchio.visualize import MeshcatVisualizer

                viz = MeshcatVisualizer(self.robot.model, None, visual)
                viz.initViewer(viewer=self._root)
                # URDF visuals without a <material> get Pinocchio's near-white grey,
                # invisible on the light background: draw those in the link colour
                plain = all(
                    np.allclose(o.meshColor, _PIN_DEFAULT_COLOR) for o in visual.geometryObjects
                )
                color = [*COLORS["link"], 1.0] if plain else None
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    viz.loadViewerModel(rootNodeName="cdpm/robot", visual_color=color)
                if caught and mode == "urdf":
                    raise ModelError(
                        "some URDF visual geometry could not be shown: "
                        + "; ".join(str(w.message) for w in caught)
                        + "; use geometry='generated'"
                    )
                for w in caught:
                    warnings.warn(str(w.message), stacklevel=3)
                self._pin_viz = viz
                return "urdf"
            if mode == "urdf":
                raise ModelError(
                    f"{self.robot.spec.urdf_path.name} has no <visual> geometry; "
                    "use geometry='generated' (or 'auto')"
                )
        g, s = self._g, self._size
        link = g.MeshPhongMaterial(color=_rgb_int(COLORS["link"]))
        for k, (j, a, b) in enumerate(_skeleton(self.robot.model)):
            path = f"cdpm/robot/joint{j}/link{k}"
            self._send(path, "set_object", g.Cylinder(1.0, 0.012 * s), link)
            self._send(path, "set_transform", _segment_transform(a, b))
        joint = g.MeshPhongMaterial(color=_rgb_int(COLORS["joint"]))
        for j in range(1, self.robot.model.njoints):
            self._send(f"cdpm/robot/joint{j}/axis", "set_object", g.Sphere(0.02 * s), joint)
        com = g.MeshPhongMaterial(color=_rgb_int(COLORS["com"]))
        for j, c in _coms(self.robot.model):
            path = f"cdpm/robot/joint{j}/com"
            self._send(path, "set_object", g.Sphere(0.016 * s), com)
            self._send(path, "set_transform", _translation(c))
        return "generated"

    def _visual_model(self, required: bool):
        import pinocchio as pin

        urdf = self.robot.spec.urdf_path
        try:
            return pin.buildGeomFromUrdf(
                self.robot.model,
                str(urdf),
                pin.GeometryType.VISUAL,
                package_dirs=[str(urdf.parent)],
            )
        except (ValueError, RuntimeError, OSError) as exc:
            if required:
                raise ModelError(
                    f"cannot load the visual geometry of {urdf}: {exc}; "
                    "check the mesh paths or use geometry='generated'"
                ) from exc
            warnings.warn(
                f"URDF visual geometry not loaded ({exc}); drawing generated links", stacklevel=3
            )
            return None

    def _build_points(self) -> None:
        g, s = self._g, self._size
        anchor = g.MeshPhongMaterial(color=_rgb_int(COLORS["anchor"]))
        attach = g.MeshPhongMaterial(color=_rgb_int(COLORS["attachment"]))
        geo = self._geometry
        points = geo.points()
        for k, joint in enumerate(geo.point_joint):
            if joint == 0:
                path = f"cdpm/anchors/p{k}"
                self._send(path, "set_object", g.Sphere(0.018 * s), anchor)
                self._send(path, "set_transform", _translation(points[k]))
            else:  # placed by display()
                self._send(f"cdpm/attachments/p{k}", "set_object", g.Sphere(0.013 * s), attach)

    def _build_cables(self) -> None:
        self._cable_colors = [None] * self.robot.n_cables

    def _set_cable_color(self, i: int, rgb: tuple[float, float, float]) -> None:
        if self._cable_colors[i] == rgb:
            return
        g = self._g
        material = g.MeshBasicMaterial(color=_rgb_int(rgb))  # unlit: the exact colour
        sl = self._geometry.route_slices[i]
        for k in range(sl.stop - sl.start - 1):
            path = f"cdpm/cables/{self.robot.cable_names[i]}/{k}/line"
            self._send(path, "set_object", g.Cylinder(1.0, 0.004 * self._size), material)
        self._cable_colors[i] = rgb

    def _build_outputs(self) -> None:
        g, s = self._g, self._size
        for name in self._geometry.output_frames:
            self._send(f"cdpm/output/{name}/axes", "set_object", g.triad(0.12 * s))
        self._marker_color = None

    def _set_marker_color(self, rgb: tuple[float, float, float]) -> None:
        if self._marker_color == rgb:
            return
        g = self._g
        material = g.MeshPhongMaterial(color=_rgb_int(rgb))
        for name in self._geometry.output_frames:
            self._send(
                f"cdpm/output/{name}/marker", "set_object", g.Sphere(0.035 * self._size), material
            )
        self._marker_color = rgb

    def _set_camera(self) -> None:
        """Look at the world origin across the scene's thinnest world axis.

        meshcat 0.3.2's orbit controls always aim at the world origin (moving
        ``/Cameras/default`` moves the eye, not the target), so the eye is
        placed far enough for every point of the scene to fit in view.
        """
        geo = self._geometry
        pts = np.concatenate([geo.points(), geo.output_positions()])
        pts = np.concatenate([pts, np.array([T[:3, 3] for T in geo.joint_placements()])])
        normal = int(np.argmin(np.ptp(pts, axis=0)))
        direction = np.zeros(3)
        direction[normal] = -1.0 if normal == 1 else 1.0  # so that +x or +y points right
        # tilt a little so that the view is not along meshcat's up axis (z)
        direction[1 if normal == 2 else 2] = -0.3 if normal == 2 else 0.3
        direction /= np.linalg.norm(direction)
        radius = float(np.max(np.linalg.norm(pts, axis=1)))
        eye = direction * 1.8 * max(radius, 0.1)  # vertical field of view 75 deg
        # the camera sits in meshcat's y-up frame: (x, z, -y) of the world
        self._send(
            "/Cameras/default/rotated/<object>",
            "set_property",
            "position",
            [float(eye[0]), float(eye[2]), float(-eye[1])],
        )
        self._send("/Background", "set_property", "top_color", [0.98, 0.98, 0.98])
        self._send("/Background", "set_property", "bottom_color", [0.80, 0.82, 0.86])
        if normal == 2:  # the grid would lie in the robot's plane
            self._send("/Grid", "set_property", "visible", False)

    # ------------------------------------------------------------ updating

    def display(self, q: Any) -> PoseState:
        """Move the robot, cables and output to q and recolour by state and verdict.

        Args:
            q: a pose name, a configuration vector (nq,) or natural coordinates (nv,).

        Returns:
            The :class:`PoseState` shown (also kept as :attr:`state`).
        """
        t0 = time.perf_counter()
        state = pose_state(self.robot, q, self._geometry)  # also updates the kinematics
        t1 = time.perf_counter()
        geo = self._geometry
        if self._pin_viz is not None:
            self._pin_viz.display(state.q)
        else:
            placements = geo.joint_placements()
            for j in range(1, self.robot.model.njoints):
                self._send(f"cdpm/robot/joint{j}", "set_transform", placements[j])
        points = np.concatenate(state.cable_points) if state.cable_points else np.zeros((0, 3))
        for k, joint in enumerate(geo.point_joint):
            if joint != 0:
                self._send(f"cdpm/attachments/p{k}", "set_transform", _translation(points[k]))
        scale = self._tension_scale or tension_scale(self.robot, state.tension)
        for i, (name, rgb) in enumerate(
            zip(self.robot.cable_names, cable_colors(state, scale), strict=True)
        ):
            self._set_cable_color(i, rgb)
            route = state.cable_points[i]
            for k in range(len(route) - 1):
                self._send(
                    f"cdpm/cables/{name}/{k}",
                    "set_transform",
                    _segment_transform(route[k], route[k + 1]),
                )
        self._set_marker_color(COLORS[state.verdict_key])
        for name, T in zip(geo.output_frames, geo.output_placements(), strict=True):
            self._send(f"cdpm/output/{name}", "set_transform", T)
        t2 = time.perf_counter()
        self.state = state
        self.last_display_seconds = {"analysis": t1 - t0, "draw": t2 - t1, "total": t2 - t0}
        return state

    # ------------------------------------------------------------ workspace map

    def show_map(
        self,
        dataset,
        *,
        color_by: str = "verdict",
        position: str = "output_frame_position",
        point_size: float | None = None,
        check_spec: bool = True,
    ) -> int:
        """Overlay a workspace map as a point cloud (path ``/meshcat/cdpm/map``).

        Args:
            dataset: an ``xarray.Dataset`` map with variables ``poc`` (int8
                codes 1 YES, 0 NO, 2 MARGINAL, -1 not analysed),
                ``poc_margin`` and ``output_frame_position`` (dims
                ``(..., "xyz")``, world position [m] of the first output's frame).
            color_by: ``"verdict"`` (green YES, red NO, amber MARGINAL, grey not
                analysed) or ``"margin"`` (red negative through white to green
                positive, scaled by the largest |margin|; NaN grey).
            position: the position variable to plot (dims ``(..., "xyz")``).
            point_size: size of the points [m] (default: 1.5 % of the scene).
            check_spec: refuse a map made from another spec file (see
                :func:`check_map_spec`); ``False`` overlays it anyway.

        Returns:
            The number of points drawn (poses with a finite position).

        Raises:
            InputError: the dataset lacks a variable or has the wrong dims, or
                was made from another spec.
        """
        if check_spec:
            check_map_spec(dataset, self.robot)
        positions, colors = map_points(dataset, color_by=color_by, position=position)
        size = 0.015 * self._size if point_size is None else float(point_size)
        g = self._g
        cloud = g.PointCloud(positions.T.astype(np.float32), colors.T.astype(np.float32), size=size)
        self._send("cdpm/map", "set_object", cloud)
        return int(positions.shape[0])

    def hide_map(self) -> None:
        """Remove the workspace map overlay."""
        self._send("cdpm/map", "delete")


def check_map_spec(dataset, robot, *, override: str = "check_spec=False") -> None:
    """Refuse a map made from another spec than ``robot``'s.

    A map records the sha256 of its spec file and URDF (attribute
    ``spec_sha256``, the hash :func:`cdpm.load_robot` computes as
    ``robot.spec.sha256``); a map without it (e.g. made by hand) is not checked.

    Args:
        dataset: the map (``xarray.Dataset``).
        robot: the robot it is to be shown with.
        override: how the caller skips this check, named in the message.

    Raises:
        InputError: the hashes differ; the message names both spec files.
    """
    stored = getattr(dataset, "attrs", {}).get("spec_sha256")
    if not stored or stored == robot.spec.sha256:
        return
    store = getattr(dataset, "encoding", {}).get("source")
    made_from = dataset.attrs.get("spec", "another spec")
    spec, now = robot.spec.path, robot.spec.sha256
    if str(made_from) == str(spec):
        source = f"an earlier version of {spec} or its URDF (sha256 {stored[:12]}, now {now[:12]})"
    else:
        source = f"{made_from} (sha256 {stored[:12]}), not from {spec} (sha256 {now[:12]})"
    what = f"map {store}" if store else "the map"
    rerun = f"`cdpm map {spec} ... --out {store} --overwrite`" if store else "it with this spec"
    raise InputError(
        f"{what} was made from {source}; re-run {rerun} or view it with the spec it was made "
        f"from ({override} overlays it anyway)"
    )


def map_points(dataset, *, color_by: str = "verdict", position: str = "output_frame_position"):
    """Positions (n, 3) [m] and RGB colours (n, 3) of a workspace map's poses.

    See :meth:`Viewer.show_map` for the dataset contract. Poses whose
    position is not finite are left out.
    """
    if color_by not in ("verdict", "margin"):
        raise InputError(f"color_by={color_by!r}; use 'verdict' or 'margin'")
    needed = {"verdict": "poc", "margin": "poc_margin"}[color_by]
    for var in (position, needed):
        if var not in getattr(dataset, "data_vars", {}):
            have = ", ".join(getattr(dataset, "data_vars", {})) or "none"
            raise InputError(
                f"the map has no variable {var!r} (it has: {have}); "
                "make it with the workspace-map command or pass position=/color_by="
            )
    pos = dataset[position]
    if "xyz" not in pos.dims or pos.sizes["xyz"] != 3:
        raise InputError(f"{position} must have a dimension 'xyz' of size 3, got dims {pos.dims}")
    pose_dims = [d for d in pos.dims if d != "xyz"]
    positions = pos.transpose(*pose_dims, "xyz").values.reshape(-1, 3).astype(float)
    values = dataset[needed].transpose(*pose_dims).values.reshape(-1)
    if values.shape[0] != positions.shape[0]:
        raise InputError(
            f"{needed} has dims {dataset[needed].dims}, expected the pose dims {tuple(pose_dims)}"
        )
    if color_by == "verdict":
        codes = values.astype(int)
        colors = np.array(
            [COLORS[VERDICT_CODES.get(int(c), "not_analysed")] for c in codes], dtype=float
        ).reshape(-1, 3)
    else:
        colors = _margin_colors(values.astype(float))
    keep = np.all(np.isfinite(positions), axis=1)
    return positions[keep], colors[keep]


def _margin_colors(margin: np.ndarray) -> np.ndarray:
    """Diverging colours: red (negative) - white (0) - green (positive)."""
    finite = np.isfinite(margin)
    scale = float(np.max(np.abs(margin[finite]))) if finite.any() else 1.0
    scale = scale or 1.0
    t = np.clip(np.where(finite, margin, 0.0) / scale, -1.0, 1.0)[:, None]
    white = np.ones(3)
    pos = white + t * (np.array(COLORS["yes"]) - white)
    neg = white - t * (np.array(COLORS["no"]) - white)
    out = np.where(t >= 0, pos, neg)
    out[~finite] = COLORS["not_analysed"]
    return out


# --------------------------------------------------------------------------
# interactive inspection


class PoseInspector:
    """Sliders over the natural coordinates driving a viewer and a text panel.

    The update logic lives here (not in a notebook) so that it is testable
    and timed: :meth:`set_coordinate` is what a slider change calls.

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: first pose; default the spec's first pose, else neutral.
        viewer: a :class:`Viewer` to update, or None for the text panel only.

    Attributes:
        natural: current natural coordinates (nv,).
        ranges: slider range of each coordinate (:func:`coordinate_ranges`).
        state: the current :class:`PoseState`.
        update_seconds: wall time of each update since creation [s].
    """

    def __init__(self, robot, q: Any = None, *, viewer: Viewer | None = None) -> None:
        self.robot = robot
        self.viewer = viewer
        q0 = robot.as_q(_default_pose(robot) if q is None else q)
        self.natural = robot.to_natural(q0)
        self.ranges = coordinate_ranges(robot, self.natural)
        self.update_seconds: list[float] = []
        self.sliders: dict[str, Any] = {}
        self.panel = None
        self.state = self._update()

    def _update(self) -> PoseState:
        t0 = time.perf_counter()
        if self.viewer is not None:
            state = self.viewer.display(self.natural)
        else:
            state = pose_state(self.robot, self.natural)
        self.state = state
        if self.panel is not None:
            self.panel.value = state._repr_html_()
        self.update_seconds.append(time.perf_counter() - t0)
        return state

    @property
    def text(self) -> str:
        """The text panel: verdict, margin, pose, tensions, slack cables."""
        return str(self.state)

    def set_coordinate(self, name: str, value: float) -> PoseState:
        """Set one natural coordinate [rad or m] and update the view and panel."""
        names = list(self.robot.coordinate_names)
        if name not in names:
            raise InputError(f"no coordinate {name!r}; coordinates: {', '.join(names)}")
        value = float(value)
        if not math.isfinite(value):
            raise InputError(f"{name} = {value!r} is not a finite number")
        natural = self.natural.copy()
        natural[names.index(name)] = value
        self.natural = natural
        return self._update()

    def set_natural(self, natural: Any) -> PoseState:
        """Set all natural coordinates (nv,) and update the view and panel."""
        q = self.robot.as_q(natural)
        self.natural = self.robot.to_natural(q)
        for name, v in zip(self.robot.coordinate_names, self.natural, strict=True):
            slider = self.sliders.get(name)
            if slider is not None:
                with slider.hold_trait_notifications():
                    slider.unobserve(self._on_slider, names="value")
                    slider.value = float(v)
                    slider.observe(self._on_slider, names="value")
        return self._update()

    def _on_slider(self, change) -> None:
        self.set_coordinate(change["owner"].description, change["new"])

    def widget(self, steps: int = 200):
        """ipywidgets box: one slider per coordinate, then the text panel.

        Args:
            steps: number of slider steps across each range.

        Raises:
            MissingExtraError: ipywidgets is not installed.
        """
        try:
            import ipywidgets as widgets
        except ImportError as exc:
            raise MissingExtraError(
                f'the sliders need ipywidgets ({exc}); install it with: pip install "cdpm[viz]"'
            ) from exc
        self.sliders = {}
        for name, (lo, hi) in self.ranges.items():
            value = float(self.natural[list(self.robot.coordinate_names).index(name)])
            slider = widgets.FloatSlider(
                value=value,
                min=lo,
                max=hi,
                step=(hi - lo) / steps,
                description=name,
                continuous_update=True,
                readout_format=".3f",
                layout=widgets.Layout(width="480px"),
            )
            slider.observe(self._on_slider, names="value")
            self.sliders[name] = slider
        self.panel = widgets.HTML(self.state._repr_html_())
        return widgets.VBox([*self.sliders.values(), self.panel])


if __name__ == "__main__":  # the server process started by Viewer
    _serve()
