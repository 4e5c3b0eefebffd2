"""Viewer scene of a robot from example-robot-data (the double pendulum): every
link drawn, the output marker on the output point, the URDF's package://
meshes found, and a missing mesh falling back to generated links; and how
each kind of output is shown (marker, orientation triad, cable sleeve, text)."""

from __future__ import annotations

import os
import re
import warnings

import numpy as np
import pytest

import cdpm
from cdpm.errors import ModelError
from cdpm.model.spec import package_share_directory
from cdpm.viewer import pose_state
from cdpm.viewer.state import AXIS_RGB, PoseGeometry
from tests.conftest import MODELS
from tests.output_kinds import EVERY_KIND_SPEC
from tests.test_viewer import _material_color, _server_scene, _viewer_servers

PENDULUM_SPEC = MODELS / "double_pendulum_cables" / "double_pendulum_cables.yaml"
#: the output point: 0.2 m along link2, in link2's frame [m]
TIP_IN_LINK2 = np.array([0.0, 0.0, 0.2])


@pytest.fixture(scope="module")
def pendulum():
    if package_share_directory("example-robot-data") is None:
        pytest.skip("needs example-robot-data (pip install 'cdpm[robots]')")
    return cdpm.load_robot(PENDULUM_SPEC)


def _joint_world(robot, q, joint: int) -> np.ndarray:
    """World placement (4, 4) of a joint at q."""
    geometry = PoseGeometry(robot)
    geometry.update(robot.as_q(q))
    return geometry.joint_placements()[joint]


def _user_warnings(caught) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


def _no_server_left() -> None:
    assert _viewer_servers(parent=os.getpid()) == set(), "a meshcat server is still running"


# ---------------------------------------------------------------- without a server


def test_link2_is_drawn_to_the_points_it_carries(pendulum):
    from cdpm.viewer.state import link_segments

    # joint2 has no child joint and its frames sit at its origin: link2 used to
    # have no segment at all; it reaches its cable attachments and the output point
    ends = {tuple(np.round(b, 9)) for j, a, b in link_segments(pendulum) if j == 2}
    assert ends == {(0.0, 0.01, 0.18), (0.0, -0.01, 0.18), (0.0, 0.0, 0.2)}
    starts = [a for j, a, _ in link_segments(pendulum) if j == 2]
    np.testing.assert_allclose(starts, 0.0, atol=0)
    # link1 still reaches joint2 (0.023, 0, 0.1 from joint1)
    assert any(
        j == 1 and np.allclose(b, [0.023, 0.0, 0.1], atol=1e-12)
        for j, _, b in link_segments(pendulum)
    )


def test_outputs_and_marker_position_are_the_robots_outputs(pendulum):
    y = pendulum.output("leaning")  # (tip_y, tip_z) [m]
    state = pose_state(pendulum, "leaning")
    np.testing.assert_allclose(state.output, y, rtol=0, atol=1e-12)
    assert state.output_frames == ("link2",)
    np.testing.assert_allclose(state.output_frame_positions[0, 1:], y, rtol=0, atol=1e-12)
    # the marker sits 0.2 m along link2 from its joint, not on link2's origin
    T = _joint_world(pendulum, "leaning", 2)
    expected = T[:3, :3] @ TIP_IN_LINK2 + T[:3, 3]
    np.testing.assert_allclose(state.output_frame_positions[0], expected, atol=1e-12)
    assert np.linalg.norm(state.output_frame_positions[0] - T[:3, 3]) == pytest.approx(0.2)
    assert "tip_y = 0.0008 m, tip_z = 0.3231 m" in str(state)


def test_package_mesh_resolves_to_an_existing_file(pendulum):
    import pinocchio as pin

    from cdpm.viewer.state import mesh_package_dirs

    urdf = pendulum.spec.urdf_path
    share = package_share_directory("example-robot-data")
    dirs = mesh_package_dirs(urdf)
    assert dirs[0] == urdf.parent and share.parent in dirs
    visual = pin.buildGeomFromUrdf(
        pendulum.model, str(urdf), pin.GeometryType.VISUAL, package_dirs=[str(d) for d in dirs]
    )
    meshes = {o.name: o.meshPath for o in visual.geometryObjects}
    assert set(meshes) == {"base_link_0", "link1_0", "link2_0"}
    link2 = share / "robots" / "double_pendulum_description" / "meshes" / "link2.stl"
    assert meshes["link2_0"] == str(link2) and link2.stat().st_size > 1000


