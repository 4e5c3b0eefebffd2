"""Robot layer: kinematics, cable Jacobian and mass matrix against the paper
and against finite differences at random poses."""

from __future__ import annotations

import math

import numpy as np
import pytest

import cdpm

RNG_SEED = 20261121
FD_STEP = 1e-6
FD_TOL = 1e-6


def random_poses(n: int, seed: int = RNG_SEED) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-math.pi, math.pi, size=(n, 2))


def central_difference(fun, q: np.ndarray, step: float = FD_STEP) -> np.ndarray:
    cols = []
    for k in range(q.size):
        dq = np.zeros_like(q)
        dq[k] = step
        cols.append((fun(q + dq) - fun(q - dq)) / (2 * step))
    return np.stack(cols, axis=-1)


def test_sizes_and_names(paper_robot):
    r = paper_robot
    assert (r.nq, r.nv, r.n_cables, r.n_outputs) == (2, 2, 4, 1)
    assert r.cable_names == ("c1", "c2", "c3", "c4")
    assert r.output_names == ("tip_x",)
    assert r.coordinate_names == ("q1", "q2")
    assert set(r.poses) == {"nominal"}
    np.testing.assert_array_equal(r.model.gravity.linear, [0, 0, 0])


@pytest.mark.parametrize("q", random_poses(20))
def test_mass_matrix_is_paper_eq14(paper_robot, q):
    c2 = math.cos(q[1])
    expected = np.array([[c2 + 1.5, 0.5 * c2 + 0.25], [0.5 * c2 + 0.25, 0.25]])
    np.testing.assert_allclose(paper_robot.mass_matrix(q), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("q", random_poses(20))
def test_output_is_paper_eq17(paper_robot, q):
    expected = math.cos(q[0]) + math.cos(q[0] + q[1])
    np.testing.assert_allclose(paper_robot.output(q), [expected], rtol=0, atol=1e-12)
    grad = [-math.sin(q[0]) - math.sin(q[0] + q[1]), -math.sin(q[0] + q[1])]
    np.testing.assert_allclose(paper_robot.output_jacobian(q), [grad], rtol=0, atol=1e-12)


def hand_lengths(q: np.ndarray) -> np.ndarray:
    """Table I geometry worked by hand in the x-y plane."""

    def rot(a):
        return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])

    elbow = rot(q[0]) @ [1.0, 0.0]
    points = [
        ((0, 0.5), rot(q[0]) @ [0.8, 0.1]),
        ((0, 1.5), elbow + rot(q[0] + q[1]) @ [0.8, 0.1]),
        ((0, -0.5), rot(q[0]) @ [0.8, -0.1]),
        ((0, -1.5), elbow + rot(q[0] + q[1]) @ [0.8, -0.1]),
    ]
    return np.array([np.linalg.norm(np.subtract(b, a)) for a, b in points])


@pytest.mark.parametrize("q", random_poses(20))
def test_cable_lengths_by_hand_and_jacobian_by_fd(paper_robot, q):
    np.testing.assert_allclose(paper_robot.cable_lengths(q), hand_lengths(q), rtol=0, atol=1e-12)
    fd = central_difference(paper_robot.cable_lengths, q)
    np.testing.assert_allclose(paper_robot.cable_jacobian(q), fd, rtol=0, atol=FD_TOL)


def test_paper_cable_jacobian_structure(paper_robot):
    # eq 16: cables 1 and 3 end on link 1, so they do not depend on q2
    L = paper_robot.cable_jacobian("nominal")
    assert L[0, 1] == 0 and L[2, 1] == 0
    assert abs(L[1, 1]) > 0.1 and abs(L[3, 1]) > 0.1


MULTI = """
urdf: arm.urdf
gravity: [0, 0, 0]
cables:
  - name: through
    tension: [1, 100]
    route:
      - {frame: world, point: [0, 1, 0]}
      - {frame: link1, point: [0.5, 0.1, 0]}
      - {frame: link2, point: [0.5, 0.1, 0]}
      - {frame: tip, point: [0, 0, 0.2]}
outputs:
  - {frame: tip, component: x}
  - {frame: tip, component: y}
"""


