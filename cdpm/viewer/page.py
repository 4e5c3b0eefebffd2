"""The inspection page of ``cdpm view``: the 3-D scene beside a live panel.

:class:`InspectionPage` serves one page on 127.0.0.1: meshcat's own viewer
(an iframe on the page's own origin, see below) beside a panel with a
slider per natural coordinate, the verdicts at the pose, a colour legend,
each cable's state and tension, the outputs, a picker of the spec's named
poses, a "copy as --q" button and, with a workspace map, a toggle of its
overlay. The page's files are ``cdpm/viewer/static/page.{html,js,css}`` and
``scene.html``; each pose is one request to a JSON
endpoint, answered by one :func:`~cdpm.viewer.panel.pose_panel` call (one
:func:`cdpm.analyze_pose`, then the scene drawn from that report).

Endpoints (loopback only):

- ``GET /``: the page; ``GET /static/page.js`` and ``/static/page.css``;
- ``GET /scene/``: meshcat's viewer (``static/scene.html`` and meshcat's
  own ``main.min.js``); ``GET /scene/ws``, a websocket, is piped byte for
  byte to the meshcat server's websocket. So page, scene and the scene's
  websocket share one origin, every URL is relative, and the page works
  under either loopback name and through a forwarded port;
- ``GET /api/model``: sliders, named poses, legend, map, the current panel;
- ``POST /api/pose``: ``{"natural": [nv numbers]}`` [rad or m] or
  ``{"pose": NAME}`` -> the panel at that pose;
- ``POST /api/map``: ``{"visible": true|false}`` -> the map overlay shown or hidden.

Every request must name a loopback host (DNS rebinding is refused) and come
from no page or a loopback page; a POST and the websocket must come from
the page itself (same origin), and a POST must carry the page's token
(``X-Cdpm-Token``, written into the page when it is served, so another
site's form or script cannot change the pose) and be JSON
(``Content-Type: application/json``, else 415). Refusals are 403, a body
over 1 MiB 413, a malformed one 400; a client that goes away mid-answer is
let go silently.

The server is the standard library's threading HTTP server (HTTP/1.1,
kept-alive connections), in a thread of the process that holds the robot;
one pose is analysed and drawn at a time (the viewer's zmq socket is not
shared between threads). The page itself keeps one request in flight and
coalesces slider moves that arrive meanwhile into the next one.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import http.server
import json
import math
import secrets
import select
import socket
import sys
import threading
from importlib import resources
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

import numpy as np

from cdpm.errors import CdpmError, InputError, float_array
from cdpm.printing import strict
from cdpm.verdicts import VERDICT_COLORS, VERDICT_LABELS, VERDICT_ORDER
from cdpm.viewer.coordinates import coordinate_sliders
from cdpm.viewer.outputs import output_drawing
from cdpm.viewer.panel import PosePanel, pose_panel, rgb_hex
from cdpm.viewer.scene import Viewer
from cdpm.viewer.server import LOOPBACK, SERVER_TIMEOUT, check_port, host_problem, origin_problem
from cdpm.viewer.state import AXIS_RGB, COLORS, default_pose, tension_scale

if TYPE_CHECKING:  # pragma: no cover - for static type checkers only
    from cdpm.model.robot import CableRobot

__all__ = ["InspectionPage", "PAGE_PORTS"]

#: Ports tried, in order, when no port is given: the first free one is used.
PAGE_PORTS = range(7000, 7100)

#: Slider steps across each coordinate's range.
SLIDER_STEPS = 1000

#: Largest request body accepted [bytes].
_MAX_BODY = 1 << 20

#: The page's files (in ``cdpm/viewer/static``) and their content types.
_STATIC = {
    "page.html": "text/html; charset=utf-8",
    "page.js": "text/javascript; charset=utf-8",
    "page.css": "text/css; charset=utf-8",
}

#: What ``page.html`` holds where the page's token goes.
_TOKEN_SLOT = "{{cdpm-token}}"

#: The header a POST carries the page's token in.
TOKEN_HEADER = "X-Cdpm-Token"

#: Files of meshcat's viewer (``meshcat/viewer/dist``) served under /scene/.
_SCENE_FILES = {"main.min.js": "text/javascript; charset=utf-8"}

#: Bytes read at once from either end of the scene's websocket.
_PIPE_CHUNK = 1 << 16

#: Connection errors of a client that went away (nothing to answer).
_GONE = (ConnectionError, TimeoutError)


class InspectionPage:
    """The inspection page of a robot, served on 127.0.0.1 until closed.

    Starts a :class:`~cdpm.viewer.Viewer` (meshcat server on its own
    loopback port, the first free from 7000) and the page's server on
    ``port``; open :attr:`url` in a browser. Use it as a context manager or
    call :meth:`close`.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: first pose (name, configuration or natural coordinates); default
            the spec's first pose, else neutral.
        port: port of the page, 1-65535 or 0 (any free port) (default: the
            first free of :data:`PAGE_PORTS`).
        scene_port: port of the meshcat server, 1-65535 or 0 (any free
            port) (default: the first free from 7000). The page reaches the
            scene through its own port; the scene's port serves it alone
            (:meth:`Viewer.url`).
        dataset: a workspace map (``xarray.Dataset`` from ``cdpm map``) to
            overlay, already checked against the robot's spec, or None.
        map_name: what the page calls the map (e.g. its store's path).
        color_by: colour of the map points (see :meth:`Viewer.show_map`).
        geometry: link geometry of the viewer (``"auto"``, ``"urdf"``, ``"generated"``).

    Attributes:
        robot: the robot.
        viewer: the :class:`~cdpm.viewer.Viewer` drawing the scene.
        panel: the :class:`~cdpm.viewer.panel.PosePanel` shown now.
        pose_name: the named pose shown now, or None.
        map_points: points of the map overlay (0 without a map).
        map_visible: whether the map overlay is shown.
        token: the page's token: a POST without it is refused (403).

    Raises:
        InputError: a port outside 0-65535, or a port in use.
        CdpmError: the meshcat server could not start.
    """

    def __init__(
        self,
        robot: CableRobot,
        q: Any = None,
        *,
        port: int | None = None,
        scene_port: int | None = None,
        dataset=None,
        map_name: str | None = None,
        color_by: str = "verdict",
        geometry: str = "auto",
    ) -> None:
        self.robot = robot
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.viewer: Viewer | None = None
        self.token = secrets.token_urlsafe(24)
        if scene_port is not None:
            scene_port = check_port(scene_port, any_free=True)
        # before meshcat's port
        self._http = _bind(None if port is None else check_port(port, any_free=True))
        try:
            q = default_pose(robot) if q is None else q
            self.pose_name = q if isinstance(q, str) else None
            q0 = robot.as_q(q)
            self.viewer = Viewer(robot, q0, port=scene_port, geometry=geometry)
            self.scene_port = int(urlsplit(self.viewer.url()).port)
            self._dataset, self._map_name, self._color_by = dataset, map_name, color_by
            self.map_points, self.map_visible = 0, False
            if dataset is not None:
                self.set_map_visible(True)
            self._sliders = _slider_model(robot, robot.to_natural(q0))
            self.panel = pose_panel(robot, q0, viewer=self.viewer)
        except BaseException:
            self.close()
            raise
        self._http.page = self
        self._thread = threading.Thread(
            target=self._http.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True
        )
        self._thread.start()

    # ------------------------------------------------------------ lifecycle

    @property
    def port(self) -> int:
        """The page's port on 127.0.0.1."""
        return int(self._http.server_address[1])

    @property
    def url(self) -> str:
        """URL of the page (http://127.0.0.1:PORT/)."""
        return f"http://{LOOPBACK}:{self.port}/"

    def close(self) -> None:
        """Stop the page's server (and the scene's websockets it pipes) and
        the viewer's meshcat server."""
        if self._thread is not None:
            self._http.shutdown()
            self._thread.join()
            self._thread = None
        self._http.close_pipes()
        self._http.server_close()
        if self.viewer is not None:
            self.viewer.close()

    def __enter__(self) -> InspectionPage:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"InspectionPage({self.robot.spec.path.name!r}, url={self.url!r})"

    # ------------------------------------------------------------ actions

    def set_pose(self, natural: Any = None, *, pose: str | None = None) -> PosePanel:
        """Analyse and show a pose: what a slider move or the picker does.

        Args:
            natural: natural coordinates (nv,) [rad or m].
            pose: a named pose of the spec instead.

        Raises:
            InputError: neither or both given, not nv finite numbers, or an unknown pose.
        """
        if (natural is None) == (pose is None):
            raise InputError("give natural coordinates or a pose name, not both or neither")
        if pose is not None:
            q = self.robot.configuration(str(pose))  # unknown names fail, listing the poses
        else:
            q = self.robot.configuration(_natural(self.robot, natural))
        with self._lock:
            self.panel = pose_panel(self.robot, q, viewer=self.viewer)
            self.pose_name = None if pose is None else str(pose)
        return self.panel

    def set_map_visible(self, visible: bool) -> None:
        """Show or hide the workspace map overlay.

        Raises:
            InputError: there is no map to show.
        """
        if self._dataset is None:
            raise InputError("no workspace map to show; start cdpm view with --map STORE")
        with self._lock:
            if visible:
                self.map_points = self.viewer.show_map(
                    self._dataset, color_by=self._color_by, check_spec=False
                )
            else:
                self.viewer.hide_map()
            self.map_visible = bool(visible)

    # ------------------------------------------------------------ content

    def panel_dict(self) -> dict:
        """The current panel as the page gets it (JSON-serialisable)."""
        return strict({**self.panel.as_dict(), "pose": self.pose_name})

    def model_dict(self) -> dict:
        """What the page loads first: sliders, poses, legend, map, panel."""
        robot = self.robot
        return strict(
            {
                "model": robot.spec.path.name,
                "coordinates": self._sliders,
                "poses": [
                    {"name": name, "natural": robot.to_natural(q).tolist()}
                    for name, q in robot.poses.items()
                ],
                "scene": {"path": "scene/"},
                "legend": _legend(robot),
                "map": None
                if self._dataset is None
                else {
                    "name": self._map_name,
                    "points": self.map_points,
                    "color_by": self._color_by,
                    "visible": self.map_visible,
                },
                "panel": self.panel_dict(),
            }
        )


def _natural(robot: CableRobot, natural: Any) -> np.ndarray:
    """Natural coordinates from a request: nv finite numbers."""
    names = ", ".join(robot.coordinate_names)
    try:
        values = float_array(natural, copy=True).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"natural must be {robot.nv} numbers ({names}), got {natural!r}") from exc
    if values.size != robot.nv or not np.all(np.isfinite(values)):
        raise InputError(f"natural must be {robot.nv} finite numbers ({names}), got {natural!r}")
    return values


