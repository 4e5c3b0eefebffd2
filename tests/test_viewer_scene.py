"""Viewer scene of a robot from example-robot-data (the double pendulum): every
link drawn, the output marker on the output point, the URDF's package://
meshes found, and a missing mesh falling back to generated links."""

from __future__ import annotations

import os
import re
import warnings

import numpy as np
import pytest

import cdpm
from cdpm.errors import ModelError
from cdpm.spec import package_share_directory
from cdpm.viewer import pose_state
from cdpm.viewer.state import PoseGeometry
from tests.conftest import MODELS
from tests.test_viewer import _server_scene, _viewer_servers

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
    assert "tip_y = 0.0008, tip_z = 0.3231" in str(state)


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
        mesh = scene["cdpm/robot/visuals/link2_0"]
        (geo,) = mesh["object"]["geometries"]
        share = package_share_directory("example-robot-data")
        stl = share / "robots" / "double_pendulum_description" / "meshes" / "link2.stl"
        assert geo["format"] == "stl" and geo["data"].data == stl.read_bytes()  # msgpack Ext
        np.testing.assert_allclose(mesh["transform"], joint2, atol=1e-12)
        return
    # generated links: a cylinder under joint2 from its origin to the output point
    np.testing.assert_allclose(scene["cdpm/robot/joint2"]["transform"], joint2, atol=1e-12)
    links = [
        node["transform"]
        for path, node in scene.items()
        if path.startswith("cdpm/robot/joint2/link") and "object" in node
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
    assert any(path.startswith("cdpm/robot/joint2/link") for path in scene)
    with pytest.raises(ModelError, match=re.escape(mesh)):
        Viewer(robot, "p", geometry="urdf")
    _no_server_left()
