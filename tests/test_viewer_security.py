"""What the viewer lets in: meshes only from the model's folders and its
packages; requests only naming a loopback host (no DNS rebinding), from the
page itself (no cross-site POST or websocket), on both the page's server and
meshcat's; malformed or abandoned requests answered or let go without a
traceback; ``cdpm view``'s ports and --seconds; and page and scene on one
origin, so a headless screenshot shows the robot under either loopback name."""

from __future__ import annotations

import http.client
import json
import os
import re
import shutil
import socket
import struct
import subprocess
import tempfile
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.errors import ModelError
from cdpm.viewer import COLORS
from cdpm.viewer.state import meshes_outside
from tests.conftest import MODELS
from tests.processes import alive
from tests.test_viewer import _server_scene, _viewer_servers
from tests.test_viewer_page import _count_near, _listening, _profile_processes

PAPER_SPEC = MODELS / "two_link_planar" / "two_link_planar.yaml"


def _no_server_left() -> None:
    assert _viewer_servers(parent=os.getpid()) == set(), "a meshcat server is still running"


def _closed(ports: list[int], server: int | None, before: set[int]) -> None:
    """Nothing listens on the ports, the meshcat server process is gone, and
    this process runs no other meshcat server than ``before``."""
    for port in ports:
        assert _listening(port) == [], f"port {port} still listens"
    if server is not None and os.path.isdir("/proc"):
        assert not alive(server), "the meshcat server still runs"
    assert _viewer_servers(parent=os.getpid()) == before, "a meshcat server is still running"


# ---------------------------------------------------------------- meshes


def _stl(path: Path) -> bytes:
    """Write a binary STL tetrahedron (0.1 m) at ``path``; returns its bytes."""
    corners = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], dtype="<f4")
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    data = b"cdpm test mesh".ljust(80, b" ") + struct.pack("<I", len(faces))
    for face in faces:
        data += np.zeros(3, "<f4").tobytes() + corners[list(face)].tobytes() + b"\0\0"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return data


def _arm_with_mesh(folder: Path, mesh: str):
    """The paper's arm in ``folder`` (spec and URDF), its links drawn by ``mesh``."""
    folder.mkdir(parents=True, exist_ok=True)
    urdf = (MODELS / "two_link_planar" / "two_link_planar.urdf").read_text()
    cylinder = '<cylinder radius="0.03" length="1.0"/>'
    assert cylinder in urdf
    (folder / "arm.urdf").write_text(urdf.replace(cylinder, f'<mesh filename="{mesh}"/>'))
    spec = PAPER_SPEC.read_text().replace("two_link_planar.urdf", "arm.urdf")
    (folder / "arm.yaml").write_text(spec)
    return cdpm.load_robot(folder / "arm.yaml")


@pytest.fixture
def meshes(tmp_path):
    """A model folder with a mesh inside, a package folder holding the model,
    and a mesh outside both: ``(model folder, outside mesh, its bytes)``."""
    model = tmp_path / "robot_pkg" / "model"
    _stl(model / "meshes" / "link.stl")
    outside = tmp_path / "elsewhere" / "secret.stl"
    return model, outside, _stl(outside)


def _refused(model: Path, mesh: str) -> list[str]:
    robot = _arm_with_mesh(model, mesh)
    return meshes_outside(robot.spec.urdf_path, [model])


def test_meshes_inside_the_model_or_its_package_are_allowed(meshes):
    model, _, _ = meshes
    assert _refused(model, "meshes/link.stl") == []
    assert _refused(model, str(model / "meshes" / "link.stl")) == []  # absolute, inside
    assert _refused(model, f"file://{model}/meshes/link.stl") == []
    # the URDF lies inside a folder named after the package (mesh_package_dirs)
    assert _refused(model, "package://robot_pkg/model/meshes/link.stl") == []
    assert _refused(model, "meshes/none.stl") == []  # not found: loading says so