def test_package_dirs_of_a_urdf_inside_its_own_package(tmp_path):
    from cdpm.viewer.state import mesh_package_dirs

    # a package not installed, but the URDF lives in a folder named after it
    urdf = tmp_path / "my_robot" / "urdf" / "arm.urdf"
    urdf.parent.mkdir(parents=True)
    urdf.write_text('<robot name="a"><link name="b"/><!-- package://my_robot/m.stl --></robot>')
    assert mesh_package_dirs(urdf) == [urdf.parent, tmp_path]


def test_two_output_points_on_one_frame(write_spec):
    spec = write_spec(
        """
        urdf: arm.urdf
        gravity: [0, 0, 0]
        cables:
          - name: c1
            route:
              - {frame: base, point: [0, 0.5, 0]}
              - {frame: link1, point: [0.8, 0.1, 0]}
        outputs:
          - {name: tip_x, frame: tip, component: x}
          - {name: tip_y, frame: tip, component: y}
          - {name: side_y, frame: tip, component: y, point: [0, 0.25, 0]}
        poses:
          p: [0.3, 0.4]
        """
    )
    robot = cdpm.load_robot(spec)
    state = pose_state(robot, "p")
    np.testing.assert_allclose(state.output, robot.output("p"), rtol=0, atol=1e-12)
    assert state.output_frames == ("tip", "tip")
    geometry = PoseGeometry(robot)
    assert geometry.output_labels == ("tip_x, tip_y", "side_y")
    assert geometry.output_point_names == ("tip", "tip.2")
    # the tip of the paper's arm (two 1 m links), and 0.25 m across link2 from it
    q1, q2 = 0.3, 0.4
    tip = [np.cos(q1) + np.cos(q1 + q2), np.sin(q1) + np.sin(q1 + q2), 0.0]
    side = np.array(tip) + 0.25 * np.array([-np.sin(q1 + q2), np.cos(q1 + q2), 0.0])
    np.testing.assert_allclose(state.output_frame_positions, [tip, side], atol=1e-12)


# ---------------------------------------------------------------- with a server


@pytest.mark.slow
@pytest.mark.parametrize("geometry", ["auto", "generated"])
def test_viewer_draws_link2_and_the_marker_on_the_output_point(pendulum, geometry):
    pytest.importorskip("meshcat")
    from cdpm.viewer import Viewer

    y = pendulum.output("leaning")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        viewer = Viewer(pendulum, "leaning", geometry=geometry)
    try:
        assert _user_warnings(caught) == []  # the meshes are found
        assert viewer.geometry == ("urdf" if geometry == "auto" else "generated")
        np.testing.assert_allclose(viewer.state.output, y, rtol=0, atol=1e-12)
        scene = _server_scene(viewer)
    finally:
        viewer.close()
    _no_server_left()
    # the marker (a sphere at the origin of the output node) on the output point
    marker_at = scene["cdpm/output/link2"]["transform"][:3, 3]
    np.testing.assert_allclose(marker_at[1:], y, atol=1e-12)
    (sphere,) = scene["cdpm/output/link2/marker"]["object"]["geometries"]
    assert (
        sphere["type"] == "SphereGeometry" and "transform" not in scene["cdpm/output/link2/marker"]
    )
    joint2 = _joint_world(pendulum, "leaning", 2)
    if geometry == "auto":  # example-robot-data's STL mesh of link2, moved with joint2
        mesh = scene["cdpm/model/robot/visuals/link2_0"]
        (geo,) = mesh["object"]["geometries"]
        share = package_share_directory("example-robot-data")
        stl = share / "robots" / "double_pendulum_description" / "meshes" / "link2.stl"
        assert geo["format"] == "stl" and geo["data"].data == stl.read_bytes()  # msgpack Ext
        np.testing.assert_allclose(mesh["transform"], joint2, atol=1e-12)
        return
    # generated links: a cylinder under joint2 from its origin to the output point
    np.testing.assert_allclose(scene["cdpm/model/robot/joint2"]["transform"], joint2, atol=1e-12)
    links = [
        node["transform"]
        for path, node in scene.items()
        if path.startswith("cdpm/model/robot/joint2/link") and "object" in node
    ]
    assert len(links) == 3  # to the two cable attachments and to the output point
    # meshcat's cylinder is centred with its axis along y: the centre and half-axis
    tips = [T[:3, 3] + 0.5 * T[:3, 1] for T in links]
    assert any(np.allclose(tip, TIP_IN_LINK2, atol=1e-12) for tip in tips), tips


