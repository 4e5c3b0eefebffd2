"""Viewer: pose state, colours, slider ranges, map points, the meshcat server
(loopback only), the view command, and a real browser rendering the scene."""

from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.errors import InputError, MissingExtraError
from cdpm.verdicts import (
    NO,
    NOT_ANALYSED,
    VERDICT_CODES,
    VERDICT_ORDER,
    VERDICT_RGB,
    YES,
    verdict_key,
)
from cdpm.viewer import (
    COLORS,
    CableState,
    PoseInspector,
    cable_colors,
    coordinate_ranges,
    map_points,
    pose_state,
)
from tests.conftest import PAPER_SPEC, ROOT

NOMINAL = np.array([math.pi / 6, math.pi / 3])


def _tip(q):
    q1, q2 = q
    return np.array([math.cos(q1) + math.cos(q1 + q2), math.sin(q1) + math.sin(q1 + q2), 0.0])


# ---------------------------------------------------------------- pose state


def test_pose_state_paper_nominal(paper_robot):
    state = pose_state(paper_robot, "nominal")
    assert str(state.verdict) == "YES"
    assert state.margin is not None and state.margin > 0
    assert state.cable_states == (CableState.SLACK,) * 4
    np.testing.assert_allclose(state.tension, 0.0)
    assert state.output_frames == ("tip",)
    np.testing.assert_allclose(state.output_frame_positions[0], _tip(NOMINAL), atol=1e-12)
    np.testing.assert_allclose(state.output, [_tip(NOMINAL)[0]], atol=1e-12)
    # route points agree with the robot's own kinematics
    for mine, theirs in zip(
        state.cable_points, paper_robot.attachment_points(NOMINAL), strict=True
    ):
        np.testing.assert_allclose(mine, theirs, atol=1e-12)
    # c1 anchor (0, 0.5) and its attachment 0.3, 0.1 from link1's COM (Table I)
    c, s = math.cos(NOMINAL[0]), math.sin(NOMINAL[0])
    np.testing.assert_allclose(state.cable_points[0][0], [0, 0.5, 0])
    np.testing.assert_allclose(state.cable_points[0][1], [0.8 * c - 0.1 * s, 0.8 * s + 0.1 * c, 0])


def test_pose_state_text_names_verdict_tensions_and_slack_cables(paper_robot):
    text = str(pose_state(paper_robot, NOMINAL))
    assert text.startswith("POC: YES (reach margin 0.1501 m)")
    assert "q1 = 0.5236, q2 = 1.0472" in text
    assert "slack cables: c1, c2, c3, c4" in text
    html = pose_state(paper_robot, NOMINAL)._repr_html_()
    assert "POC: YES" in html and "rgb(46,158,68)" in html  # #2e9e44, the verdicts' green


def test_arm_stretched_along_x_is_not_poc(paper_robot):
    # at q = (0, 0) d(tip_x)/dq = 0: no cable can move the output
    state = pose_state(paper_robot, [0.0, 0.0])
    assert str(state.verdict) == "NO"
    assert state.verdict_key == "no"
    assert state.as_dict()["verdict"] == "no"


def test_zero_length_cable_is_unavailable_not_an_error(write_spec):
    spec = write_spec(
        """
        urdf: arm.urdf
        gravity: [0, 0, 0]
        cables:
          - name: short
            route:
              - {frame: base, point: [0, 0, 0]}
              - {frame: link1, point: [0, 0, 0]}
          - name: c2
            route:
              - {frame: base, point: [0, 1.5, 0]}
              - {frame: link2, point: [0.8, 0.1, 0]}
        outputs:
          - {name: tip_x, frame: tip, component: x}
        poses:
          p: [0.3, 0.4]
        """
    )
    robot = cdpm.load_robot(spec)
    state = pose_state(robot, "p")
    assert state.verdict is None and state.verdict_key == "unavailable"
    assert state.cable_states == (CableState.UNAVAILABLE,) * 2
    assert state.tension is None
    assert "zero length" in state.reason
    assert str(state).startswith("POC: unavailable (")
    assert cable_colors(state, 1.0) == [COLORS["unavailable"]] * 2


def test_cable_colours_scale_with_tension(paper_robot):
    base = pose_state(paper_robot, NOMINAL)
    taut = (CableState.TAUT,) * 3 + (CableState.SLACK,)
    tension = np.array([0.0, 5.0, 10.0, 0.0])
    from dataclasses import replace

    state = replace(base, cable_states=taut, tension=tension)
    colors = cable_colors(state, scale=10.0)
    np.testing.assert_allclose(colors[0], COLORS["taut_low"])
    np.testing.assert_allclose(colors[2], COLORS["taut_high"])
    mid = 0.5 * (np.array(COLORS["taut_low"]) + np.array(COLORS["taut_high"]))
    np.testing.assert_allclose(colors[1], mid, atol=0.02)  # 32 quantisation levels
    assert colors[3] == COLORS["slack"]
    # above the scale saturates
    assert cable_colors(state, scale=1.0)[1] == pytest.approx(COLORS["taut_high"])


# ---------------------------------------------------------------- slider ranges


def test_ranges_from_urdf_limits(paper_robot):
    ranges = coordinate_ranges(paper_robot, NOMINAL)
    assert list(ranges) == ["q1", "q2"]
    for lo, hi in ranges.values():
        assert lo == pytest.approx(-math.pi) and hi == pytest.approx(math.pi)


