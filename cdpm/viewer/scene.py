"""The meshcat 3-D view of a cable robot: :class:`Viewer`.

The scene is built once (links, anchors, attachment points, cables, output
frames); :meth:`Viewer.display` then moves it to a pose and recolours the
cables by state and the output marker by the POC verdict,
:meth:`Viewer.play` moves it through a simulated motion in real time (cables
coloured by their tension at each instant), and :meth:`Viewer.show_map`
overlays a workspace map. The URDF's ``package://`` meshes are found in
the installed packages
(:func:`cdpm.viewer.state.mesh_package_dirs`). meshcat and pinocchio
are imported when a viewer is made.
"""

from __future__ import annotations

import contextlib
import html
import io
import math
import time
import warnings
import weakref
from typing import Any

import numpy as np

from cdpm.dynamics.simulation import Trajectory
from cdpm.errors import CdpmError, InputError, MissingExtraError, ModelError
from cdpm.viewer.output_marks import OutputMarks
from cdpm.viewer.output_marks import rgb_int as _rgb_int
from cdpm.viewer.output_marks import segment_transform as _segment_transform
from cdpm.viewer.overlay import check_map_spec, map_points
from cdpm.viewer.server import SERVER_TIMEOUT, _Server, check_port
from cdpm.viewer.state import (
    COLORS,
    PoseGeometry,
    PoseState,
    cable_colors,
    centres_of_mass,
    default_pose,
    link_segments,
    mesh_package_dirs,
    meshes_outside,
    pose_state,
    tension_colors,
    tension_scale,
)

__all__ = ["Viewer"]

#: Colour Pinocchio gives URDF visuals that have no material.
_PIN_DEFAULT_COLOR = (0.9, 0.9, 0.9, 1.0)

#: Wall time [s] the last frame stays between passes of a looping playback.
_LOOP_PAUSE = 0.5


def _import_meshcat():
    try:
        # optional: cdpm[viz]
        import meshcat
        import meshcat.geometry
        import meshcat.servers.zmqserver  # noqa: F401
        import meshcat.visualizer
    except ImportError as exc:
        raise MissingExtraError(
            f'the 3-D viewer needs meshcat ({exc}); install it with: pip install "cdpm[viz]"'
        ) from exc
    return meshcat


def _one_line(message: Any) -> str:
    """A Pinocchio or coal error message on one line, without the C++
    source location coal puts before its ``message:``."""
    return " ".join(str(message).split("message:", 1)[-1].split())