def _nice_step(span: float) -> float:
    """The largest of 1, 2, 5 x 10^k [rad or m] that cuts ``span`` into at
    least :data:`SLIDER_STEPS` steps."""
    raw = span / SLIDER_STEPS
    if not (math.isfinite(raw) and raw > 0):
        return 1e-3
    exponent = math.floor(math.log10(raw))
    for mantissa in (5, 2, 1):
        step = float(f"{mantissa}e{exponent}")
        if step <= raw:
            return step
    return float(f"1e{exponent - 1}")


def _slider_model(robot: CableRobot, natural: np.ndarray) -> list[dict]:
    """One slider per coordinate: range (:func:`coordinate_sliders`, widened
    to hold every named pose), unit and step.

    The step is a round number and the ends are multiples of it within the
    range, so the browser's slider (which snaps to ``min + k step`` in
    decimal arithmetic) reaches round values such as 0 exactly; the number
    field beside it takes any value.
    """
    sliders = coordinate_sliders(robot, natural)
    named = [robot.to_natural(q) for q in robot.poses.values()]
    out = []
    for i, s in enumerate(sliders):
        low = min([s.low, *(n[i] for n in named)])
        high = max([s.high, *(n[i] for n in named)])
        step = _nice_step(high - low)
        digits = max(0, -math.floor(math.log10(step))) + 1
        out.append(
            {
                "name": s.name,
                "low": round(math.ceil(low / step - 1e-9) * step, digits),
                "high": round(math.floor(high / step + 1e-9) * step, digits),
                "step": step,
                "unit": s.unit,
            }
        )
    return out


