"""The meshcat 3-D view of a cable robot: :class:`Viewer`.

The scene is built once (links, anchors, attachment points, cables, output
frames); :meth:`Viewer.display` then moves it to a pose and recolours the
cables by state and the output marker by the POC verdict, and
:meth:`Viewer.show_map` overlays a workspace map. meshcat and pinocchio are
imported when a viewer is made.
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

from cdpm.errors import CdpmError, InputError, MissingExtraError, ModelError
from cdpm.viewer.overlay import check_map_spec, map_points
from cdpm.viewer.server import SERVER_TIMEOUT, _Server, check_port
from cdpm.viewer.state import (
    COLORS,
    PoseGeometry,
    PoseState,
    cable_colors,
    centres_of_mass,
    default_pose,
    pose_state,
    skeleton_segments,
    tension_scale,
)

__all__ = ["Viewer"]

#: Colour Pinocchio gives URDF visuals that have no material.
_PIN_DEFAULT_COLOR = (0.9, 0.9, 0.9, 1.0)


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
        self._geometry = PoseGeometry(robot)
        self._tension_scale = tension_scale
        self._cable_colors: list[tuple[float, float, float] | None] = []
        self._marker_color: tuple[float, float, float] | None = None
        self.state: PoseState | None = None
        #: seconds spent in the last :meth:`display`: ``analysis`` and ``draw``
        self.last_display_seconds: dict[str, float] = {}
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
        for k, (j, a, b) in enumerate(skeleton_segments(self.robot.model)):
            path = f"cdpm/robot/joint{j}/link{k}"
            self._send(path, "set_object", g.Cylinder(1.0, 0.012 * s), link)
            self._send(path, "set_transform", _segment_transform(a, b))
        joint = g.MeshPhongMaterial(color=_rgb_int(COLORS["joint"]))
        for j in range(1, self.robot.model.njoints):
            self._send(f"cdpm/robot/joint{j}/axis", "set_object", g.Sphere(0.02 * s), joint)
        com = g.MeshPhongMaterial(color=_rgb_int(COLORS["com"]))
        for j, c in centres_of_mass(self.robot.model):
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
        self._set_marker_color(state.verdict_rgb)
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
                analysed), ``"margin"`` (red negative through white to green
                positive, scaled by the largest |margin|; NaN grey), or any map
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