def test_meshes_leading_outside_the_model_are_refused(meshes):
    model, outside, _ = meshes
    (model / "meshes" / "link_to_secret.stl").symlink_to(outside)
    for mesh in [
        str(outside),  # absolute
        f"file://{outside}",
        "../../elsewhere/secret.stl",  # up and out of the model's folder
        "meshes/link_to_secret.stl",  # a link inside, pointing out
        "package://robot_pkg/../elsewhere/secret.stl",  # out of its package
    ]:
        (problem,) = _refused(model, mesh)
        assert repr(mesh) in problem and str(outside) in problem, problem
    (problem,) = _refused(model, "http://example.com/link.stl")
    assert "is not a file" in problem


@pytest.mark.slow
def test_viewer_does_not_load_a_mesh_outside_the_model(meshes):
    pytest.importorskip("meshcat")
    from cdpm.viewer import Viewer

    model, outside, secret = meshes
    robot = _arm_with_mesh(model, str(outside))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with Viewer(robot, "nominal") as viewer:
            assert viewer.geometry == "generated"
            scene = _server_scene(viewer)
    _no_server_left()
    (message,) = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert f"mesh {str(outside)!r} lies outside the model's folder ({model})" in message
    assert message.endswith("drawing generated links")
    # nothing of the file reached the scene the browser gets
    meshes_sent = [
        geometry.get("data")
        for node in scene.values()
        for geometry in node.get("object", {}).get("geometries", [])
    ]
    assert not any(getattr(data, "data", data) == secret for data in meshes_sent)
    assert any(path.startswith("cdpm/model/robot/joint2/link") for path in scene)
    with pytest.raises(ModelError, match=f"mesh {str(outside)!r} lies outside the model's"):
        Viewer(robot, "nominal", geometry="urdf")
    _no_server_left()
    # the same mesh inside the model's folder is drawn
    inside = _arm_with_mesh(model, "meshes/link.stl")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with Viewer(inside, "nominal") as viewer:
            assert viewer.geometry == "urdf"
    assert not [w for w in caught if issubclass(w.category, UserWarning)]
    _no_server_left()


# ---------------------------------------------------------------- requests


@pytest.fixture(scope="module")
def page():
    """One inspection page of the paper's arm; closed, with nothing left, at the end."""
    pytest.importorskip("meshcat")
    from cdpm.viewer import InspectionPage

    robot = cdpm.load_robot(PAPER_SPEC)
    before = _viewer_servers(parent=os.getpid())
    with InspectionPage(robot, "nominal", port=0, scene_port=0) as shown:
        ports, server = [shown.port, shown.scene_port], shown.viewer.server_pid
        yield shown
        log = Path(shown.viewer._server.log.name).read_text()
        assert "Traceback" not in log and "Error" not in log, log
    _closed(ports, server, before)


