"""Linearisation of the paper's example: eqs 24-28 from URDF + YAML."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm

# Paper eq 25, rows 3 and 4, as printed (3 decimals).
PAPER_B3 = [0.500, -0.046, -0.337, -0.822]
PAPER_B4 = [-1.000, 3.088, 0.674, 2.310]
# Half a unit in the printed digit. The paper's 2.310 is 2.3094976 rounded
# (to 2.3095 then 2.310); allow 1e-5 beyond half a unit for that entry.
PRINTED = 0.5e-3 + 1e-5


def test_paper_eqs_24_to_26(paper_robot):
    lin = cdpm.linearise(paper_robot, "nominal")
    expected_A = np.zeros((4, 4))
    expected_A[0, 2] = expected_A[1, 3] = 1.0
    np.testing.assert_array_equal(lin.A, expected_A)  # eq 24
    np.testing.assert_array_equal(lin.B[:2], 0.0)  # eq 25, rows 1-2
    np.testing.assert_allclose(lin.B[2], PAPER_B3, rtol=0, atol=PRINTED)
    np.testing.assert_allclose(lin.B[3], PAPER_B4, rtol=0, atol=PRINTED)
    np.testing.assert_allclose(lin.C, [[-1.5, -1.0, 0.0, 0.0]], rtol=0, atol=1e-12)  # eq 26
    np.testing.assert_array_equal(lin.tension, 0.0)
    assert lin.sign_constrained.tolist() == [True] * 4
    assert lin.nilpotent
    np.testing.assert_allclose(lin.output, [np.sqrt(3) / 2], atol=1e-15)  # y_eq
    assert lin.state_names == ("q1", "q2", "q1_dot", "q2_dot")


def test_paper_eq28(paper_robot):
    lin = cdpm.linearise(paper_robot, "nominal")
    np.testing.assert_allclose(lin.C @ lin.B, 0.0, atol=1e-15)  # no t^0 term
    cab = lin.C @ lin.A @ lin.B  # C e^{At} B = t CAB (eq 28)
    np.testing.assert_allclose(cab, [[0.250, -3.018, -0.169, -1.077]], rtol=0, atol=0.5e-3)


def test_linearise_rejects_bad_tension(paper_robot, write_spec):
    with pytest.raises(cdpm.InputError, match="tension has 3 entries, expected one per cable"):
        cdpm.linearise(paper_robot, "nominal", tension=[0, 0, 0])
    with pytest.raises(cdpm.InputError, match=r"tension outside the cable bounds: c1=-1"):
        cdpm.linearise(paper_robot, "nominal", tension=[-1, 0, 0, 0])
    # nonzero tension that does not hold the pose: rejected with its residual
    with pytest.raises(cdpm.InputError, match=r"not an equilibrium .* residual"):
        cdpm.linearise(paper_robot, "nominal", tension=[1, 0, 0, 0])


def test_given_tension_within_round_off_of_a_bound_is_accepted():
    # elbow_up of two_link_vertical: c1 alone holds the arm. Adding a multiple
    # of the null-space direction of L^T that loads c1 and c3 together gives
    # another equilibrium; a round-off negative on a slack cable must not
    # turn it into "not an equilibrium".
    from tests.conftest import MODELS

    robot = cdpm.load_robot(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
    base = cdpm.linearise(robot, "elbow_up")
    L = base.cable_jacobian
    n = np.array([L[2, 0], 0.0, -L[0, 0], 0.0])  # L^T n = 0: c1 and c3 act on joint 1 only
    n = n / n[2]
    tension = base.tension + 5.0 * n
    tension[[1, 3]] = -1e-13
    lin = cdpm.linearise(robot, "elbow_up", tension=tension)
    np.testing.assert_allclose(lin.tension[[1, 3]], 0.0, atol=0)
    assert lin.sign_constrained.tolist() == [False, True, False, True]
    assert lin.tension[2] == pytest.approx(5.0)


@pytest.mark.parametrize("q", [(0.0, np.pi), (np.pi, 0.0), (0.0, -np.pi), (np.pi, np.pi)])
def test_round_off_output_jacobian_is_no_output_direction(q):
    """At a folded or stretched pose of the paper arm, d(tip x)/dq = 0 and
    forward kinematics leaves ~1e-16: that is no output direction, so the
    output rank is 0 and POC is NO (not a YES judged on round-off)."""
    from tests.conftest import MODELS

    robot = cdpm.load_robot(MODELS / "two_link_planar" / "two_link_planar.yaml")
    lin = cdpm.linearise(robot, np.array(q))
    assert np.abs(robot.output_jacobian(np.array(q))).max() < 1e-15  # round-off
    assert not np.any(lin.C)
    poc = cdpm.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
    )
    assert poc.verdict is cdpm.Verdict.NO
    natural = np.array([q])
    out = cdpm.evaluate_poses(robot, natural)
    assert out["poc"][0] == cdpm.VERDICT_CODES["no"] and out["output_controllable"][0] == 0
    # a genuine direction nearby is kept
    near = cdpm.linearise(robot, np.array(q) + 1e-6)
    assert np.any(near.C)


def test_a_free_flyers_states_are_named_in_its_own_frame():
    """The states of a free-flyer platform are its tangent displacement
    dq (q = pin.integrate(q0, dq)) and velocity, both in the platform's own
    frame: d_x moves it along its own x axis, th_z turns it about its own z
    axis, at a tilted pose where those differ from the world's x, z and yaw."""
    import pinocchio as pin

    from tests.conftest import MODELS

    robot = cdpm.load_robot(MODELS / "spatial_8cable" / "spatial_8cable.yaml")
    lin = cdpm.linearise(robot, robot.configuration([0.0, 0.0, 1.0, 0.1, -0.05, 0.1]))
    joint = robot.model.names[1]
    displacement = [f"{joint}.{c}" for c in ("d_x", "d_y", "d_z", "th_x", "th_y", "th_z")]
    velocity = [f"{joint}.{c}" for c in ("v_x", "v_y", "v_z", "w_x", "w_y", "w_z")]
    assert lin.state_names == tuple(displacement + velocity)
    q0 = lin.q
    rotation = pin.XYZQUATToSE3(q0).rotation
    assert not np.allclose(rotation, np.eye(3), atol=0.05)
    for k, axis in ((0, [1.0, 0.0, 0.0]), (5, [0.0, 0.0, 1.0])):
        dq = np.zeros(6)
        dq[k] = 1e-3
        moved = pin.XYZQUATToSE3(pin.integrate(robot.model, q0, dq))
        if k < 3:  # along the platform's own axis, not the world's
            np.testing.assert_allclose(
                moved.translation - q0[:3], 1e-3 * rotation @ axis, atol=1e-12
            )
        else:  # about the platform's own axis
            turned = pin.log3(rotation.T @ moved.rotation)
            np.testing.assert_allclose(turned, 1e-3 * np.array(axis), atol=1e-12)