def _arm_with_mesh(write_spec, mesh: str):
    """The paper's arm, its link visuals replaced by ``mesh``."""
    spec = write_spec(
        """
        urdf: arm.urdf
        gravity: [0, 0, 0]
        cables:
          - name: c1
            route:
              - {frame: base, point: [0, 0.5, 0]}
              - {frame: link1, point: [0.8, 0.1, 0]}
        outputs:
          - {name: tip_x, frame: tip, component: x}
        poses:
          p: [0.3, 0.4]
        """
    )
    urdf = spec.parent / "arm.urdf"
    cylinder = '<cylinder radius="0.03" length="1.0"/>'
    text = urdf.read_text()
    assert cylinder in text
    urdf.write_text(text.replace(cylinder, f'<mesh filename="{mesh}"/>'))
    return cdpm.load_robot(spec)


@pytest.mark.slow
@pytest.mark.parametrize("mesh", ["package://no_such_package/meshes/link.stl", "unreadable.stl"])
def test_missing_mesh_falls_back_to_generated_links_with_one_warning(write_spec, mesh):
    pytest.importorskip("meshcat")
    from cdpm.viewer import Viewer

    robot = _arm_with_mesh(write_spec, mesh)
    (robot.spec.urdf_path.parent / "unreadable.stl").write_text("not an STL file")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with Viewer(robot, "p") as viewer:
            assert viewer.geometry == "generated"
            scene = _server_scene(viewer)
    _no_server_left()
    (message,) = _user_warnings(caught)
    assert mesh in message and "drawing generated links" in message
    assert "\n" not in message
    assert any(path.startswith("cdpm/model/robot/joint2/link") for path in scene)
    with pytest.raises(ModelError, match=re.escape(mesh)):
        Viewer(robot, "p", geometry="urdf")
    _no_server_left()


# ---------------------------------------------------------------- every output kind

Q1, Q2 = 0.3, 0.4


@pytest.fixture
def every_kind(write_spec):
    return cdpm.load_robot(write_spec(EVERY_KIND_SPEC))


def _every_kind_by_hand() -> dict:
    """Outputs, the tip and link2's origin of EVERY_KIND_SPEC at (Q1, Q2), worked by hand."""
    elbow = np.array([np.cos(Q1), np.sin(Q1), 0.0])  # link2's origin
    tip = elbow + [np.cos(Q1 + Q2), np.sin(Q1 + Q2), 0.0]
    c1_on_link1 = [0.8 * np.cos(Q1) - 0.1 * np.sin(Q1), 0.8 * np.sin(Q1) + 0.1 * np.cos(Q1)]
    c1_length = float(np.hypot(c1_on_link1[0], c1_on_link1[1] - 0.5))
    outputs = [tip[0], Q1 + Q2, Q2, c1_length, 0.5 * elbow[0] + 0.5 * tip[0]]
    return {"outputs": np.array(outputs), "tip": tip, "elbow": elbow}


def test_every_output_kind_in_the_state_and_its_text(every_kind):
    hand = _every_kind_by_hand()
    state = pose_state(every_kind, "p")
    np.testing.assert_allclose(state.output, hand["outputs"], rtol=0, atol=1e-12)
    assert state.output_units == ("m", "rad", "rad", "m", "m")
    assert state.output_kinds == ("position", "rotation", "joint", "cable", "sum")
    # one marker at the tip (tip_x and tip_rz), one at the sum's first term
    # (link2's origin); none for the joint and the cable output
    geometry = PoseGeometry(every_kind)
    assert state.output_frames == ("tip", "link2")
    assert geometry.output_labels == ("tip_x, tip_rz", "mid_x")
    assert geometry.output_point_rotation == (True, False)
    np.testing.assert_allclose(
        state.output_frame_positions, [hand["tip"], hand["elbow"]], rtol=0, atol=1e-12
    )
    assert geometry.drawing.cables == {0: ("c1_length",)}
    assert geometry.drawing.joints == {"q2": ("elbow",)}
    y = hand["outputs"]
    assert (
        f"outputs: tip_x = {y[0]:.4f} m, tip_rz = 0.7000 rad (tip.rz), "
        f"elbow = 0.4000 rad (joint q2), c1_length = {y[3]:.4f} m (cable c1), "
        f"mid_x = {y[4]:.4f} m (0.5 link2.x + 0.5 tip.x)"
    ) in str(state)
    assert state.as_dict()["output_units"] == {
        "tip_x": "m",
        "tip_rz": "rad",
        "elbow": "rad",
        "c1_length": "m",
        "mid_x": "m",
    }