def test_ranges_without_limits(tmp_path):
    (tmp_path / "r.urdf").write_text(
        textwrap.dedent(
            """\
            <robot name="r">
              <link name="base"/>
              <link name="a"><inertial><mass value="1"/>
                <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
              <link name="b"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
                <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
              <link name="c"><inertial><mass value="1"/>
                <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
              <joint name="slide" type="prismatic"><parent link="base"/><child link="a"/>
                <axis xyz="1 0 0"/><limit lower="0" upper="0" effort="1" velocity="1"/></joint>
              <joint name="spin" type="continuous"><parent link="a"/><child link="b"/>
                <axis xyz="0 0 1"/></joint>
              <joint name="hinge" type="revolute"><parent link="b"/><child link="c"/>
                <origin xyz="1 0 0"/><axis xyz="0 0 1"/>
                <limit lower="-0.5" upper="1.5" effort="1" velocity="1"/></joint>
            </robot>
            """
        )
    )
    (tmp_path / "r.yaml").write_text(
        textwrap.dedent(
            """\
            urdf: r.urdf
            cables:
              - name: k
                route: [{frame: base, point: [0, 1, 0]}, {frame: c, point: [0.2, 0, 0]}]
            outputs: [{name: x, frame: c, component: x}]
            """
        )
    )
    robot = cdpm.load_robot(tmp_path / "r.yaml")
    ranges = coordinate_ranges(robot, [0.25, 2.0, 0.1])
    assert ranges["slide"] == pytest.approx((-0.75, 1.25))  # no usable limits: value +- 1 m
    assert ranges["spin"] == pytest.approx((-math.pi, math.pi))  # continuous: one turn
    assert ranges["hinge"] == pytest.approx((-0.5, 1.5))  # from the URDF
    # the current value is always inside
    assert coordinate_ranges(robot, [0.0, 0.0, 1.6])["hinge"] == pytest.approx((-0.5, 1.6))


# ---------------------------------------------------------------- inspector


def test_inspector_updates_state_and_text(paper_robot):
    inspector = PoseInspector(paper_robot, q=[0.0, math.pi / 3])
    assert inspector.text.startswith("POC: YES")
    state = inspector.set_coordinate("q2", 0.0)
    assert str(state.verdict) == "NO" and inspector.text.startswith("POC: NO")
    np.testing.assert_allclose(inspector.natural, [0.0, 0.0])
    assert len(inspector.update_seconds) == 2
    with pytest.raises(InputError, match="no coordinate 'q3'; coordinates: q1, q2"):
        inspector.set_coordinate("q3", 0.0)
    with pytest.raises(InputError, match="not a finite number"):
        inspector.set_coordinate("q1", float("nan"))


def test_inspector_widget_slider_change_updates_panel(paper_robot):
    pytest.importorskip("ipywidgets")
    inspector = PoseInspector(paper_robot, q=[0.0, math.pi / 3])
    box = inspector.widget()
    assert len(box.children) == 3
    slider = inspector.sliders["q2"]
    assert (slider.min, slider.max) == pytest.approx((-math.pi, math.pi))
    assert "POC: YES" in inspector.panel.value
    slider.value = 0.0
    assert "POC: NO" in inspector.panel.value
    inspector.set_natural(NOMINAL)
    assert inspector.sliders["q1"].value == pytest.approx(NOMINAL[0])
    assert "POC: YES" in inspector.panel.value


# ---------------------------------------------------------------- map points


def _synthetic_map(xr, sample: bool = False):
    q1 = np.linspace(-1.0, 1.0, 3)
    q2 = np.linspace(0.5, 1.5, 2)
    Q1, Q2 = np.meshgrid(q1, q2, indexing="ij")
    pos = np.stack([np.cos(Q1) + np.cos(Q1 + Q2), np.sin(Q1) + np.sin(Q1 + Q2), 0 * Q1], -1)
    pos[0, 0] = np.nan  # a pose without a position (e.g. failed)
    poc = np.array([[1, 0], [2, -1], [1, 1]], dtype=np.int8)
    margin = np.array([[0.5, 0.2], [0.0, np.nan], [1.0, 0.25]])
    ds = xr.Dataset(
        {
            "poc": (
                ("q1", "q2"),
                poc,
                {"flag_values": [1, 0, 2, -1], "flag_meanings": "yes no marginal not_analysed"},
            ),
            "reach_margin": (("q1", "q2"), margin),
            "output_frame_position": (("q1", "q2", "xyz"), pos),
            "y": (("q1", "q2", "output"), pos[..., :1]),
        },
        coords={"q1": q1, "q2": q2, "xyz": ["x", "y", "z"], "output": ["tip_x"]},
    )
    if sample:
        ds = ds.stack(sample=("q1", "q2")).reset_index("sample")
    return ds, pos


@pytest.mark.parametrize("sample", [False, True])
def test_map_points_by_verdict(sample):
    xr = pytest.importorskip("xarray")
    ds, pos = _synthetic_map(xr, sample)
    positions, colors = map_points(ds)
    assert positions.shape == (5, 3)  # the NaN position is left out
    np.testing.assert_allclose(positions, pos.reshape(-1, 3)[1:])
    expected = ["no", "marginal", "not_analysed", "yes", "yes"]
    np.testing.assert_allclose(colors, [COLORS[k] for k in expected])