def _output_legend(robot: CableRobot) -> list[dict]:
    """How the robot's outputs are drawn in the scene, one entry per kind
    present (:mod:`cdpm.viewer.outputs`)."""
    drawing = output_drawing(robot)
    entries = []
    if any(not point.rotation for point in drawing.points):
        entries.append(
            {
                "label": "marker",
                "meaning": "sphere on an output point, in the POC verdict's colour",
            }
        )
    if any(point.rotation for point in drawing.points):
        names = ", ".join(p.label for p in drawing.points if p.rotation)
        entries.append(
            {
                "label": "axes",
                "color": rgb_hex(AXIS_RGB[0]),
                "to": rgb_hex(AXIS_RGB[2]),
                "meaning": "the frame of an orientation output (x red, y green, z blue), "
                f"the verdict marker at its origin: {names}",
            }
        )
    if drawing.cables:
        names = "; ".join(
            f"{robot.cable_names[i]}: {', '.join(outs)}" for i, outs in drawing.cables.items()
        )
        entries.append(
            {
                "label": "sleeve",
                "meaning": "a cable whose length is an output, sleeved in the verdict's "
                f"colour ({names})",
            }
        )
    if drawing.joints:
        names = "; ".join(f"{j}: {', '.join(outs)}" for j, outs in drawing.joints.items())
        entries.append(
            {"label": "joint", "meaning": f"joint outputs have no marker: see Outputs ({names})"}
        )
    return entries