def _ask(port: int, method: str, path: str, headers=None, body: bytes | None = None):
    """(status, body text) of one request to 127.0.0.1:port, with exactly
    these headers (a Host header among them replaces the usual one)."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        connection.request(method, path, body=body, headers=headers or {})
        response = connection.getresponse()
        return response.status, response.read().decode(errors="replace")
    finally:
        connection.close()


def _handshake(port: int, path: str, headers: dict[str, str]) -> bytes:
    """Send a websocket handshake; returns the answer: a refusal with its
    body, or the switch with the scene the meshcat server sends first."""
    lines = [f"GET {path} HTTP/1.1"] + [f"{k}: {v}" for k, v in headers.items()]
    lines += [
        "Connection: Upgrade",
        "Upgrade: websocket",
        "Sec-WebSocket-Version: 13",
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
    ]

    def complete(received: bytes) -> bool:
        head, sep, body = received.partition(b"\r\n\r\n")
        if not sep:
            return False
        if head.startswith(b"HTTP/1.1 101"):
            return b"meshcat/cdpm" in body
        length = re.search(rb"(?i)content-length: *(\d+)", head)
        return length is not None and len(body) >= int(length.group(1))

    with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
        sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        received = b""
        while not complete(received):
            chunk = sock.recv(1 << 16)
            if not chunk:
                break
            received += chunk
    return received


@pytest.mark.parametrize(
    "host",
    ["evil.example:{port}", "127.0.0.1.evil.example:{port}", "localhost.evil:{port}", ""],
)
def test_page_refuses_a_host_that_is_not_loopback(page, host):
    status, body = _ask(page.port, "GET", "/", {"Host": host.format(port=page.port)})
    assert status == 403 and "refused: the viewer answers only 127.0.0.1, localhost" in body
    status, body = _ask(page.port, "GET", "/scene/main.min.js", {"Host": "evil.example"})
    assert status == 403


@pytest.mark.parametrize("host", ["127.0.0.1:{port}", "localhost:{port}", "[::1]:{port}"])
def test_page_answers_every_loopback_name_and_a_forwarded_port(page, host):
    for named in (host.format(port=page.port), host.format(port=8123)):  # ssh -L 8123:...
        status, body = _ask(page.port, "GET", "/", {"Host": named})
        assert status == 200 and '<aside id="panel"' in body


@pytest.mark.parametrize("origin", ["http://evil.example", "null", "http://localhost.evil"])
def test_page_refuses_another_sites_page(page, origin):
    host = {"Host": f"127.0.0.1:{page.port}"}
    status, body = _ask(page.port, "GET", "/api/model", {**host, "Origin": origin})
    assert status == 403 and f"a request from the page {origin!r} refused" in body
    assert _ask(page.port, "GET", "/api/model", host)[0] == 200  # no page: a tool
    same = {**host, "Origin": f"http://127.0.0.1:{page.port}"}
    assert _ask(page.port, "GET", "/api/model", same)[0] == 200


def test_scene_server_refuses_other_hosts_and_origins(page):
    port = page.scene_port
    assert _ask(port, "GET", "/static/", {"Host": f"127.0.0.1:{port}"})[0] == 200
    assert _ask(port, "GET", "/static/", {"Host": f"localhost:{port}"})[0] == 200
    for headers, problem in [
        ({"Host": f"evil.example:{port}"}, "refused: the viewer answers only 127.0.0.1"),
        ({"Host": "localhost:1"}, f"refused: this server listens on port {port}"),
        (
            {"Host": f"127.0.0.1:{port}", "Origin": "http://evil.example"},
            "a request from the page 'http://evil.example' refused",
        ),
    ]:
        status, body = _ask(port, "GET", "/static/", headers)
        assert (status, body.strip()) == (403, body.strip()) and problem in body, body
        answer = _handshake(port, "/", headers)
        assert answer.startswith(b"HTTP/1.1 403") and problem.encode() in answer, answer[:300]
    answer = _handshake(port, "/", {"Host": f"127.0.0.1:{port}", "Origin": "http://localhost:7"})
    assert answer.startswith(b"HTTP/1.1 101") and b"meshcat/cdpm" in answer
    log = Path(page.viewer._server.log.name).read_text()
    assert "Traceback" not in log and "403" not in log  # refused quietly


def test_cross_site_posts_change_nothing(page):
    before = page.panel
    body = json.dumps({"natural": [0.0, 0.0]}).encode()
    host = {"Host": f"127.0.0.1:{page.port}"}
    simple = {**host, "Content-Type": "text/plain"}  # what a form or no-cors fetch sends
    for headers, problem in [
        ({**simple, "Origin": "http://evil.example"}, "'http://evil.example' refused"),
        (
            {**simple, "Origin": f"http://localhost:{page.port}"},  # another origin
            f"only the page on 127.0.0.1:{page.port} may ask",
        ),
        ({**simple, "Origin": f"http://127.0.0.1:{page.port}"}, "without the page's token"),
        ({**simple, "X-Cdpm-Token": "guess"}, "without the page's token"),
    ]:
        status, answer = _ask(page.port, "POST", "/api/pose", headers, body)
        assert status == 403 and problem in json.loads(answer)["error"], answer
        status, answer = _ask(page.port, "POST", "/api/map", headers, b'{"visible": true}')
        assert status == 403
    # the page's own origin and token, but a body another site's form could send
    own = {**host, "Origin": f"http://127.0.0.1:{page.port}", "X-Cdpm-Token": page.token}
    status, answer = _ask(page.port, "POST", "/api/pose", {**own, **simple}, body)
    assert (status, json.loads(answer)) == (
        415,
        {"error": "a JSON body (Content-Type: application/json) is expected"},
    )
    assert page.panel is before  # the pose did not change
    # the page's own request: its origin, its token, JSON
    own["Content-Type"] = "application/json"
    status, answer = _ask(page.port, "POST", "/api/pose", own, body)
    assert status == 200 and json.loads(answer)["natural"] == [0.0, 0.0]
    status, html = _ask(page.port, "GET", "/", host)
    assert f'<meta name="cdpm-token" content="{page.token}">' in html


def test_the_scenes_websocket_goes_through_the_page(page):
    own = {"Host": f"localhost:{page.port}", "Origin": f"http://localhost:{page.port}"}
    answer = _handshake(page.port, "/scene/ws", own)
    assert answer.startswith(b"HTTP/1.1 101 Switching Protocols") and b"meshcat/cdpm" in answer
    other = {"Host": f"localhost:{page.port}", "Origin": "http://localhost:9"}
    answer = _handshake(page.port, "/scene/ws", other)
    assert answer.startswith(b"HTTP/1.1 403") and b"only the page on localhost" in answer
    status, html = _ask(page.port, "GET", "/scene/", own)
    assert status == 200 and '<script src="main.min.js">' in html
    status, script = _ask(page.port, "GET", "/scene/main.min.js", own)
    assert status == 200 and "MeshCat" in script


def test_a_scene_closed_mid_update_does_not_hang_the_viewer(page):
    """meshcat's server wrote to a websocket closed but not yet out of its
    pool, raised, and left the viewer's request unanswered (a 20 s hang, then
    an error): a tab closed or reloaded while the pose changes."""
    own = {
        "Host": f"127.0.0.1:{page.port}",
        "X-Cdpm-Token": page.token,
        "Content-Type": "application/json",
    }
    for k in range(10):
        # a scene's websocket (meshcat's own, as the page's pipes it), opened and dropped
        answer = _handshake(page.scene_port, "/", {"Host": f"127.0.0.1:{page.scene_port}"})
        assert answer.startswith(b"HTTP/1.1 101")
        body = json.dumps({"natural": [0.1, k / 10]}).encode()
        status, answer = _ask(page.port, "POST", "/api/pose", own, body)
        assert status == 200, answer


def _handler_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if "process_request_thread" in t.name]


def test_malformed_and_abandoned_requests_print_no_traceback(page, capfd):
    own = {
        "Host": f"127.0.0.1:{page.port}",
        "X-Cdpm-Token": page.token,
        "Content-Type": "application/json",
    }
    deep = b"[" * 100_000 + b"]" * 100_000
    status, answer = _ask(page.port, "POST", "/api/pose", own, deep)
    assert (status, json.loads(answer)) == (
        400,
        {"error": "the request body is JSON nested too deeply"},
    )
    status, answer = _ask(page.port, "POST", "/api/pose", {**own, "Content-Length": "2000000"})
    assert status == 413 and "a request body of 0-1048576 bytes" in answer
    status, answer = _ask(page.port, "POST", "/api/pose", {**own, "Content-Length": "x"})
    assert status == 400
    # clients that go away while the answer (the page's script) is sent
    for _ in range(5):
        sock = socket.create_connection(("127.0.0.1", page.port))
        sock.sendall(
            f"GET /scene/main.min.js HTTP/1.1\r\nHost: 127.0.0.1:{page.port}\r\n\r\n".encode()
        )
        sock.recv(100)  # the answer has begun
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        sock.close()  # a reset, mid-answer
    deadline = time.monotonic() + 30
    while _handler_threads() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _handler_threads(), "a request is still being answered"
    assert _ask(page.port, "GET", "/api/model", own)[0] == 200  # the server still serves
    err = capfd.readouterr().err
    assert "Traceback" not in err and "Exception" not in err, err


# ---------------------------------------------------------------- cdpm view


def test_view_seconds_beyond_what_the_clock_can_wait_is_an_error(capsys):
    from cdpm.cli import main

    with pytest.raises(SystemExit) as info:
        main(["view", str(PAPER_SPEC), "--seconds", "1e300"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "argument --seconds: --seconds 1e300 is longer than this system can wait" in err
    assert "omit it to serve until Ctrl-C" in err and "Traceback" not in err


def test_view_help_names_the_scene_port(capsys):
    from cdpm.cli import main

    with pytest.raises(SystemExit):
        main(["view", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--scene-port SCENE_PORT port of the 3-D scene's own server, 1-65535, or 0" in out
    assert "--port PORT port of the page, 1-65535, or 0 for any free port" in out


@pytest.mark.parametrize("scene_port", ["0", "free"])
def test_view_serves_for_seconds_on_the_ports_asked(scene_port, capsys):
    pytest.importorskip("meshcat")
    from cdpm.cli import main
    from tests.test_viewer import _free_port

    asked = str(_free_port()) if scene_port == "free" else "0"
    before = _viewer_servers(parent=os.getpid())
    args = ["view", str(PAPER_SPEC), "--port", "0", "--scene-port", asked, "--seconds", "0"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "Ctrl-C" not in out and "  (for 0 s)" in out
    (scene,) = [line.split()[2] for line in out.splitlines() if line.startswith("scene alone:")]
    (url,) = [line.split()[1] for line in out.splitlines() if line.startswith("viewer:")]
    ports = [int(u.split(":")[2].split("/")[0]) for u in (url, scene)]
    assert 0 not in ports and ports[0] != ports[1]
    if scene_port == "free":
        assert ports[1] == int(asked)
    _closed(ports, None, before)


# ---------------------------------------------------------------- one origin, headless

CHROMIUM = shutil.which("chromium")


def _headless_screenshot(url: str, folder: Path) -> np.ndarray:
    """``chromium --headless --screenshot`` of a URL (1280 x 900), as (h, w, 3)
    RGB; checks that no Chromium process of its profile is left."""
    from PIL import Image

    profile = tempfile.mkdtemp(prefix="cdpm-shot-chromium-", dir=folder)
    shot = Path(profile) / "shot.png"
    subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-gl=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--no-first-run",
            "--hide-scrollbars",
            "--window-size=1280,900",
            f"--user-data-dir={profile}",
            "--virtual-time-budget=10000",
            f"--screenshot={shot}",
            url,
        ],
        capture_output=True,
        timeout=120,
        check=False,
    )
    deadline = time.monotonic() + 10
    while _profile_processes(profile) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _profile_processes(profile), "Chromium processes left"
    assert shot.exists(), "chromium wrote no screenshot"
    pixels = np.asarray(Image.open(shot).convert("RGB"))
    shutil.copy(shot, folder / f"{url.split('/')[2].replace(':', '_')}.png")
    return pixels


@pytest.mark.slow
@pytest.mark.skipif(
    CHROMIUM is None and os.environ.get("CI") != "true",
    reason="needs Debian's chromium (apt-get install chromium); CI installs it",
)
def test_headless_screenshot_of_the_page_shows_the_robot(tmp_path):
    pytest.importorskip("meshcat")
    from cdpm.viewer import InspectionPage

    robot = cdpm.load_robot(PAPER_SPEC)
    before = _viewer_servers(parent=os.getpid())
    with InspectionPage(robot, "nominal", port=0) as page:
        for name in ("localhost", "127.0.0.1"):
            for _attempt in range(3):  # a loaded machine may need a longer budget
                pixels = _headless_screenshot(f"http://{name}:{page.port}/", tmp_path)
                scene = pixels[:, :800]  # the panel is the right 460 px of 1280
                if _count_near(scene, COLORS["slack"]) > 300:
                    break
            assert pixels.shape[:2] == (900, 1280)
            # the paper's pose: four slack (pink) cables, a YES (green) marker
            assert _count_near(scene, COLORS["slack"]) > 300, f"{name}: a blank scene"
            assert _count_near(scene, COLORS["yes"], tol=40) > 50, f"{name}: no marker"
            assert len(np.unique(scene.reshape(-1, 3), axis=0)) > 200
        ports, server = [page.port, page.scene_port], page.viewer.server_pid
    _closed(ports, server, before)


def test_one_port_for_page_and_scene_is_a_clear_error(capsys):
    from cdpm.cli import main
    from tests.conftest import PAPER_SPEC

    ports = ["--port", "7345", "--scene-port", "7345"]
    code = main(["view", str(PAPER_SPEC), *ports, "--seconds", "1"])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err
    assert "--port and --scene-port are both 7345" in err