def _positive(value: Any, name: str, hint: str, allow_zero: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if not (math.isfinite(x) and (x > 0 or (allow_zero and x == 0))):
        kind = "a non-negative" if allow_zero else "a positive"
        raise InputError(f"{name}={value!r} must be {kind} number: {hint}")
    return x


def _as_trajectory(trajectory: Any, robot):
    """The :class:`cdpm.Trajectory` of a trajectory or a steering result,
    checked against the robot."""

    traj = getattr(trajectory, "trajectory", trajectory)
    if not isinstance(traj, Trajectory):
        raise InputError(
            "play takes a Trajectory (cdpm.simulate) or a SteerResult (cdpm.steer), "
            f"got {type(trajectory).__name__}"
        )
    if tuple(traj.cable_names) != tuple(robot.cable_names):
        raise InputError(
            f"the trajectory's cables ({', '.join(traj.cable_names)}) are not this "
            f"robot's ({', '.join(robot.cable_names)}); simulate this robot"
        )
    n = traj.t.shape[0]
    if traj.q.shape != (n, robot.nq) or traj.f.shape != (n, robot.n_cables) or n < 1:
        raise InputError(
            f"the trajectory has q of shape {traj.q.shape} and f of shape {traj.f.shape}; "
            f"expected ({n}, {robot.nq}) and ({n}, {robot.n_cables}) for {n} sample times"
        )
    if np.any(np.diff(traj.t) <= 0) or not np.all(np.isfinite(traj.t)):
        raise InputError("the trajectory's sample times must be finite and increasing")
    return traj


def _translation(p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


class Viewer:
    """meshcat view of a cable robot, its cables and the POC verdict.

    Starts a meshcat server (web and zmq ports on 127.0.0.1 only) in a
    subprocess, or connects to a running one with ``zmq_url``; open
    :meth:`url` in a browser. The scene is built once; :meth:`display` and
    each frame of :meth:`play` then only send transforms, and materials of
    cables whose colour changed.

    Scene (meshcat paths under ``/meshcat/cdpm``): ``robot`` (URDF visuals or
    generated links: from each joint to its child joints and to the points
    it carries), ``anchors`` (route points fixed to the world, dark
    spheres), ``attachments`` (route points on links, grey spheres),
    ``cables/<name>/<k>`` (segment k of a cable: taut blue by tension, slack
    pink, unavailable grey), ``output/<frame>`` (a marker on each output
    point, coloured by the verdict: green YES, red NO, amber MARGINAL, grey
    unavailable; with the frame's axes, ``output/<frame>/triad``, where an
    orientation output is drawn), ``cables/<name>/<k>/output`` (a sleeve in
    the verdict colour on a cable whose length is an output), ``map``
    (workspace map); see :mod:`cdpm.viewer.output_marks`.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: first pose (name, configuration or natural coordinates); default
            the spec's first pose, else neutral.
        port: web port of the started server, 1-65535 or 0 (any free port)
            (default: first free from 7000).
        zmq_url: connect to this running meshcat server instead of starting one.
        geometry: ``"auto"`` (URDF visuals when the URDF has some and they
            load, else generated; one warning names a mesh that cannot be
            loaded, or that lies outside the model's folder and its
            ``package://`` packages, :func:`~cdpm.viewer.state.meshes_outside`,
            and is not loaded), ``"urdf"`` or ``"generated"``.
        tension_scale: tension [N] drawn in the darkest taut colour (default
            :func:`tension_scale`).

    Raises:
        MissingExtraError: meshcat is not installed.
        InputError: a port outside 0-65535 or an unknown geometry.
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
            port = check_port(port, any_free=True)
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
            # optional: cdpm[viz]
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
        self._geometry = PoseGeometry(robot)
        self._tension_scale = tension_scale
        self._cable_colors: list[tuple[float, float, float] | None] = []
        self.state: PoseState | None = None
        #: seconds spent in the last :meth:`display`: ``analysis`` and ``draw``
        self.last_display_seconds: dict[str, float] = {}
        try:  # the server stops at once when the scene cannot be built
            q0 = robot.as_q(default_pose(robot) if q is None else q)
            self._geometry.update(q0)
            self._size = self._scene_size()
            self._pin_viz = None
            self.geometry = self._build_robot(geometry)
            self._build_points()
            self._build_cables()
            self._build_outputs()
            self._set_camera()
            self.display(q0)
        except BaseException:
            self.close()
            raise

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
    def cable_colors(self) -> tuple[tuple[float, float, float] | None, ...]:
        """RGB colour (0..1) each cable is drawn in now (None before the first draw)."""
        return tuple(self._cable_colors)

    @property
    def marker_color(self) -> tuple[float, float, float] | None:
        """RGB colour (0..1) of the output markers now: the POC verdict's
        (None before the first draw)."""
        return self._marks.color

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
        with self._answered():
            getattr(self._root[path], method)(*args)

    @contextlib.contextmanager
    def _answered(self):
        """Turn a request the meshcat server leaves unanswered into a CdpmError."""
        try:
            yield
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
        """Draw the links; returns ``"urdf"`` or ``"generated"``.

        With ``"auto"``, a URDF visual that cannot be shown (a mesh not
        found or not readable) gives one warning naming it, and the
        generated links are drawn instead.
        """
        if mode in ("auto", "urdf"):
            visual = self._visual_model(required=mode == "urdf")
            if visual is not None and visual.ngeoms > 0:
                # scipy: loaded on first use
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
                    viz.loadViewerModel(rootNodeName="cdpm/model/robot", visual_color=color)
                if not caught:
                    self._pin_viz = viz
                    return "urdf"
                problem = _one_line(caught[0].message)
                more = f" (and {len(caught) - 1} more)" if len(caught) > 1 else ""
                if mode == "urdf":
                    raise ModelError(
                        f"some URDF visual geometry could not be shown: {problem}{more}; "
                        "use geometry='generated'"
                    )
                self._send("cdpm/model/robot", "delete")
                warnings.warn(
                    f"URDF visual geometry not shown: {problem}{more}; drawing generated links",
                    stacklevel=3,
                )
            elif mode == "urdf":
                raise ModelError(
                    f"{self.robot.spec.urdf_path.name} has no <visual> geometry; "
                    "use geometry='generated' (or 'auto')"
                )
        g, s = self._g, self._size
        link = g.MeshPhongMaterial(color=_rgb_int(COLORS["link"]))
        for k, (j, a, b) in enumerate(link_segments(self.robot)):
            path = f"cdpm/model/robot/joint{j}/link{k}"
            self._send(path, "set_object", g.Cylinder(1.0, 0.012 * s), link)
            self._send(path, "set_transform", _segment_transform(a, b))
        joint = g.MeshPhongMaterial(color=_rgb_int(COLORS["joint"]))
        for j in range(1, self.robot.model.njoints):
            self._send(f"cdpm/model/robot/joint{j}/axis", "set_object", g.Sphere(0.02 * s), joint)
        com = g.MeshPhongMaterial(color=_rgb_int(COLORS["com"]))
        for j, c in centres_of_mass(self.robot.model):
            path = f"cdpm/model/robot/joint{j}/com"
            self._send(path, "set_object", g.Sphere(0.016 * s), com)
            self._send(path, "set_transform", _translation(c))
        return "generated"

    def _visual_model(self, required: bool):
        """The URDF's visual geometry, its meshes found in
        :func:`~cdpm.viewer.state.mesh_package_dirs`; None (after one
        warning naming the missing file) when it cannot be loaded and not
        ``required``."""
        # pinocchio: loaded on first use
        import pinocchio as pin

        urdf = self.robot.spec.urdf_path
        # a mesh outside the model (e.g. /home/you/.ssh/key as a mesh) is
        # neither read nor sent to the browser
        outside = meshes_outside(urdf, [self.robot.spec.path.parent, urdf.parent])
        if outside:
            more = f" (and {len(outside) - 1} more)" if len(outside) > 1 else ""
            problem = (
                f"{outside[0]}{more}; the viewer loads meshes only from the model's "
                "folder or a package:// package (move the mesh there)"
            )
            if required:
                raise ModelError(
                    f"URDF visual geometry not loaded: {problem}, or use geometry='generated'"
                )
            warnings.warn(
                f"URDF visual geometry not loaded: {problem}; drawing generated links",
                stacklevel=4,
            )
            return None
        dirs = mesh_package_dirs(urdf)
        try:
            return pin.buildGeomFromUrdf(
                self.robot.model,
                str(urdf),
                pin.GeometryType.VISUAL,
                package_dirs=[str(d) for d in dirs],
            )
        except (ValueError, RuntimeError, OSError) as exc:
            where = ", ".join(str(d) for d in dirs)
            problem = f"{_one_line(exc)} (looked in: {where})"
            if required:
                raise ModelError(
                    f"cannot load the visual geometry of {urdf}: {problem}; "
                    "check the mesh paths or use geometry='generated'"
                ) from exc
            warnings.warn(
                f"URDF visual geometry not loaded: {problem}; drawing generated links",
                stacklevel=4,
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
        """Markers at the output points, under ``output/<frame>``
        (``output/<frame>.<k>`` for the k-th further point of a frame), the
        axes of the frames of orientation outputs, sleeves on the cables
        whose lengths are outputs (:class:`OutputMarks`)."""
        geo = self._geometry
        self._marks = OutputMarks(
            self._send,
            self._g,
            geo.drawing,
            self.robot.cable_names,
            [s.stop - s.start - 1 for s in geo.route_slices],
            self._size,
        )

    def _set_marker_color(self, rgb: tuple[float, float, float]) -> None:
        self._marks.set_color(rgb)

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

    def display(self, q: Any, *, report: Any = None, reason: str | None = None) -> PoseState:
        """Move the robot, cables and output to q and recolour by state and verdict.

        Args:
            q: a pose name, a configuration vector (nq,) or natural coordinates (nv,).
            report, reason: what :func:`cdpm.analyze_pose` gave at q, to show
                without analysing again (see :func:`pose_state`).

        Returns:
            The :class:`PoseState` shown (also kept as :attr:`state`).
        """
        t0 = time.perf_counter()
        # pose_state also updates the kinematics
        state = pose_state(self.robot, q, self._geometry, report=report, reason=reason)
        t1 = time.perf_counter()
        scale = self._tension_scale or tension_scale(self.robot, state.tension)
        self._draw(state.q, cable_colors(state, scale), state.verdict_rgb)
        t2 = time.perf_counter()
        self.state = state
        self.last_display_seconds = {"analysis": t1 - t0, "draw": t2 - t1, "total": t2 - t0}
        return state

    def _draw(
        self,
        q: np.ndarray,
        cable_rgb: list[tuple[float, float, float]],
        marker_rgb: tuple[float, float, float],
    ) -> None:
        """Send the transforms of the pose q (the geometry already updated at
        q) and the materials of cables and marker whose colour changed."""
        geo = self._geometry
        if self._pin_viz is not None:
            with self._answered():
                self._pin_viz.display(q)
        else:
            placements = geo.joint_placements()
            for j in range(1, self.robot.model.njoints):
                self._send(f"cdpm/model/robot/joint{j}", "set_transform", placements[j])
        points = geo.points()
        for k, joint in enumerate(geo.point_joint):
            if joint != 0:
                self._send(f"cdpm/attachments/p{k}", "set_transform", _translation(points[k]))
        for i, (name, rgb) in enumerate(zip(self.robot.cable_names, cable_rgb, strict=True)):
            self._set_cable_color(i, rgb)
            route = points[geo.route_slices[i]]
            for k in range(len(route) - 1):
                self._send(
                    f"cdpm/cables/{name}/{k}",
                    "set_transform",
                    _segment_transform(route[k], route[k + 1]),
                )
        self._set_marker_color(marker_rgb)
        self._marks.place(geo.output_placements())

    # ------------------------------------------------------------ playback

    def play(
        self,
        trajectory,
        *,
        speed: float = 1.0,
        fps: float = 30,
        loop: bool = False,
        seconds: float | None = None,
    ) -> int:
        """Play a motion in real time: robot, cables and output marker.

        The trajectory's samples are resampled to ``fps`` frames per second
        of wall time (configurations interpolated on the configuration
        manifold, tensions as simulated: a profile's held value, else
        interpolated); the last frame is the trajectory's last sample. Each
        frame sends only transforms, and materials of cables whose colour
        changed; nothing is analysed. Cables are coloured by their tension at
        that instant on the scale of :meth:`display` (:func:`tension_colors`:
        at the lower bound slack pink, else light blue to navy up to the
        viewer's ``tension_scale``, default the cables' largest finite upper
        bound, else the trajectory's largest tension). The output marker is
        grey (not analysed) while playing: the poses of a motion are not
        equilibria; :meth:`display` analyses again. When drawing falls behind
        the clock, frames are dropped (never the last one of a pass).

        Args:
            trajectory: a :class:`cdpm.Trajectory` (:func:`cdpm.simulate`) or
                a :class:`cdpm.SteerResult` (its ``trajectory``), of this robot.
            speed: playback rate; 2 plays twice as fast as simulated time.
            fps: frames per second of wall time.
            loop: play again and again (with a 0.5 s pause on the last frame
                between passes) until Ctrl-C or ``seconds``.
            seconds: stop after this many seconds of wall time (waiting on
                the last frame when the playback ends earlier without loop).

        Returns:
            The number of frames shown. Ctrl-C ends a looping playback and
            returns normally; a single pass re-raises it (the viewer stays
            usable either way). :attr:`state` is None afterwards.

        Raises:
            InputError: not a trajectory of this robot, or bad speed, fps or seconds.
        """
        traj = _as_trajectory(trajectory, self.robot)
        speed = _positive(speed, "speed", "a playback rate, e.g. 1.0 for real time")
        fps = _positive(fps, "fps", "frames per second, e.g. 30")
        if seconds is not None:
            seconds = _positive(seconds, "seconds", "wall time [s]", allow_zero=True)
        wall, qs, colors = self._frames(traj, speed, fps)
        self.state = None
        self._set_marker_color(COLORS["not_analysed"])
        shown = 0
        start = time.perf_counter()
        offset = 0.0  # wall time [s] of the current pass's first frame
        try:
            while True:
                for k in range(wall.size):
                    due = offset + wall[k]
                    if seconds is not None and due > seconds:
                        time.sleep(max(seconds - (time.perf_counter() - start), 0.0))
                        return shown
                    now = time.perf_counter() - start
                    if k + 1 < wall.size and now > offset + wall[k + 1]:
                        continue  # late: drop this frame, keep real time
                    if due > now:
                        time.sleep(due - now)
                    self._geometry.update(qs[k])
                    self._draw(qs[k], colors[k], COLORS["not_analysed"])
                    shown += 1
                if not loop:
                    break
                offset += wall[-1] + _LOOP_PAUSE
            if seconds is not None:
                time.sleep(max(seconds - (time.perf_counter() - start), 0.0))
        except KeyboardInterrupt:
            self._drain_reply()
            if not loop:
                raise
        return shown

    def _frames(self, traj, speed: float, fps: float):
        """One pass: wall times (n,) [s], configurations (n, nq) and cable colours."""
        # pinocchio: loaded on first use
        import pinocchio as pin

        t = traj.t
        duration = float(t[-1] - t[0]) / speed  # wall time of a pass
        n = int(math.ceil(duration * fps - 1e-9)) + 1 if duration > 0 else 1
        wall = np.minimum(np.arange(n) / fps, duration)
        at = t[0] + wall * speed  # trajectory times
        at[-1] = t[-1]
        scale = self._tension_scale or tension_scale(self.robot, traj.f)
        model = self.robot.model
        qs = np.empty((n, traj.q.shape[1]))
        colors = []
        for k, s in enumerate(at):
            i = min(max(int(np.searchsorted(t, s, side="right")) - 1, 0), max(t.size - 2, 0))
            alpha = 0.0 if t.size == 1 else (s - t[i]) / (t[i + 1] - t[i])
            if alpha <= 0.0:
                qs[k] = traj.q[i]
            elif alpha >= 1.0:
                qs[k] = traj.q[i + 1]
            else:
                qs[k] = pin.interpolate(model, traj.q[i], traj.q[i + 1], alpha)
            if traj.profile is not None:
                f = traj.profile(s)
            elif t.size == 1:
                f = traj.f[0]
            else:
                f = traj.f[i] + min(max(alpha, 0.0), 1.0) * (traj.f[i + 1] - traj.f[i])
            colors.append(tension_colors(f, self.robot.tension_min, self.robot.tension_max, scale))
        return wall, qs, colors

    def _drain_reply(self) -> None:
        """After an interrupt: take the server's reply to a request sent just
        before it, so the zmq REQ socket accepts the next one."""
        zmq, socket = self._zmq, self._window.zmq_socket
        try:
            socket.recv(zmq.NOBLOCK)
        except zmq.Again:  # the reply is on its way
            if socket.poll(int(SERVER_TIMEOUT * 1000)):
                socket.recv()
        except zmq.ZMQError:  # no request outstanding
            pass

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
                ``reach_margin`` and ``output_frame_position`` (dims
                ``(..., "xyz")``, world position [m] of the first output's frame).
            color_by: ``"verdict"`` (green YES, red NO, amber MARGINAL, grey not
                analysed), ``"margin"`` (the reach margin, light to dark blue from
                its least to its largest value; NaN grey), or any map
                criterion with a plot hint (:func:`cdpm.viewer.overlay.color_choices`:
                verdicts in verdict colours, quantities light to dark blue).
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
