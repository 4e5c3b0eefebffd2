"""One pipeline: the per-pose API is the batched stages on a batch of one.

The numbers agree to round-off, not always bit for bit: the batch kinematics
are views whose strides depend on the batch size, and numpy's products of
strided operands can round differently (a few units in 1e-16). Verdicts
must agree exactly."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.dynamics.equilibrium import equilibrium_tensions
from cdpm.dynamics.linearisation import linearise_batch, mass_inverse
from cdpm.model.poses import configurations
from tests.conftest import MODELS

SPECS = {
    "vertical": MODELS / "two_link_vertical" / "two_link_vertical.yaml",
    "spatial": MODELS / "spatial_8cable" / "spatial_8cable.yaml",
    "multilink": MODELS / "multilink_arm" / "multilink_arm.yaml",
}


def _feasible_poses(robot, n, seed):
    base = robot.to_natural(next(iter(robot.poses.values())))
    natural = base + np.random.default_rng(seed).uniform(-0.2, 0.2, (n, robot.nv))
    return configurations(robot, natural)


@pytest.mark.parametrize("name", list(SPECS))
def test_per_pose_equilibrium_and_linearisation_are_the_batch_of_one(name):
    robot = cdpm.load_robot(SPECS[name])
    qs = _feasible_poses(robot, 8, seed=11)
    kin = robot.kinematics_batch(qs, dynamics=True)
    LT = np.swapaxes(kin.jacobian, 1, 2)
    eq = equilibrium_tensions(robot, LT, -kin.gravity - robot.external_wrench)
    Minv, regular = mass_inverse(kin.mass_matrix)
    assert regular.all()
    lin = linearise_batch(robot, kin, Minv, eq.tension, eq.input_sign)
    compared = 0
    for i, q in enumerate(qs):
        one = cdpm.equilibrium_tension(robot, q)
        assert one.feasible == eq.feasible[i]
        if not one.feasible:
            continue
        scale = max(1.0, float(np.abs(one.tension).max()))
        np.testing.assert_allclose(one.tension, eq.tension[i], rtol=0, atol=1e-12 * scale)
        np.testing.assert_array_equal(one.at_lower_bound, eq.at_lower_bound[i])
        single = cdpm.linearise(robot, q)
        for field in ("A", "B", "C", "B_cone", "stiffness"):
            a, b = getattr(single, field), getattr(lin, field)[i]
            atol = 1e-12 * max(1.0, float(np.abs(b).max()))
            np.testing.assert_allclose(a, b, rtol=0, atol=atol, err_msg=field)
        compared += 1
    assert compared >= 4
    # the map of these poses and each pose alone: the same verdicts
    natural = np.array([robot.to_natural(q) for q in qs])
    chunk = cdpm.evaluate_poses(robot, natural)
    for i in range(len(qs)):
        alone = cdpm.evaluate_poses(robot, natural[i : i + 1])
        for name in ("poc", "output_controllable", "positive_controllable", "status", "n_taut"):
            assert alone[name][0] == chunk[name][i], (name, i)


def test_given_tension_and_methods_share_the_statics_rule(paper_robot):
    """check_equilibrium and the methods judge 'holds' by one tolerance."""
    q = paper_robot.poses["nominal"]
    assert cdpm.check_equilibrium(paper_robot, q, np.zeros(4)).feasible
    res = cdpm.check_equilibrium(paper_robot, q, np.full(4, 1e-3))
    assert not res.feasible and "do not hold the pose" in res.message


def test_unknown_method_names_the_registry(paper_robot):
    with pytest.raises(cdpm.InputError, match="use one of zero, min_norm, pretension"):
        cdpm.evaluate_poses(paper_robot, np.zeros((1, 2)), "least")