def test_the_panel_lists_every_output_with_its_unit_and_formula(every_kind):
    from cdpm.viewer import pose_panel

    panel = pose_panel(every_kind, "p")
    rows = {row["name"]: row for row in panel.as_dict()["outputs"]}
    assert {n: (r["unit"], r["kind"], r["definition"]) for n, r in rows.items()} == {
        "tip_x": ("m", "position", "tip.x"),
        "tip_rz": ("rad", "rotation", "tip.rz"),
        "elbow": ("rad", "joint", "joint q2"),
        "c1_length": ("m", "cable", "cable c1"),
        "mid_x": ("m", "sum", "0.5 link2.x + 0.5 tip.x"),
    }
    assert rows["elbow"]["value"] == pytest.approx(Q2, abs=1e-12)
    assert "elbow = 0.4000 rad (joint q2)" in str(panel)
    assert "tip_rz = 0.7000 rad (tip.rz)" in str(panel)


def test_a_spec_of_only_joint_and_cable_outputs_has_no_marker(write_spec):
    cables = EVERY_KIND_SPEC.split("    outputs:")[0]
    outputs = """
    outputs:
      - {name: elbow, joint: q2}
      - {name: c2_length, cable: c2}
    poses:
      p: [0.3, 0.4]
    """
    spec = write_spec(cables + outputs.lstrip("\n"))
    robot = cdpm.load_robot(spec)
    state = pose_state(robot, "p")
    assert state.output_frames == () and state.output_frame_positions.shape == (0, 3)
    assert PoseGeometry(robot).drawing.cables == {1: ("c2_length",)}
    assert "elbow = 0.4000 rad (joint q2)" in str(state)


def test_viewer_draws_a_triad_for_orientation_and_a_sleeve_for_cable_length(every_kind):
    pytest.importorskip("meshcat")
    from cdpm.viewer import Viewer
    from cdpm.viewer.output_marks import TRIAD_SIZE, rgb_int

    hand = _every_kind_by_hand()
    with Viewer(every_kind, "p", geometry="generated") as viewer:
        scene = _server_scene(viewer)
        verdict, size = viewer.marker_color, viewer._size
    _no_server_left()
    nodes = {p.split("/")[2] for p in scene if p.startswith("cdpm/output/")}
    assert nodes == {"tip", "link2"}  # no node for the joint or the cable output
    markers = {p for p in scene if p.startswith("cdpm/output/") and p.endswith("/marker")}
    assert markers == {"cdpm/output/tip/marker", "cdpm/output/link2/marker"}
    for path in markers:
        assert _material_color(scene, path) == rgb_int(verdict)
    # the tip's node: on the tip, turned as the tip frame (Q1 + Q2 about z)
    T = scene["cdpm/output/tip"]["transform"]
    c, s = np.cos(Q1 + Q2), np.sin(Q1 + Q2)
    np.testing.assert_allclose(T[:3, 3], hand["tip"], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-12)
    # its triad: an arrow along each of the frame's axes, in red, green, blue
    triad = sorted(p for p in scene if p.startswith("cdpm/output/tip/triad/"))
    assert triad == [
        f"cdpm/output/tip/triad/{a}/{part}" for a in "xyz" for part in ("head", "shaft")
    ]
    for k, axis in enumerate("xyz"):
        shaft = scene[f"cdpm/output/tip/triad/{axis}/shaft"]["transform"]
        head = scene[f"cdpm/output/tip/triad/{axis}/head"]["transform"]
        tip_of_arrow = head[:3, 3] + 0.5 * head[:3, 1]  # meshcat's cylinder: along y, centred
        direction = tip_of_arrow / np.linalg.norm(tip_of_arrow)
        np.testing.assert_allclose(T[:3, :3] @ direction, T[:3, k], atol=1e-12)
        np.testing.assert_allclose(shaft[:3, 3] - 0.5 * shaft[:3, 1], 0.0, atol=1e-12)
        assert np.linalg.norm(tip_of_arrow) == pytest.approx(TRIAD_SIZE * size, rel=1e-12)
        rgb = _material_color(scene, f"cdpm/output/tip/triad/{axis}/shaft")
        assert rgb == rgb_int(AXIS_RGB[k])
    assert not any(p.startswith("cdpm/output/link2/triad") for p in scene)
    # the cable whose length is an output wears a translucent sleeve in the verdict colour
    sleeve = scene["cdpm/cables/c1/0/output"]["object"]
    assert sleeve["materials"][0]["opacity"] == 0.4
    assert sleeve["materials"][0]["color"] == rgb_int(verdict)
    assert "cdpm/cables/c2/0/output" not in scene