def test_map_points_by_margin():
    xr = pytest.importorskip("xarray")
    ds, _ = _synthetic_map(xr)
    _, colors = map_points(ds, color_by="margin")
    # margins after dropping the NaN position: 0.2, 0.0, nan, 1.0, 0.25, on a
    # log scale between the 1st and 99th percentile of the positive ones
    np.testing.assert_allclose(colors[1], COLORS["no"])  # zero margin: red, as a NO
    np.testing.assert_allclose(colors[2], COLORS["not_analysed"])  # NaN margin: grey
    logs = np.log10([0.2, 0.5, 1.0, 0.25])
    lo, hi = np.percentile(logs, [1, 99])
    light, dark = np.array(COLORS["taut_low"]), np.array(COLORS["taut_high"])
    for i, m in ((0, 0.2), (3, 1.0), (4, 0.25)):
        t = np.clip((np.log10(m) - lo) / (hi - lo), 0, 1)
        np.testing.assert_allclose(colors[i], light + t * (dark - light))


def test_map_points_errors():
    xr = pytest.importorskip("xarray")
    ds, _ = _synthetic_map(xr)
    with pytest.raises(InputError, match="no variable 'reach_margin'"):
        map_points(ds.drop_vars("reach_margin"), color_by="margin")
    with pytest.raises(InputError, match="color_by='tension'"):
        map_points(ds, color_by="tension")
    bad = ds.rename({"xyz": "component"})
    with pytest.raises(InputError, match="dimension 'xyz'"):
        map_points(bad)


# ---------------------------------------------------------------- one verdict palette


def _verdict(code: int):
    """The analysis verdict of a code (None: not analysed)."""
    from cdpm.analysis import Verdict

    return None if code == NOT_ANALYSED else Verdict(verdict_key(code))


@pytest.mark.slow
def test_verdict_colours_agree_in_marker_overlay_plot_and_picture(paper_robot):
    pytest.importorskip("matplotlib")
    xr = pytest.importorskip("xarray")
    from dataclasses import replace

    from matplotlib.collections import QuadMesh
    from matplotlib.colors import to_rgb

    from cdpm.plotting import VERDICT_COLORS, plot_map
    from cdpm.plotting.picture import render_pose

    ds, _ = _synthetic_map(xr)  # every verdict code occurs in it
    codes = ds["poc"].values.reshape(-1)
    assert set(codes.tolist()) == set(VERDICT_ORDER)
    # map overlay: one colour per pose (all positions finite here)
    ds["output_frame_position"] = ds["output_frame_position"].fillna(0.0)
    _, overlay = map_points(ds)
    # plot: the verdict panel's cells (rows q1, columns q2, as in the map)
    fig = plot_map(ds, margin=False, output_view=False)
    (mesh,) = [c for c in fig.axes[0].collections if isinstance(c, QuadMesh)]
    cells = mesh.to_rgba(np.asarray(mesh.get_array()).reshape(-1))[:, :3]
    base = pose_state(paper_robot, NOMINAL)
    for code in VERDICT_ORDER:
        expected = VERDICT_RGB[code]
        np.testing.assert_allclose(to_rgb(VERDICT_COLORS[code]), expected, atol=1e-12)
        for drawn in (cells, overlay):
            expected_all = [expected] * int(np.sum(codes == code))
            np.testing.assert_allclose(drawn[codes == code], expected_all, atol=1e-6)
        state = replace(base, verdict=_verdict(code))
        assert state.verdict_code == code
        assert state.verdict_rgb == expected  # the 3-D view's output marker
        # the picture's output star (the only scatter of size 260)
        ax = render_pose(paper_robot, state=state).axes[0]
        (star,) = [c for c in ax.collections if c.get_sizes().tolist() == [260]]
        np.testing.assert_allclose(star.get_facecolor()[0][:3], expected, atol=1e-6)
    # the drawing's named verdict colours are the same ones
    for name in ("yes", "no", "marginal", "not_analysed"):
        assert COLORS[name] == VERDICT_RGB[VERDICT_CODES[name]]


# ---------------------------------------------------------------- server