def test_multi_segment_route(write_spec):
    robot = cdpm.load_robot(write_spec(MULTI))
    assert robot.output_names == ("tip_x", "tip_y")
    np.testing.assert_array_equal(robot.tension_min, [1.0])
    for q in random_poses(20, seed=7):
        c1, s1 = math.cos(q[0]), math.sin(q[0])
        c12, s12 = math.cos(q[0] + q[1]), math.sin(q[0] + q[1])
        p0 = np.array([0, 1, 0])
        p1 = np.array([0.5 * c1 - 0.1 * s1, 0.5 * s1 + 0.1 * c1, 0])
        elbow = np.array([c1, s1, 0])
        p2 = elbow + [0.5 * c12 - 0.1 * s12, 0.5 * s12 + 0.1 * c12, 0]
        p3 = elbow + [c12, s12, 0.2]
        expected = sum(np.linalg.norm(b - a) for a, b in [(p0, p1), (p1, p2), (p2, p3)])
        np.testing.assert_allclose(robot.cable_lengths(q), [expected], rtol=0, atol=1e-12)
        fd = central_difference(robot.cable_lengths, q)
        np.testing.assert_allclose(robot.cable_jacobian(q), fd, rtol=0, atol=FD_TOL)
        np.testing.assert_allclose(robot.output(q), p3[:2], atol=1e-12)
        pts = robot.attachment_points(q)[0]
        np.testing.assert_allclose(pts, np.stack([p0, p1, p2, p3]), atol=1e-12)


def test_zero_length_segment_is_a_clear_error(write_spec):
    text = MULTI.replace("{frame: world, point: [0, 1, 0]}", "{frame: world, point: [0.5, 0.1, 0]}")
    robot = cdpm.load_robot(write_spec(text))
    with pytest.raises(cdpm.ModelError, match=r"cable 'through': segment 0 has zero length"):
        robot.cable_jacobian([0.0, 0.3])


def test_configuration_validation(paper_robot):
    with pytest.raises(cdpm.InputError, match=r"q has 3 entries, expected nq=2"):
        paper_robot.cable_lengths([0, 1, 2])
    with pytest.raises(cdpm.InputError, match=r"q\[1\] = nan: coordinates must be finite"):
        paper_robot.mass_matrix([0, float("nan")])
    with pytest.raises(cdpm.InputError, match=r"pose 'home' not in spec; poses: nominal"):
        paper_robot.configuration("home")


def test_load_robot_accepts_model_folder(paper_robot):
    from tests.conftest import MODELS

    robot = cdpm.load_robot(MODELS / "two_link_planar")
    assert robot.cable_names == paper_robot.cable_names


PENDULUM_URDF = """<?xml version="1.0"?>
<robot name="pendulum">
  <link name="base"/>
  <link name="arm">
    <inertial><origin xyz="0.5 0 0"/><mass value="2.0"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
  </link>
  <joint name="hinge" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
</robot>
"""


def test_single_degree_of_freedom_robot(tmp_path):
    (tmp_path / "pendulum.urdf").write_text(PENDULUM_URDF)
    spec = tmp_path / "pendulum.yaml"
    spec.write_text(
        "urdf: pendulum.urdf\ngravity: [0, 0, 0]\n"
        "cables:\n  - name: up\n    route:\n      - {frame: world, point: [0, 1, 0]}\n"
        "      - {frame: arm, point: [1, 0, 0]}\n"
        "outputs:\n  - {frame: arm, component: y}\n"
    )
    robot = cdpm.load_robot(spec)
    assert (robot.nq, robot.nv) == (1, 1)
    q = np.array([0.3])
    # length of the segment from (0, 1) to (cos q, sin q): sqrt(2 - 2 sin q)
    np.testing.assert_allclose(robot.cable_lengths(q), [math.sqrt(2 - 2 * math.sin(0.3))])
    fd = central_difference(robot.cable_lengths, q)
    np.testing.assert_allclose(robot.cable_jacobian(q), fd, rtol=0, atol=FD_TOL)
    np.testing.assert_allclose(robot.mass_matrix(q), [[0.5]], atol=1e-12)  # 2 kg at 0.5 m