def _legend(robot: CableRobot) -> dict:
    """Verdict, cable and output colours (hex) with their labels."""

    upper = robot.tension_max[np.isfinite(robot.tension_max)]
    if upper.size == robot.n_cables and upper.size:
        scale = f"navy at {tension_scale(robot, None):g} N (the largest upper bound)"
    else:
        scale = "navy at the largest tension of the pose"
    return {
        "verdicts": [
            {
                "label": "unavailable" if code < 0 else VERDICT_LABELS[code].upper(),
                "color": VERDICT_COLORS[code],
            }
            for code in reversed(VERDICT_ORDER)
        ],
        "cables": [
            {
                "label": "taut",
                "color": rgb_hex(COLORS["taut_low"]),
                "to": rgb_hex(COLORS["taut_high"]),
                "meaning": f"tension above its lower bound: light blue at 0 N, {scale}",
            },
            {
                "label": "slack",
                "color": rgb_hex(COLORS["slack"]),
                "meaning": "at its lower bound (zero tension by default): it can only pull harder",
            },
            {
                "label": "unavailable",
                "color": rgb_hex(COLORS["unavailable"]),
                "meaning": "no equilibrium or linearisation at this pose",
            },
        ],
        "outputs": _output_legend(robot),
    }


class _PageServer(http.server.ThreadingHTTPServer):
    """The page's HTTP server: a thread per connection, the scene's
    websockets piped to the meshcat server, and clients that go away let go
    without a traceback."""

    daemon_threads = True

    def __init__(self, address: tuple[str, int]) -> None:
        super().__init__(address, _Handler)
        self.page: InspectionPage | None = None
        self._pipes: set[socket.socket] | None = set()  # None once closing
        self._pipes_lock = threading.Lock()

    def handle_error(self, request, client_address) -> None:
        # socketserver calls this inside the handler's except clause
        if isinstance(sys.exc_info()[1], _GONE):
            return  # the browser closed the tab or the connection: nothing to answer
        super().handle_error(request, client_address)

    def add_pipe(self, *sockets: socket.socket) -> bool:
        """Track the sockets of a websocket pipe (False: the server is closing)."""
        with self._pipes_lock:
            if self._pipes is None:
                return False
            self._pipes.update(sockets)
            return True

    def drop_pipe(self, *sockets: socket.socket) -> None:
        with self._pipes_lock:
            if self._pipes is not None:
                self._pipes.difference_update(sockets)

    def close_pipes(self) -> None:
        """End every websocket pipe (their threads then return)."""
        with self._pipes_lock:
            pipes, self._pipes = self._pipes or set(), None
        for sock in pipes:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)


