"""Equilibrium tensions: hand-worked cases, exact bounds, statics to 1e-9,
optimality (KKT) of the least-norm tensions, infeasible poses as results."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pinocchio as pin
import pytest

import cdpm
from cdpm.dynamics.equilibrium import (
    EquilibriumResult,
    InfeasibleEquilibriumError,
    check_equilibrium,
    equilibrium_tension,
)
from tests.conftest import MODELS

linearise = cdpm.linearise

G = 9.81
VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
SPATIAL = MODELS / "spatial_8cable" / "spatial_8cable.yaml"
ARM = MODELS / "multilink_arm" / "multilink_arm.yaml"
STATICS_ATOL = 1e-9


@pytest.fixture(scope="module")
def vertical():
    return cdpm.load_robot(VERTICAL)


def assert_kkt(robot, result: EquilibriumResult, lower: np.ndarray) -> None:
    """First-order optimality of min |f|^2 s.t. L^T f = -G - w, lower <= f <= f_max:
    f = L lam + mu with mu >= 0 on cables at their lower bound, mu <= 0 at
    the upper bound and mu = 0 on the others."""
    f = result.tension
    L = robot.cable_jacobian(result.q)
    at_low = f == lower
    at_high = f == robot.tension_max
    free = ~(at_low | at_high)
    lam = np.linalg.lstsq(L[free], f[free], rcond=None)[0]
    mu = f - L @ lam
    scale = max(1.0, float(np.abs(f).max()))
    np.testing.assert_allclose(mu[free], 0.0, atol=1e-8 * scale)
    assert np.all(mu[at_low] >= -1e-8 * scale)
    assert np.all(mu[at_high] <= 1e-8 * scale)


def test_paper_model_default_is_exactly_zero_tension(paper_robot):
    for q in ("nominal", [0.3, -1.2], [2.0, 0.1]):
        eq = equilibrium_tension(paper_robot, q)
        assert eq.method == "min_norm" and eq.feasible
        np.testing.assert_array_equal(eq.tension, 0.0)
        assert eq.residual == 0.0
        assert eq.cable_states() == ["slack"] * 4
    assert equilibrium_tension(paper_robot, "nominal", method="zero").feasible


def test_horizontal_pose_by_hand(vertical):
    # q = (0, 0): links level along x. Table I points: B1 = (0.8, 0.1),
    # B2 = (1.8, 0.1), B3 = (0.8, -0.1), B4 = (1.8, -0.1); anchors (0, +-0.5),
    # (0, +-1.5). Rows of L (u . dB/dq): c1 = (-0.8*0.1 - 0.4*0.8)/sqrt(0.8)
    # = -0.4472 on q1; c2: u = (1.8, -1.4)/sqrt(5.2), dB2/dq1 = (-0.1, 1.8),
    # dB2/dq2 = (-0.1, 0.8) -> (-1.1840, -0.5701); c3, c4 mirror c1, c2.
    # G = g (1.5 + 0.5, 0.5) = (19.62, 4.905). L^T f = -G gives
    # f2 - f4 = 4.905 / 0.5701 = 8.6039 and f1 - f3 = (19.62 - 1.1840 * 8.6039)
    # / 0.4472 = 21.092; the least norm puts f3 = f4 = 0.
    eq = equilibrium_tension(vertical, "horizontal")
    assert eq.feasible
    np.testing.assert_allclose(eq.tension, [21.0921, 8.60394, 0, 0], rtol=0, atol=1e-4)
    assert eq.tension[2] == 0.0 and eq.tension[3] == 0.0  # bounds exactly
    assert eq.residual <= STATICS_ATOL
    assert eq.cable_states() == ["taut", "taut", "slack", "slack"]
    np.testing.assert_array_equal(eq.free, [True, True, False, False])
    # pretension 10 N lifts the mirrored pair equally: (31.09, 18.60, 10, 10)
    pre = equilibrium_tension(vertical, "horizontal", method="pretension", pretension=10)
    np.testing.assert_allclose(pre.tension, [31.0921, 18.60394, 10, 10], rtol=0, atol=1e-4)
    assert pre.tension[2] == 10.0 and pre.tension[3] == 10.0
    assert pre.free.all() and pre.taut.all()


def test_zero_method_under_gravity_is_infeasible_with_the_load_as_residual(vertical):
    eq = equilibrium_tension(vertical, "horizontal", method="zero")
    assert not eq.feasible and not eq
    np.testing.assert_array_equal(eq.tension, 0.0)
    assert eq.residual == pytest.approx(math.hypot(2 * G, 0.5 * G), rel=1e-12)
    assert "unbalanced" in eq.message


def test_pretension_infeasible_at_the_paper_pose(vertical):
    # At (pi/6, pi/3) cables c2 and c4 both turn the elbow the same way
    # (L[1, 1] and L[3, 1] < 0) and gravity puts no torque on it
    # (cos(q1 + q2) = 0), so no f2, f4 >= 10 N balance the elbow.
    L = vertical.cable_jacobian("nominal")
    assert L[1, 1] < 0 and L[3, 1] < 0
    eq = equilibrium_tension(vertical, "nominal", method="pretension", pretension=10)
    assert not eq.feasible
    assert eq.residual > 1.0
    assert np.all(eq.tension >= 10.0)  # closest tension still within the bounds
    with pytest.raises(InfeasibleEquilibriumError, match="no equilibrium at this pose"):
        linearise(vertical, "nominal", tension="pretension", pretension=10)


def test_pretension_above_maximum_is_reported(write_spec):
    spec = write_spec(
        """
        urdf: arm.urdf
        gravity: [0, 0, 0]
        cables:
          - name: a
            tension: [0, 5]
            route: [{frame: world, point: [0, 1, 0]}, {frame: link1, point: [0.5, 0, 0]}]
          - name: b
            route: [{frame: world, point: [0, -1, 0]}, {frame: link1, point: [0.5, 0, 0]}]
          - name: c
            route: [{frame: world, point: [0, 1, 0]}, {frame: link2, point: [0.5, 0, 0]}]
          - name: d
            route: [{frame: world, point: [0, -1, 0]}, {frame: link2, point: [0.5, 0, 0]}]
        outputs: [{frame: tip, component: x}]
        """
    )
    robot = cdpm.load_robot(spec)
    eq = equilibrium_tension(robot, [0.3, 0.4], method="pretension", pretension=8)
    assert not eq.feasible
    assert "exceeds the maximum tension of a" in eq.message


@pytest.mark.parametrize("spec", [VERTICAL, SPATIAL, ARM], ids=lambda p: p.parent.name)
@pytest.mark.parametrize("method", ["min_norm", "pretension"])
def test_statics_bounds_and_optimality_at_random_poses(spec, method):
    robot = cdpm.load_robot(spec)
    rng = np.random.default_rng(7)
    centre = next(iter(robot.poses.values()))
    found = 0
    for _ in range(400):
        q = pin.integrate(robot.model, centre, rng.uniform(-0.5, 0.5, robot.nv))
        eq = equilibrium_tension(robot, q, method=method, pretension=3.0)
        lower = robot.tension_min if method == "min_norm" else np.maximum(robot.tension_min, 3.0)
        if not eq.feasible:
            # infeasible is a result, with the closest tension within the bounds
            assert np.all(eq.tension >= lower) and np.all(eq.tension <= robot.tension_max)
            assert eq.residual > 0
            continue
        L = robot.cable_jacobian(q)
        statics = L.T @ eq.tension + robot.gravity_torque(q) + robot.external_wrench
        assert np.linalg.norm(statics) <= STATICS_ATOL
        assert eq.residual == pytest.approx(np.linalg.norm(statics), abs=1e-12)
        assert np.all(eq.tension >= lower) and np.all(eq.tension <= robot.tension_max)
        # cables reported on a bound sit exactly on it
        np.testing.assert_array_equal(
            eq.tension[eq.at_lower_bound], robot.tension_min[eq.at_lower_bound]
        )
        if method == "pretension":
            assert np.all(eq.tension[eq.tension == lower] == lower[eq.tension == lower])
        assert_kkt(robot, eq, lower)
        found += 1
        if found == 10:
            break
    assert found == 10


def test_check_equilibrium_and_linearise_reject_non_equilibrium(vertical):
    eq = check_equilibrium(vertical, "horizontal", [21.0921, 8.60394, 0, 0])
    assert eq.method == "given" and not eq.feasible  # 4 digits miss statics by ~1e-4
    good = equilibrium_tension(vertical, "horizontal").tension
    assert check_equilibrium(vertical, "horizontal", good).feasible
    with pytest.raises(cdpm.InputError, match=r"not an equilibrium .* residual"):
        linearise(vertical, "horizontal", tension=[1, 2, 3, 4])
    lin = linearise(vertical, "horizontal", tension=good)
    np.testing.assert_array_equal(lin.tension, good)


def test_bad_arguments(vertical):
    with pytest.raises(cdpm.InputError, match="unknown equilibrium method 'least'"):
        equilibrium_tension(vertical, "horizontal", method="least")
    with pytest.raises(cdpm.InputError, match="pretension must be finite, >= 0"):
        equilibrium_tension(vertical, "horizontal", method="pretension", pretension=-1)
    # one pretension for every cable: a list of one is a mistake, not a number
    for given in ([5.0], np.array([5.0])):
        with pytest.raises(cdpm.InputError, match=r"pretension must be a number of newtons"):
            cdpm.maps.override_robot(vertical, pretension=given)
    assert cdpm.maps.override_robot(vertical, pretension=np.float64(5)).spec.pretension == 5.0
    with pytest.raises(cdpm.InputError, match="tension has 3 entries"):
        check_equilibrium(vertical, "horizontal", [1, 2, 3])
    # 1e300 N squared overflowed in the residual (a numpy warning, residual inf)
    huge = [1e300] * 4
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(cdpm.InputError, match=r"finite tensions of at most 1e\+12 N"):
            check_equilibrium(vertical, "horizontal", huge)
        with pytest.raises(cdpm.InputError, match=r"finite tensions of at most 1e\+12 N"):
            linearise(vertical, "horizontal", tension=huge)
        for call in (
            lambda: cdpm.evaluate_poses(vertical, [[0.3, 0.2]], tension=huge),
            lambda: cdpm.workspace_map(vertical, {"q1": [0.3, 0.4]}, tension=huge),
        ):
            with pytest.raises(cdpm.InputError, match=r"4 finite tensions \[N\] of at most 1e\+12"):
                call()
        with pytest.raises(cdpm.InputError, match=r"pretension must be finite, >= 0 and <= 1e\+12"):
            equilibrium_tension(vertical, "horizontal", method="pretension", pretension=1e13)
        with pytest.raises(cdpm.InputError, match=r"tension_cap must be a positive tension of at"):
            cdpm.best_tension(vertical, "horizontal", tension_cap=1e300)
        for tension in ([1e13] * 4, ([0.0, 1.0], [[1e13] * 4]), lambda t, q, v: huge):
            with pytest.raises(cdpm.InputError, match=r"of at most 1e\+12 N"):
                cdpm.simulate(vertical, "horizontal", tension=tension, duration=0.1)


def test_result_presentation(vertical):
    eq = equilibrium_tension(vertical, "horizontal")
    text = str(eq)
    assert "Equilibrium (min_norm): feasible" in text and "c3" in text and "slack" in text
    d = eq.as_dict()
    assert d["feasible"] is True and d["method"] == "min_norm"
    assert [c["state"] for c in d["cables"]] == ["taut", "taut", "slack", "slack"]
    assert "<pre>" in eq._repr_html_()


def test_spec_default_method_and_pretension(vertical):
    # two_link_vertical.yaml: equilibrium: {method: min_norm, pretension: 10}
    assert vertical.spec.equilibrium_method == "min_norm"
    assert vertical.spec.pretension == 10.0
    pre = equilibrium_tension(vertical, "horizontal", method="pretension")
    assert pre.pretension == 10.0 and pre.tension[2] == 10.0


def test_infeasible_error_names_python_arguments_and_plain_reasons(vertical):
    with pytest.raises(InfeasibleEquilibriumError) as info:
        linearise(vertical, "nominal", tension="pretension", pretension=10)
    message = str(info.value)
    assert (
        "no tension within the cable bounds balances the load (proved by an exact solver)"
        in message
    )
    assert "DAQP" not in message and "flag" not in message  # no solver jargon
    assert "try a lower pretension (pretension=N, now 10 N), tension='min_norm'" in message
    assert "--" not in message and "(QP exit flag" not in message
    with pytest.raises(InfeasibleEquilibriumError) as info:
        linearise(vertical, "horizontal", tension="zero")
    assert "let the cables take the load (tension='min_norm')" in str(info.value)
    assert "pretension" not in str(info.value)
    # a command line spells the options its own way
    cli = InfeasibleEquilibriumError(
        info.value.result, method_option="--tension {}", pretension_option="--pretension {}"
    )
    assert "(--tension min_norm)" in str(cli) and cli.result is info.value.result


def test_solver_failures_in_words():
    from cdpm.dynamics.equilibrium.qp import _solver_failure

    assert "reached its iteration limit (status -4; please report" in _solver_failure(-4)
    assert "cycled" in _solver_failure(-2) and "failed (status -9;" in _solver_failure(-9)
    assert all("DAQP" not in _solver_failure(k) for k in (-1, -2, -4, -9))


def test_zero_pretension_warns_that_it_is_min_norm(vertical):
    from cdpm.dynamics.equilibrium import EquilibriumWarning

    with pytest.warns(EquilibriumWarning, match=r"pretension of 0 N is the 'min_norm' method"):
        pre = equilibrium_tension(vertical, "horizontal", method="pretension", pretension=0)
    plain = equilibrium_tension(vertical, "horizontal", method="min_norm")
    np.testing.assert_array_equal(pre.tension, plain.tension)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # other methods do not use the pretension: no warning
        equilibrium_tension(vertical, "horizontal", method="min_norm", pretension=0)
        equilibrium_tension(vertical, "horizontal", method="pretension", pretension=1e-3)
