"""The batched cable stiffness (cdpm.model.robot.CableRobot.cable_stiffness_batch,
compiled kernel in cdpm.model.stiffness_kernel): the segment formula written out
pose by pose, and a pose's result independent of its batch and of the
kinematics' memory layout. Its agreement with finite differences is in
tests/test_linearise_full.py."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.model.poses import configurations
from tests.conftest import MODELS

#: models with several segments per cable (multilink_arm), a floating base
#: (spatial_8cable) and a plain planar arm
NAMES = ("multilink_arm", "spatial_8cable", "two_link_planar")


@pytest.fixture(scope="module", params=NAMES)
def robot(request):
    return cdpm.load_robot(MODELS / request.param / f"{request.param}.yaml")


def random_batch(robot, n: int, seed: int):
    """Kinematics and tensions at n poses within 0.3 of the named poses."""
    rng = np.random.default_rng(seed)
    named = np.array([robot.to_natural(q) for q in robot.poses.values()])
    natural = named[rng.integers(len(named), size=n)] + rng.uniform(-0.3, 0.3, (n, robot.nv))
    kin = robot.kinematics_batch(configurations(robot, natural))
    return kin, rng.uniform(0.0, 50.0, (n, robot.n_cables))


def written_out(robot, kin, tension, n: int) -> np.ndarray:
    """The stiffness of pose n, one segment at a time (the docstring of
    cdpm.model.stiffness_kernel.stiffness_batch)."""
    support = robot._dof_support()
    w = kin.spatial_jacobian[n, 3:]  # (3, nv)
    H = np.zeros((robot.nv, robot.nv))
    for s, (a, b) in enumerate(robot._segment_points):
        f = tension[n, robot._segment_cable[s]]
        u, length = kin.segment_units[n, s], kin.segment_lengths[n, s]
        jd = kin.point_jacobians[n, b] - kin.point_jacobians[n, a]
        H += f * jd.T @ (np.eye(3) - np.outer(u, u)) @ jd / length
        for p, sign in ((b, 1.0), (a, -1.0)):
            first = kin.point_jacobians[n, p].T @ np.cross(u[:, None], w, axis=0)
            mask = robot._point_mask[p][:, None]
            H += sign * f * np.where(support, first, first.T * mask)
    return H


def test_the_batch_is_the_segment_formula(robot):
    kin, tension = random_batch(robot, 40, seed=1)
    H = robot.cable_stiffness_batch(kin, tension)
    assert H.shape == (40, robot.nv, robot.nv)
    for n in range(40):
        expected = written_out(robot, kin, tension, n)
        np.testing.assert_allclose(H[n], expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_a_pose_alone_gives_its_result_in_any_batch(robot):
    """Bit for bit: alone, in batches that end inside a block of the kernel,
    and with the kinematics laid out pose-first (a subset) or pose-last (a
    whole batch's views)."""
    kin, tension = random_batch(robot, 37, seed=2)
    whole = robot.cable_stiffness_batch(kin, tension)
    for n in (0, 7, 8, 9, 36):
        alone = robot.cable_stiffness_batch(kin.take(np.array([n])), tension[n : n + 1])
        assert np.array_equal(alone[0], whole[n])
    for size in (1, 5, 8, 9, 17):
        idx = np.arange(37 - size, 37)
        part = robot.cable_stiffness_batch(kin.take(idx), tension[idx])
        assert np.array_equal(part, whole[idx])
    every_other = np.arange(0, 37, 2)
    part = robot.cable_stiffness_batch(kin.take(every_other), tension[every_other])
    assert np.array_equal(part, whole[every_other])


def test_the_per_pose_stiffness_is_the_batch_of_one(robot):
    kin, tension = random_batch(robot, 3, seed=3)
    # the per-pose API takes q through as_q (unit quaternions)
    kin = robot.kinematics_batch(np.array([robot.as_q(q) for q in kin.qs]))
    whole = robot.cable_stiffness_batch(kin, tension)
    for n in range(3):
        assert np.array_equal(robot.cable_stiffness(kin.qs[n], tension[n]), whole[n])


def test_the_kernels_are_loaded_once_per_process(monkeypatch):
    """load_kernels runs every kernel on tiny inputs the first time only
    (the suite's fixture did): a map calls it before its chunks, and
    later maps of a script pay nothing for it."""
    from cdpm.pipeline import compiled

    assert compiled._LOADED.is_set()
    calls = []
    monkeypatch.setattr(compiled, "_load_kernels", lambda: calls.append(1))
    compiled.load_kernels()
    assert calls == []
    monkeypatch.setattr(compiled, "_LOADED", compiled.threading.Event())  # a new process
    compiled.load_kernels()
    assert calls == [1] and compiled._LOADED.is_set()