def _bind(port: int | None) -> _PageServer:
    """The page's HTTP server bound to 127.0.0.1:port (0: any free port;
    None: the first free of :data:`PAGE_PORTS`)."""
    ports = [port] if port is not None else list(PAGE_PORTS)
    for p in ports:
        try:
            return _PageServer((LOOPBACK, p))
        except OSError as exc:
            if exc.errno != errno.EADDRINUSE:
                raise CdpmError(f"cannot serve the page on {LOOPBACK}:{p}: {exc}") from exc
    if port is not None:
        raise InputError(f"port {port} is in use; choose another port or omit --port")
    raise CdpmError(f"no free port in {PAGE_PORTS.start}-{PAGE_PORTS.stop - 1} for the page")


@functools.cache
def _static(name: str) -> bytes:
    return resources.files("cdpm.viewer").joinpath("static", name).read_bytes()


@functools.cache
def _scene_file(name: str) -> bytes:
    """A file of meshcat's own viewer (``meshcat/viewer/dist``)."""
    # optional: cdpm[viz] (the page's Viewer has imported it already)
    import meshcat

    return resources.files(meshcat).joinpath("viewer", "dist", name).read_bytes()


def _pipe(one: socket.socket, other: socket.socket) -> None:
    """Copy bytes both ways between two sockets until either end closes."""
    ends = {one: other, other: one}
    try:
        while True:
            readable, _, _ = select.select(list(ends), [], [])
            for sock in readable:
                data = sock.recv(_PIPE_CHUNK)
                if not data:
                    return
                ends[sock].sendall(data)
    except (OSError, ValueError):  # an end reset, or closed by close_pipes
        return