def _listening(port: int) -> list[str]:
    """Local addresses (hex, as in /proc/net/tcp*) listening on a TCP port."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not os.path.exists(table):
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            address, hexport = fields[1].rsplit(":", 1)
            if fields[3] == "0A" and int(hexport, 16) == port:  # 0A: LISTEN
                found.append(address)
    return found


LOOPBACK_HEX = "0100007F"  # 127.0.0.1 in /proc/net/tcp byte order


@pytest.fixture(scope="module")
def viewer(paper_robot):
    pytest.importorskip("meshcat")
    v = cdpm.viewer.Viewer(paper_robot, "nominal")
    yield v
    v.close()


def test_servers_listen_on_loopback_only(viewer):
    if not os.path.exists("/proc/net/tcp"):
        pytest.skip("needs Linux /proc/net/tcp to list listening sockets")
    web_port = int(viewer.url().split(":")[2].split("/")[0])
    zmq_port = int(viewer.zmq_url.rsplit(":", 1)[1])
    assert viewer.url().startswith("http://127.0.0.1:")
    assert viewer.zmq_url.startswith("tcp://127.0.0.1:")
    for port in (web_port, zmq_port):
        assert _listening(port) == [LOOPBACK_HEX], f"port {port}: {_listening(port)}"


def test_viewer_display_and_map(viewer, paper_robot):
    state = viewer.display([0.0, 0.0])
    assert state.verdict_key == "no" and viewer.state is state
    assert viewer.marker_color == COLORS["no"] == VERDICT_RGB[NO]
    assert set(viewer.last_display_seconds) == {"analysis", "draw", "total"}
    state = viewer.display("nominal")
    assert viewer.marker_color == COLORS["yes"] == VERDICT_RGB[YES]
    assert viewer._cable_colors == [COLORS["slack"]] * 4
    assert viewer.geometry == "urdf"  # the paper's URDF has visual cylinders
    xr = pytest.importorskip("xarray")
    ds, _ = _synthetic_map(xr)
    assert viewer.show_map(ds) == 5
    viewer.hide_map()
    page = viewer._root.static_html()  # the server's scene, as a browser gets it
    assert "MeshCat" in page and len(page) > 10_000


@pytest.mark.parametrize("code", VERDICT_ORDER)
def test_viewer_marker_has_the_verdict_colour(viewer, paper_robot, monkeypatch, code):
    import cdpm.viewer.scene

    def with_verdict(robot, q, geometry=None, **analysis):
        from dataclasses import replace

        return replace(pose_state(robot, q, geometry, **analysis), verdict=_verdict(code))

    monkeypatch.setattr(cdpm.viewer.scene, "pose_state", with_verdict)
    viewer.display("nominal")
    assert viewer.marker_color == VERDICT_RGB[code]
    _, overlay = map_points(_one_pose_map(code))
    assert tuple(overlay[0]) == viewer.marker_color


def _one_pose_map(code: int):
    xr = pytest.importorskip("xarray")
    return xr.Dataset(
        {
            "poc": (("sample",), np.array([code], dtype=np.int8)),
            "output_frame_position": (("sample", "xyz"), np.zeros((1, 3))),
        }
    )


# ---------------------------------------------------------------- playback


def _server_scene(viewer) -> dict[str, dict]:
    """What the meshcat server holds, as a browser opening the page gets it:
    for each path (under /meshcat/), its last transform (4, 4) and object."""
    import base64
    import re

    import umsgpack  # meshcat's own message format

    scene: dict[str, dict] = {}
    for blob in re.findall(r'base64,([A-Za-z0-9+/=]*)"\)', viewer._root.static_html()):
        command = umsgpack.unpackb(base64.b64decode(blob))
        node = scene.setdefault(command["path"].removeprefix("/meshcat/"), {})
        if command["type"] == "set_transform":
            node["transform"] = np.array(command["matrix"]).reshape(4, 4).T
        elif command["type"] == "set_object":
            node["object"] = command["object"]
    return scene


def _material_color(scene: dict, path: str) -> int:
    return scene[path]["object"]["materials"][0]["color"]


def _rgb(color: int) -> np.ndarray:
    return np.array([(color >> shift) & 255 for shift in (16, 8, 0)]) / 255


def _ports(viewer) -> list[int]:
    web = int(viewer.url().split(":")[2].split("/")[0])
    return [web, int(viewer.zmq_url.rsplit(":", 1)[1])]


def _start_command(*args: str) -> subprocess.Popen:
    """``cdpm ARGS`` in a subprocess, its output piped as text."""
    return subprocess.Popen(
        [sys.executable, "-m", "cdpm.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )


def _viewer_url(proc: subprocess.Popen, timeout: float = 60, seen: list | None = None) -> str:
    """The URL a viewer command prints on its ``viewer: URL`` line ("" if none);
    the lines before it are appended to ``seen``."""
    url = ""
    deadline = time.monotonic() + timeout
    while not url and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.startswith("viewer: "):
            url = line.split()[1]
        elif seen is not None:
            seen.append(line)
        if not line and proc.poll() is not None:
            break
    return url


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _viewer_servers(parent: int | None = None, port: int | None = None) -> set[int]:
    """Processes running a meshcat server of cdpm (python -m cdpm.viewer),
    children of ``parent`` (any when None) or serving ``port``, zombies included."""
    if not os.path.isdir("/proc"):
        pytest.skip("needs Linux /proc to list processes")
    found = set()
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            stat = (proc / "stat").read_text()
            argv = (proc / "cmdline").read_bytes().decode(errors="replace").split("\0")
        except OSError:  # gone meanwhile
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if "cdpm.viewer" not in argv:
            continue
        if parent is not None and ppid != parent:
            continue
        if port is not None and str(port) not in argv:
            continue
        found.add(int(proc.name))
    return found


def _steer_target(robot, dy: float = 0.005) -> np.ndarray:
    return robot.output("nominal") + dy


@pytest.mark.slow
def test_play_ends_on_the_last_pose_with_cables_coloured_by_tension(paper_robot):
    pytest.importorskip("meshcat")
    import pinocchio as pin

    from cdpm.viewer.scene import _rgb_int

    # c1 pulls for 0.1 s, then lets go while c3 pulls twice as hard as c2; c4 stays slack
    profile = ([0.0, 0.1, 0.2], [[4.0, 0.0, 0.0, 0.0], [0.0, 2.0, 4.0, 0.0]])
    traj = cdpm.simulate(paper_robot, "nominal", tension=profile)
    before = _viewer_servers(parent=os.getpid())
    v = cdpm.viewer.Viewer(paper_robot, "nominal", geometry="generated")
    try:
        ports = _ports(v)
        assert _viewer_servers(parent=os.getpid()) == before | {v.server_pid}
        start = _server_scene(v)
        shown = v.play(traj)
        scene = _server_scene(v)
        # 0.2 s at 30 frames per second: frames at 0, 1/30, ..., 0.2 s
        wall, qs, _ = v._frames(traj, 1.0, 30)
    finally:
        v.close()
    # the server is gone: no process, nothing listening on its ports
    assert _viewer_servers(parent=os.getpid()) == before
    for port in ports:
        assert _listening(port) == []
    np.testing.assert_allclose(wall, np.arange(7) / 30, atol=1e-15)
    np.testing.assert_array_equal(qs[-1], traj.q[-1])
    assert 1 <= shown <= 7  # frames are dropped only when drawing falls behind the clock
    assert v.state is None  # the frames are not analysed

    # the last frame: links, output frame and cables at the trajectory's last pose
    model = paper_robot.model
    data = model.createData()
    q_end = traj.q[-1]
    assert np.linalg.norm(q_end - traj.q[0]) > 0.02  # the arm moved
    pin.framesForwardKinematics(model, data, q_end)
    for j in (1, 2):
        drawn = scene[f"cdpm/model/robot/joint{j}"]["transform"]
        np.testing.assert_allclose(drawn, data.oMi[j].homogeneous, atol=1e-12)
    moved = start["cdpm/model/robot/joint2"]["transform"] - data.oMi[2].homogeneous
    assert np.abs(moved).max() > 1e-2
    tip = data.oMf[model.getFrameId("tip")].homogeneous
    np.testing.assert_allclose(scene["cdpm/output/tip"]["transform"], tip, atol=1e-12)
    for name, route in zip(
        paper_robot.cable_names, paper_robot.attachment_points(q_end), strict=True
    ):
        T = scene[f"cdpm/cables/{name}/0"]["transform"]
        np.testing.assert_allclose(T[:3, 3], 0.5 * (route[0] + route[1]), atol=1e-12)
        np.testing.assert_allclose(T[:3, 1], route[1] - route[0], atol=1e-12)  # its length

    # cables by their tension at the end: zero is slack pink, the largest (the
    # scale) navy, half of it between
    colour = {n: _material_color(scene, f"cdpm/cables/{n}/0/line") for n in paper_robot.cable_names}
    assert colour["c1"] == colour["c4"] == _rgb_int(COLORS["slack"])
    assert colour["c3"] == _rgb_int(COLORS["taut_high"])
    mid = 0.5 * (np.array(COLORS["taut_low"]) + np.array(COLORS["taut_high"]))
    np.testing.assert_allclose(_rgb(colour["c2"]), mid, atol=0.03)  # 32 shades
    # at the start, the equilibrium at zero tension: every cable slack
    for name in paper_robot.cable_names:
        assert _material_color(start, f"cdpm/cables/{name}/0/line") == _rgb_int(COLORS["slack"])
    assert _material_color(start, "cdpm/output/tip/marker") == _rgb_int(COLORS["yes"])
    marker = _material_color(scene, "cdpm/output/tip/marker")
    assert marker == _rgb_int(COLORS["not_analysed"])


def test_play_a_steering_result_ends_where_display_draws_its_last_pose(viewer, paper_robot):
    # URDF visuals (Pinocchio's meshcat support) move like generated links
    assert viewer.geometry == "urdf"
    result = cdpm.steer(paper_robot, "nominal", _steer_target(paper_robot), duration=0.2)
    assert viewer.play(result, speed=2.0) >= 1
    played = _server_scene(viewer)
    state = viewer.display(result.trajectory.q[-1])
    displayed = _server_scene(viewer)
    assert state.verdict is not None
    moving = [
        p for p in displayed if p.startswith(("cdpm/model/robot", "cdpm/cables", "cdpm/output"))
    ]
    transforms = [p for p in moving if "transform" in displayed[p]]
    assert len(transforms) >= 2 + 4 + 1  # two links, four cables, the output frame
    for path in transforms:
        np.testing.assert_allclose(
            played[path]["transform"], displayed[path]["transform"], atol=1e-12, err_msg=path
        )
    viewer.display("nominal")
    start = _server_scene(viewer)
    assert any(not np.allclose(start[p]["transform"], played[p]["transform"]) for p in transforms)


def test_play_refuses_what_it_cannot_play(viewer, paper_robot):
    from dataclasses import replace

    traj = cdpm.simulate(paper_robot, "nominal", tension=[0.0, 1.0, 0.0, 0.0], duration=0.1)
    with pytest.raises(InputError, match="play takes a Trajectory .* got str"):
        viewer.play("nominal")
    other = replace(traj, cable_names=("a", "b", "c", "d"))
    with pytest.raises(InputError, match=r"cables \(a, b, c, d\) are not this robot's"):
        viewer.play(other)
    with pytest.raises(InputError, match="speed=0 must be a positive number"):
        viewer.play(traj, speed=0)
    with pytest.raises(InputError, match="fps=nan must be a positive number"):
        viewer.play(traj, fps=float("nan"))
    with pytest.raises(InputError, match="seconds=-1 must be a non-negative"):
        viewer.play(traj, seconds=-1)
    viewer.display("nominal")


@pytest.mark.slow
def test_ctrl_c_stops_playback_and_the_viewer_stays_usable(viewer, paper_robot):
    import threading

    traj = cdpm.simulate(paper_robot, "nominal", tension=[0.0, 1.0, 0.0, 0.0], duration=0.1)
    # a request whose reply was not read, as when Ctrl-C lands between the two
    viewer._window.zmq_socket.send(b"url")
    viewer._drain_reply()
    viewer._drain_reply()  # nothing outstanding: returns at once
    assert viewer.display("nominal").verdict_key == "yes"

    def ctrl_c_in(seconds: float) -> threading.Timer:
        timer = threading.Timer(seconds, os.kill, (os.getpid(), signal.SIGINT))
        timer.start()
        return timer

    # a loop ends at Ctrl-C (not at its 60 s) and returns the frames shown
    timer = ctrl_c_in(0.5)
    try:
        started = time.monotonic()
        shown = viewer.play(traj, loop=True, seconds=60)
        assert time.monotonic() - started < 60
    finally:
        timer.cancel()
    assert shown >= 1
    assert viewer.display("nominal").verdict_key == "yes"
    # a single pass (20 s slowed down 200 times) passes Ctrl-C on
    timer = ctrl_c_in(0.5)
    try:
        with pytest.raises(KeyboardInterrupt):
            viewer.play(traj, speed=0.005)
    finally:
        timer.cancel()
    assert viewer.display("nominal").verdict_key == "yes"


@pytest.mark.slow
def test_steer_command_views_for_seconds_then_stops_its_server(capsys):
    pytest.importorskip("meshcat")
    from cdpm.cli import main

    port = _free_port()
    before = _viewer_servers(parent=os.getpid())
    args = ["steer", str(PAPER_SPEC), "--by", "0.005", "--duration", "0.2"]
    assert main([*args, "--view", "--port", str(port), "--seconds", "0.5"]) == 0
    out, err = capsys.readouterr()
    assert f"viewer: http://127.0.0.1:{port}/static/  (playing the motion" in out
    assert "viewer stopped after " in err
    assert _viewer_servers(parent=os.getpid()) == before
    assert _listening(port) == []
    assert main([*args, "--seconds", "1"]) == 1
    assert "--seconds goes with --view" in capsys.readouterr().err


def test_steer_command_ctrl_c_stops_playback_and_the_server():
    pytest.importorskip("meshcat")
    port = _free_port()
    proc = _start_command("steer", str(PAPER_SPEC), "--by", "0.005", "--view", "--port", str(port))
    try:
        url = _viewer_url(proc)
        assert url == f"http://127.0.0.1:{port}/static/", proc.stderr.read()
        assert _viewer_servers(port=port)  # serving while it plays
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0  # the target was reached; Ctrl-C ends the view
        err = proc.stderr.read()
        assert "viewer stopped after " in err and "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert _viewer_servers(port=port) == set()
    if os.path.exists("/proc/net/tcp"):
        assert _listening(port) == []


def test_generated_geometry_and_close(paper_robot):
    pytest.importorskip("meshcat")
    v = cdpm.viewer.Viewer(paper_robot, [0.2, 0.3], geometry="generated")
    pid = v.server_pid
    assert v.geometry == "generated" and v.state.verdict_key == "yes"
    v.close()
    with pytest.raises(ProcessLookupError):
        for _ in range(50):
            os.kill(pid, 0)
            time.sleep(0.1)


def test_viewer_bad_arguments(paper_robot):
    pytest.importorskip("meshcat")
    with pytest.raises(InputError, match="geometry='mesh'"):
        cdpm.viewer.Viewer(paper_robot, geometry="mesh")
    with pytest.raises(InputError, match="tension_scale"):
        cdpm.viewer.Viewer(paper_robot, tension_scale=-1.0)


def _run(code: str, *flags: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *flags, "-c", code],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
        **kwargs,
    )


def test_missing_meshcat_gives_install_hint():
    code = textwrap.dedent(
        f"""
        import sys
        sys.modules["meshcat"] = None  # as if not installed
        import cdpm
        from cdpm.viewer import Viewer
        robot = cdpm.load_robot({str(PAPER_SPEC)!r})
        try:
            Viewer(robot)
        except cdpm.MissingExtraError as exc:
            print("HINT:", exc)
        """
    )
    out = _run(code)
    assert out.returncode == 0, out.stderr
    assert 'pip install "cdpm[viz]"' in out.stdout
    assert issubclass(MissingExtraError, ImportError)


def test_import_cdpm_loads_no_viewer_dependencies():
    out = _run("import cdpm", "-X", "importtime")
    assert out.returncode == 0, out.stderr
    imported = {line.rsplit("|", 1)[-1].strip() for line in out.stderr.splitlines() if "|" in line}
    assert "cdpm" in imported  # the profile did run
    for name in ("meshcat", "matplotlib", "ipywidgets", "zmq", "tornado", "cdpm.viewer"):
        assert not any(m == name or m.startswith(name + ".") for m in imported), name


def test_import_viewer_loads_no_heavy_dependencies():
    code = "import cdpm.viewer, cdpm.plotting.picture, cdpm.plotting"
    out = _run(code, "-X", "importtime")
    assert out.returncode == 0, out.stderr
    imported = {line.rsplit("|", 1)[-1].strip() for line in out.stderr.splitlines() if "|" in line}
    assert "cdpm.viewer.scene" in imported  # the profile did run
    for name in ("meshcat", "matplotlib", "ipywidgets", "pinocchio", "zmq", "tornado"):
        assert not any(m == name or m.startswith(name + ".") for m in imported), name


def test_viewer_modules_import_only_modules_below_them():
    import ast

    layers = [
        "outputs",
        "state",
        "coordinates",
        "server",
        "overlay",
        "output_marks",
        "scene",
        "inspector",
        "panel",
        "page",
    ]
    package = ROOT / "cdpm" / "viewer"
    for k, name in enumerate(layers):
        tree = ast.parse((package / f"{name}.py").read_text())
        used = {
            node.module.rsplit(".", 1)[-1]
            for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("cdpm.viewer.")
        }
        assert used <= set(layers[:k]), f"cdpm.viewer.{name} imports {used - set(layers[:k])}"


# ---------------------------------------------------------------- command


def test_view_command_serves_then_stops(capsys):
    pytest.importorskip("meshcat")
    from cdpm.cli import main

    assert main(["view", str(PAPER_SPEC), "--q", "0", "0", "--seconds", "0.2"]) == 0
    out = capsys.readouterr().out
    assert "Positive output controllability (POC): NO (nilpotent); reach margin r_T = 0 m" in out
    assert "note: singular pose: the output Jacobian dy/dq has rank 0 < p = 1" in out
    assert "viewer: http://127.0.0.1:" in out
    assert "  (for 0.2 s)" in out and "Ctrl-C to stop" not in out  # it stops by itself


def test_view_command_ctrl_c_exits_130_and_stops_the_server():
    pytest.importorskip("meshcat")
    proc = _start_command("view", str(PAPER_SPEC), "--pose", "nominal")
    try:
        lines: list[str] = []
        url = _viewer_url(proc, seen=lines)
        assert url.startswith("http://127.0.0.1:") and url.endswith("/"), proc.stderr.read()
        (scene,) = [line.split()[2] for line in lines if line.startswith("scene alone: ")]
        assert scene.startswith("http://127.0.0.1:") and scene.endswith("/static/")
        ports = [int(u.split(":")[2].split("/")[0]) for u in (url, scene)]
        assert ports[0] != ports[1]
        with urllib.request.urlopen(url, timeout=30) as page:  # the inspection page
            assert '<aside id="panel"' in page.read().decode()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 130
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if os.path.exists("/proc/net/tcp"):
        for port in ports:  # the page's server and the meshcat server
            assert _listening(port) == []


def test_view_command_bad_map(tmp_path, capsys):
    from cdpm.cli import main

    xr = pytest.importorskip("xarray")
    missing = tmp_path / "missing.zarr"
    assert main(["view", str(PAPER_SPEC), "--map", str(missing), "--seconds", "0"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"cdpm view: error: map store {missing} not found; make it with")
    # a zarr store that cdpm did not write is refused, not overlaid (cdpm.open_map)
    ds, _ = _synthetic_map(xr, sample=True)
    ds.to_zarr(tmp_path / "foreign.zarr", consolidated=False)
    args = ["view", str(PAPER_SPEC), "--map", str(tmp_path / "foreign.zarr"), "--seconds", "0"]
    assert main(args) == 1
    assert "is a zarr store but not a cdpm map" in capsys.readouterr().err


@pytest.mark.parametrize("option", ["--port", "--scene-port"])
@pytest.mark.parametrize("port", ["-1", "65536", "99999", "http"])
def test_view_command_port_out_of_range(option, port, capsys):
    from cdpm.cli import main

    with pytest.raises(SystemExit) as info:
        main(["view", str(PAPER_SPEC), option, port, "--seconds", "0"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert (
        f"argument {option}: port {port} is not a TCP port; use 0 (any free port) or 1-65535" in err
    )


def test_viewer_port_out_of_range(paper_robot):
    with pytest.raises(InputError, match="port 99999 is not a TCP port; use 0 .any free port."):
        cdpm.viewer.Viewer(paper_robot, port=99999)
    with pytest.raises(InputError, match="port 0 is not a TCP port; use 1-65535"):
        cdpm.viewer.check_port(0)  # 0 (any free port) only where the caller allows it


# ---------------------------------------------------------------- real browser

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",  # without it WebGL does not start: a blank page
    "--disable-background-networking",
    "--no-first-run",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    "--window-size=800,600",
]


def _count_near(pixels: np.ndarray, rgb, tol: int = 12) -> int:
    target = np.round(np.array(rgb) * 255)
    return int(np.sum(np.all(np.abs(pixels[..., :3].astype(int) - target) <= tol, axis=-1)))


@pytest.mark.skipif(
    shutil.which("chromium") is None and os.environ.get("CI") != "true",
    reason="needs Debian's chromium (apt-get install chromium); CI installs it",
)
def test_browser_renders_cables_and_verdict(paper_robot, tmp_path):
    if os.environ.get("CI") == "true":
        import meshcat  # noqa: F401  CI installs the viz extra: a missing one fails here
    else:
        pytest.importorskip("meshcat")
    from PIL import Image

    chromium = shutil.which("chromium")
    assert chromium, "chromium is not installed (CI must install Debian's chromium)"
    shot = tmp_path / "view.png"
    with cdpm.viewer.Viewer(paper_robot, "nominal") as v:
        for _attempt in range(3):  # a loaded machine may need a longer budget
            profile = tempfile.mkdtemp(prefix="cdpm-chromium-", dir=tmp_path)
            subprocess.run(
                [
                    chromium,
                    *CHROMIUM_FLAGS,
                    f"--user-data-dir={profile}",
                    f"--screenshot={shot}",
                    "--virtual-time-budget=8000",
                    v.url(),
                ],
                capture_output=True,
                timeout=120,
                check=False,
            )
            pixels = np.asarray(Image.open(shot).convert("RGB")) if shot.exists() else None
            if pixels is not None and _count_near(pixels, COLORS["slack"]) > 300:
                break
    assert pixels is not None, "chromium wrote no screenshot"
    assert pixels.shape[:2] == (600, 800)
    slack = _count_near(pixels, COLORS["slack"])
    green = _count_near(pixels, COLORS["yes"], tol=40)  # lit sphere: shaded green
    red = _count_near(pixels, COLORS["no"], tol=40)
    assert slack > 300, f"slack-cable pink pixels: {slack}"
    assert green > 50, f"YES marker green pixels: {green}"
    assert red < 20, f"NO red pixels at a YES pose: {red}"
    assert _count_near(pixels, COLORS["taut_high"]) < 20  # no taut cable at zero tension


@pytest.fixture(scope="module")
def paper_map(tmp_path_factory):
    pytest.importorskip("zarr")
    store = tmp_path_factory.mktemp("maps") / "paper.zarr"
    robot = cdpm.load_robot(PAPER_SPEC)
    cdpm.workspace_map(robot, {"q1": np.linspace(-3, 3, 5)}, store=store, workers=1)
    return store


def test_view_command_overlays_a_map_without_warnings(paper_map, capsys):
    import warnings

    pytest.importorskip("meshcat")
    from cdpm.cli import main

    args = ["view", str(PAPER_SPEC), "--map", str(paper_map), "--seconds", "0"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main([*args, "--color-by", "margin"]) == 0
    assert f"map: 5 poses from {paper_map}, coloured by margin" in capsys.readouterr().out
    from_map_reading = [w for w in caught if "xarray" in w.filename or "zarr" in w.filename]
    assert not from_map_reading, [str(w.message) for w in from_map_reading]


@pytest.mark.slow
def test_view_command_refuses_a_map_of_another_spec(paper_map, write_spec, capsys):
    from cdpm.cli import main

    # the same robot with one more comment line: another file, another hash
    other = write_spec(
        "# edited\n" + PAPER_SPEC.read_text().replace("two_link_planar.urdf", "arm.urdf")
    )
    args = ["view", str(other), "--map", str(paper_map), "--seconds", "0"]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"cdpm view: error: map {paper_map} was made from {PAPER_SPEC} ")
    assert f"not from {other} " in err
    # the other robot's map is kept: the advice is a new store, never --overwrite
    new_store = paper_map.parent / f"{other.stem}.zarr"
    assert (
        f"make a map of this spec into a new store (`cdpm map {other} ... --out {new_store}`)"
        in err
    )
    assert "--overwrite" not in err
    assert "--allow-other-spec" in err and len(err.strip().splitlines()) == 1
    # the Python check says the same, naming its own override
    dataset = cdpm.open_map(paper_map)
    with pytest.raises(InputError, match="check_spec=False"):
        cdpm.viewer.check_map_spec(dataset, cdpm.load_robot(other))
    cdpm.viewer.check_map_spec(dataset, cdpm.load_robot(PAPER_SPEC))  # its own spec: fine
    pytest.importorskip("meshcat")
    assert main([*args, "--allow-other-spec"]) == 0
    assert f"map: 5 poses from {paper_map}, coloured by verdict" in capsys.readouterr().out


def test_map_of_an_edited_spec_is_refused(write_spec):
    pytest.importorskip("zarr")
    text = PAPER_SPEC.read_text().replace("two_link_planar.urdf", "arm.urdf")
    spec = write_spec(text)
    store = spec.parent / "arm.zarr"
    cdpm.workspace_map(cdpm.load_robot(spec), {"q1": [0.1, 0.2]}, store=store, workers=1)
    dataset = cdpm.open_map(store)
    cdpm.viewer.check_map_spec(dataset, cdpm.load_robot(spec))
    spec.write_text(text.replace("nominal", "home"))
    edited = cdpm.load_robot(spec)
    with pytest.raises(InputError, match=f"an earlier version of {spec} or its URDF") as info:
        cdpm.viewer.check_map_spec(dataset, edited)
    # this spec's own stale map: remaking it in place is the fix
    assert f"re-run `cdpm map {spec} ... --out {store} --overwrite`" in str(info.value)
    # a map without the hash (made by hand) is not checked
    dataset.attrs.pop("spec_sha256")
    cdpm.viewer.check_map_spec(dataset, edited)
