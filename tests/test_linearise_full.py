"""Full linearisation (gravity, cable stiffness, damping, floating bases)
against central finite differences of Pinocchio's forward dynamics, for every
shipped model at 10 seeded random poses where an equilibrium exists."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import cdpm
from cdpm.dynamics.equilibrium import equilibrium_tension
from tests.conftest import MODELS

linearise = cdpm.linearise

SEED = 20261122
N_POSES = 10
FD_STEP = 1e-6
REL_TOL = 1e-6  # acceptance: analytic A, B within 1e-6 (relative) of central differences
MODEL_SPECS = sorted(MODELS.glob("*/*.yaml"))
#: spread of the random poses around each model's first named pose (tangent space)
SPREAD = 0.6


def _needs_robots_extra(spec) -> bool:
    return "package" in spec.read_text()


@pytest.fixture(scope="module", params=MODEL_SPECS, ids=lambda p: p.parent.name)
def robot(request):
    spec = request.param
    if _needs_robots_extra(spec):
        pytest.importorskip("cmeel", reason="example-robot-data (pip install 'cdpm[robots]')")
    try:
        return cdpm.load_robot(spec)
    except cdpm.SpecError as exc:
        if "not installed" in str(exc):
            pytest.skip(f"model needs an optional package: {exc}")
        raise


def equilibrium_poses(robot, n: int = N_POSES, seed: int = SEED) -> list[np.ndarray]:
    """n configurations near the model's first named pose with a feasible
    min-norm equilibrium (rejection sampling, seeded)."""
    rng = np.random.default_rng(seed)
    centre = next(iter(robot.poses.values())) if robot.poses else robot.neutral()
    poses: list[np.ndarray] = []
    for _ in range(200 * n):
        q = pin.integrate(robot.model, centre, rng.uniform(-SPREAD, SPREAD, robot.nv))
        try:
            if equilibrium_tension(robot, q, method="min_norm").feasible:
                poses.append(q)
        except cdpm.ModelError:
            continue
        if len(poses) == n:
            return poses
    raise AssertionError(f"only {len(poses)} equilibrium poses found near {centre}")


def forward_dynamics(robot, q, v, f):
    """q'' from Pinocchio's ABA with the cables' generalised force, the
    external wrench and the URDF joint damping."""
    data = robot.model.createData()
    tau = -robot.cable_jacobian(q).T @ f - robot.external_wrench - robot.joint_damping * v
    return pin.aba(robot.model, data, q, v, tau)


def fd_state_matrix(robot, q, f) -> np.ndarray:
    nv = robot.nv
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    for k in range(nv):
        e = np.zeros(nv)
        e[k] = FD_STEP
        plus = forward_dynamics(robot, pin.integrate(robot.model, q, e), np.zeros(nv), f)
        minus = forward_dynamics(robot, pin.integrate(robot.model, q, -e), np.zeros(nv), f)
        A[nv:, k] = (plus - minus) / (2 * FD_STEP)
        A[nv:, nv + k] = (forward_dynamics(robot, q, e, f) - forward_dynamics(robot, q, -e, f)) / (
            2 * FD_STEP
        )
    return A


def fd_input_matrix(robot, q, f) -> np.ndarray:
    nv, m = robot.nv, robot.n_cables
    B = np.zeros((2 * nv, m))
    for j in range(m):
        e = np.zeros(m)
        e[j] = FD_STEP
        plus = forward_dynamics(robot, q, np.zeros(nv), f + e)
        minus = forward_dynamics(robot, q, np.zeros(nv), f - e)
        B[nv:, j] = (plus - minus) / (2 * FD_STEP)
    return B


def relative_error(analytic: np.ndarray, numeric: np.ndarray) -> float:
    return float(np.abs(analytic - numeric).max() / max(np.abs(numeric).max(), 1e-300))


def test_every_model_has_poses_and_loads(robot):
    assert robot.poses, "every shipped model names at least one pose"
    assert robot.n_outputs >= 1


def test_A_and_B_match_finite_differences_of_aba(robot):
    worst_a = worst_b = 0.0
    for q in equilibrium_poses(robot):
        lin = linearise(robot, q, tension="min_norm")
        f = lin.tension
        A_fd = fd_state_matrix(robot, q, f)
        B_fd = fd_input_matrix(robot, q, f)
        worst_a = max(worst_a, relative_error(lin.A, A_fd))
        worst_b = max(worst_b, relative_error(lin.B, B_fd))
        # the rest position is an equilibrium: q'' = 0 there (statics)
        acc = forward_dynamics(robot, q, np.zeros(robot.nv), f)
        np.testing.assert_allclose(acc, 0.0, atol=1e-7)
    assert worst_a <= REL_TOL, f"A off by {worst_a:.2e} (relative)"
    assert worst_b <= REL_TOL, f"B off by {worst_b:.2e} (relative)"


def test_A_with_pretension_matches_finite_differences(robot):
    """Nonzero tension in every cable exercises the cable stiffness fully."""
    checked = 0
    for q in equilibrium_poses(robot, n=3, seed=SEED + 1):
        eq = equilibrium_tension(robot, q, method="pretension", pretension=2.0)
        if not eq.feasible:
            continue
        lin = linearise(robot, q, tension=eq.tension)
        assert relative_error(lin.A, fd_state_matrix(robot, q, eq.tension)) <= REL_TOL
        assert not lin.sign_constrained.any()  # every cable taut: all inputs free
        checked += 1
    if checked == 0:
        # only a robot whose cables cannot pull against each other has none
        # (two_link_two_cables: 2 cables, 2 joints, no internal force)
        assert robot.n_cables <= robot.nv, "no pretension equilibrium near the named poses"


def test_cable_stiffness_matches_finite_differences_for_any_tension(robot):
    """d(L^T f)/dq along pin.integrate, for arbitrary (non-equilibrium) f."""
    rng = np.random.default_rng(SEED + 2)
    for q in equilibrium_poses(robot, n=3, seed=SEED + 3):
        f = rng.uniform(0, 10, robot.n_cables)
        H = robot.cable_stiffness(q, f)
        fd = np.zeros_like(H)
        for k in range(robot.nv):
            e = np.zeros(robot.nv)
            e[k] = FD_STEP
            plus = robot.cable_jacobian(pin.integrate(robot.model, q, e)).T @ f
            minus = robot.cable_jacobian(pin.integrate(robot.model, q, -e)).T @ f
            fd[:, k] = (plus - minus) / (2 * FD_STEP)
        assert relative_error(H, fd) <= REL_TOL


def test_cable_jacobian_matches_finite_differences_of_lengths(robot):
    for q in equilibrium_poses(robot):
        fd = np.zeros((robot.n_cables, robot.nv))
        for k in range(robot.nv):
            e = np.zeros(robot.nv)
            e[k] = FD_STEP
            plus = robot.cable_lengths(pin.integrate(robot.model, q, e))
            minus = robot.cable_lengths(pin.integrate(robot.model, q, -e))
            fd[:, k] = (plus - minus) / (2 * FD_STEP)
        np.testing.assert_allclose(robot.cable_jacobian(q), fd, rtol=0, atol=1e-8)


def test_output_matrix_matches_finite_differences(robot):
    for q in equilibrium_poses(robot, n=3):
        lin = linearise(robot, q)
        fd = np.zeros((robot.n_outputs, robot.nv))
        for k in range(robot.nv):
            e = np.zeros(robot.nv)
            e[k] = FD_STEP
            plus = robot.output(pin.integrate(robot.model, q, e))
            minus = robot.output(pin.integrate(robot.model, q, -e))
            fd[:, k] = (plus - minus) / (2 * FD_STEP)
        # rotation rows are angular velocities, not derivatives of the stored
        # rotation vector: tests/test_outputs.py checks them against log3
        rows = [k for k, out in enumerate(robot.spec.outputs) if not out.has_rotation]
        np.testing.assert_allclose(lin.C[rows, : robot.nv], fd[rows], rtol=0, atol=1e-8)
        np.testing.assert_array_equal(lin.C[:, robot.nv :], 0.0)


def test_damping_block_is_minus_Minv_D():
    """The example-robot-data double pendulum has 0.05 N m s/rad joint damping."""
    spec = MODELS / "double_pendulum_cables" / "double_pendulum_cables.yaml"
    try:
        robot = cdpm.load_robot(spec)
    except cdpm.SpecError as exc:
        pytest.skip(f"needs example-robot-data: {exc}")
    np.testing.assert_array_equal(robot.joint_damping, [0.05, 0.05])
    lin = linearise(robot, "leaning")
    expected = -np.linalg.solve(lin.mass_matrix, np.diag([0.05, 0.05]))
    np.testing.assert_allclose(lin.rate_stiffness, expected, rtol=1e-12)
    np.testing.assert_allclose(lin.A[2:, 2:], expected, rtol=1e-12)
    assert not lin.nilpotent