class _Handler(http.server.BaseHTTPRequestHandler):
    """Requests to the page's server (see the module's docstring)."""

    protocol_version = "HTTP/1.1"  # keep connections alive between slider moves
    server_version = "cdpm"
    # headers and body go out in two writes: without TCP_NODELAY the body
    # waits for the client's delayed ACK of the headers (some 40 ms)
    disable_nagle_algorithm = True

    def log_message(self, format: str, *args) -> None:  # noqa: A002 - the base's name
        pass  # the terminal shows the verdict panel, not a request log

    def _send(self, status: int, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, status: int, content: Any) -> None:
        self._send(status, json.dumps(content).encode(), "application/json")

    def _refuse(self, problem: str | None) -> bool:
        """Answer 403 with ``problem`` (True), or go on when it is None (False)."""
        if problem is None:
            return False
        self.close_connection = True
        self._json(403, {"error": problem})
        return True

    def _refused(self, same_origin: bool) -> bool:
        """Refuse (403) a request naming another host (DNS rebinding) or
        sent by another site's page (or, with ``same_origin``, by any page
        but this one)."""
        host = self.headers.get("Host")
        problem = host_problem(host) or origin_problem(
            self.headers.get("Origin"), host if same_origin else None
        )
        return self._refuse(problem)

    def do_GET(self) -> None:
        path = urlsplit(self.path).path
        websocket = path == "/scene/ws"
        if self._refused(same_origin=websocket):
            return
        page = self.server.page
        name = "page.html" if path in ("/", "/index.html") else path.removeprefix("/static/")
        if name in _STATIC and (path.startswith("/static/") or name == "page.html"):
            body = _static(name)
            if name == "page.html":
                body = body.replace(_TOKEN_SLOT.encode(), page.token.encode())
            self._send(200, body, _STATIC[name])
        elif path == "/scene/":  # its relative URLs need the slash
            self._send(200, _static("scene.html"), _STATIC["page.html"])
        elif path.removeprefix("/scene/") in _SCENE_FILES:
            name = path.removeprefix("/scene/")
            self._send(200, _scene_file(name), _SCENE_FILES[name])
        elif websocket:
            self._websocket(page.scene_port)
        elif path == "/api/model":
            self._json(200, page.model_dict())
        else:
            self._json(404, {"error": f"no page {path}; open /"})

    def _websocket(self, port: int) -> None:
        """Pipe the scene's websocket to the meshcat server: the handshake
        request goes on with the meshcat server's own Host, then bytes flow
        both ways unchanged until either end closes."""
        self.close_connection = True
        if self.headers.get("Upgrade", "").lower() != "websocket":
            self._json(400, {"error": "/scene/ws takes a websocket (Upgrade: websocket)"})
            return
        try:
            upstream = socket.create_connection((LOOPBACK, port), timeout=SERVER_TIMEOUT)
        except OSError as exc:
            self._json(502, {"error": f"the meshcat server on port {port} does not answer: {exc}"})
            return
        with upstream:
            lines = ["GET / HTTP/1.1", f"Host: {LOOPBACK}:{port}"]
            lines += [f"{k}: {v}" for k, v in self.headers.items() if k.lower() != "host"]
            upstream.sendall(("\r\n".join(lines) + "\r\n\r\n").encode("latin-1"))
            upstream.settimeout(None)
            self.connection.settimeout(None)
            if self.server.add_pipe(self.connection, upstream):
                try:
                    _pipe(self.connection, upstream)
                finally:
                    self.server.drop_pipe(self.connection, upstream)

    def do_POST(self) -> None:
        if self._refused(same_origin=True):
            return
        if not secrets.compare_digest(
            self.headers.get(TOKEN_HEADER, "").encode(), self.server.page.token.encode()
        ):
            self._refuse(
                f"a request without the page's token ({TOKEN_HEADER}) refused: "
                "change the pose from the page (reload it if the viewer was restarted)"
            )
            return
        kind = self.headers.get("Content-Type", "").split(";")[0].strip().lower()
        if kind != "application/json":  # a form or text/plain: what another site can send
            self.close_connection = True
            self._json(415, {"error": "a JSON body (Content-Type: application/json) is expected"})
            return
        path = urlsplit(self.path).path
        try:
            length = int(self.headers.get("Content-Length", "0"))
        except ValueError:
            length = -1
        if not 0 <= length <= _MAX_BODY:
            self.close_connection = True
            status = 413 if length > _MAX_BODY else 400
            self._json(status, {"error": f"a request body of 0-{_MAX_BODY} bytes is expected"})
            return
        raw = self.rfile.read(length)
        page = self.server.page
        try:
            try:
                body = json.loads(raw or b"{}")
            except RecursionError as exc:
                raise InputError("the request body is JSON nested too deeply") from exc
            except ValueError as exc:
                raise InputError(f"the request body is not JSON: {exc}") from exc
            if not isinstance(body, dict):
                raise InputError("the request body must be a JSON object")
            if path == "/api/pose":
                page.set_pose(body.get("natural"), pose=body.get("pose"))
                self._json(200, page.panel_dict())
            elif path == "/api/map":
                page.set_map_visible(bool(body.get("visible")))
                self._json(200, {"visible": page.map_visible, "points": page.map_points})
            else:
                self._json(404, {"error": f"no endpoint {path}"})
        except InputError as exc:
            self._json(400, {"error": str(exc)})
        except CdpmError as exc:  # e.g. the meshcat server stopped answering
            self._json(500, {"error": str(exc)})
