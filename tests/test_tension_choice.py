"""Choosing the equilibrium tension: the feasible tensions (tension_range),
the search for a POC tension (best_tension), its map criteria and its
command line.

The hand-worked model, tests/data/tension_choice/one_joint.yaml: one
revolute joint about z, a link of 1 m along x with a 1 kg point-like mass
at the tip (izz = 0.001 kg m^2, so I = 1.001 kg m^2 about the joint), no
gravity, pose q1 = 0 (tip at (1, 0, 0)); output the tip's y = sin q1.

- c1 runs from (2, 0, 0) to the tip: l1 = sqrt(5 - 4 cos q1), so
  dl1/dq1 = 2 sin q1 / l1 = 0 at q1 = 0 (its line passes through the
  joint axis: any tension t in it is in equilibrium) and
  d^2 l1/dq1^2 = 2 at q1 = 0: the cable stiffness is 2 t, the torque
  -2 t sin(d) for a rotation d, so K = -2 t / I.
- c2 runs from (1, 1, 0) to the tip: dl2/dq1 = -1, L = [[0], [-1]]; the
  statics L^T f = 0 give f2 = 0 (it pulls the tip along +y alone).

So the feasible tensions are {(t, 0): t >= 0}: c1 in [0, inf), c2 fixed at
0 (must be slack), the null space of L^T is spanned by (1, 0). The
least-norm tension is f = 0: both cables slack, A = [[0, 1], [0, 0]]
nilpotent, B = [[0, 0], [0, 1/I]], C = [1, 0], so CB = 0 and CAB = (0, 1/I):
one input direction, NO. With t > 0, A = [[0, 1], [-2t/I, 0]] has
eigenvalues +-i sqrt(2t/I) and the single pull-only input c2 drives y both
ways (an oscillatory mode with a nonzero modal input row: Brammer), YES. The
pretension method is infeasible (c2 cannot carry a pretension). With the
pull of c2 within [0, F] and the impulse response y = sin(w s)/(w I),
w = sqrt(2 t / I), the reach margin at horizon T with pi <= w T <= 2 pi
is r_T = F (1 + cos(w T)) / (w^2 I).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from cdpm.dynamics.equilibrium import InfeasibleEquilibriumError
from cdpm.errors import InputError
from cdpm.text import (
    best_tension_json,
    best_tension_text,
    tension_range_json,
    tension_range_text,
)
from cdpm.verdicts import NO, NOT_ANALYSED, YES
from tests.conftest import MODELS

ONE_JOINT = Path(__file__).parent / "data" / "tension_choice" / "one_joint.yaml"
VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
SPATIAL = MODELS / "spatial_8cable" / "spatial_8cable.yaml"
#: two_link_vertical: no tension within the bounds holds this pose
NOWHERE = [-0.5, -1.0]
INERTIA = 1.001  # kg m^2 about the joint: 1 kg at 1 m plus izz


@pytest.fixture(scope="module")
def one_joint():
    return cdpm.load_robot(ONE_JOINT)


# ---------------------------------------------------------------- tension_range


def test_tension_range_of_the_hand_model(one_joint):
    r = cdpm.tension_range(one_joint, "straight")
    assert r.feasible and r.rank == 1
    np.testing.assert_allclose(r.least, [0.0, 0.0], atol=1e-12)
    assert r.greatest[0] == np.inf and r.greatest[1] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(np.abs(r.null_space), [[1.0], [0.0]], atol=1e-12)
    np.testing.assert_array_equal(r.can_be_slack, [True, True])
    np.testing.assert_array_equal(r.must_be_slack, [False, True])
    np.testing.assert_array_equal(r.can_be_taut, [True, False])
    # cap: 10 reach budgets of F = 1 kg * 1 m/s^2; the interior point is
    # the middle of c1's capped range [0, 10]
    assert r.tension_cap == pytest.approx(10.0)
    np.testing.assert_allclose(r.interior, [5.0, 0.0], atol=1e-9)
    assert r.interior_slack == pytest.approx(5.0)
    assert r.cable_states() == ["slack or taut", "must be slack"]
    text = tension_range_text(r)
    assert "c2" in text and "must be slack" in text and "capped at 10 N" in text
    assert str(r) == (
        "Feasible equilibrium tensions: rank L^T = 1, 1 internal-force direction(s); "
        "can be slack: c1, c2; must be slack: c2"
    )
    data = json.loads(json.dumps(tension_range_json(r), allow_nan=False))  # strict JSON
    assert data["cables"][0]["greatest"] is None and data["cables"][0]["tension_max"] is None
    assert data["null_space_dimension"] == 1


def test_tension_range_of_the_spatial_robot_against_hand_values():
    """IPAnema 1 at its centre: 25 kg hung from four upper cables (the
    lower ones slack) needs W / (4 s) in each, s the vertical component
    of a unit upper cable, (1.94, 1.44, 1) / |.|; with an upper cable at
    its 720 N maximum the lower one below it carries 720 - W / (4 s)."""
    robot = cdpm.load_robot(SPATIAL)
    r = cdpm.tension_range(robot, "centre")
    s = 1.0 / math.sqrt(1.94**2 + 1.44**2 + 1.0)
    hold = 25 * 9.81 / (4 * s)  # 160.3 N
    upper, lower = slice(0, 4), slice(4, 8)
    assert r.feasible and r.rank == 6 and r.null_space.shape == (8, 2)
    np.testing.assert_allclose(r.least[upper], hold, rtol=1e-7)
    np.testing.assert_allclose(r.greatest[upper], 720.0, rtol=1e-9)
    np.testing.assert_allclose(r.least[lower], 0.0, atol=1e-7)
    np.testing.assert_allclose(r.greatest[lower], 720.0 - hold, rtol=1e-7)
    np.testing.assert_array_equal(r.can_be_slack, [False] * 4 + [True] * 4)
    assert not r.must_be_slack.any() and r.can_be_taut.all()
    # the interior point keeps every cable half its range from the bounds
    assert r.interior_slack == pytest.approx((720.0 - hold) / 2, rel=1e-6)
    L = robot.cable_jacobian(robot.configuration("centre"))
    np.testing.assert_allclose(L.T @ r.null_space, 0.0, atol=1e-12)
    eq = cdpm.check_equilibrium(robot, "centre", r.interior)
    assert eq.feasible


def test_tension_range_at_a_pose_without_equilibrium():
    robot = cdpm.load_robot(VERTICAL)
    r = cdpm.tension_range(robot, NOWHERE)
    assert not r.feasible and np.all(np.isnan(r.least))
    assert "none" in str(r) and "none" in tension_range_text(r)
    json.dumps(tension_range_json(r), allow_nan=False)


# ---------------------------------------------------------------- best_tension


def test_min_norm_is_no_and_another_feasible_tension_is_yes(one_joint):
    lin = cdpm.linearise(one_joint, "straight")  # min_norm: f = 0
    np.testing.assert_array_equal(lin.tension, [0.0, 0.0])
    poc = cdpm.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
    )
    assert poc.verdict == cdpm.Verdict.NO
    eq = cdpm.equilibrium_tension(one_joint, "straight", method="pretension", pretension=1.0)
    assert not eq.feasible  # c2 cannot carry a pretension

    best = cdpm.best_tension(one_joint, "straight")
    assert best.poc_possible == YES and bool(best)
    assert best.default_verdict == NO and best.default_method == "min_norm"
    t = best.tension[0]
    assert t > 0 and best.tension[1] == 0.0
    # the hand-worked stiffness K = -2 t / I
    assert best.linearisation.stiffness[0, 0] == pytest.approx(-2 * t / INERTIA, rel=1e-9)
    assert 1 <= best.n_yes < best.n_candidates
    # the certificate re-checks with the per-pose API at the returned tension
    lin = cdpm.linearise(one_joint, "straight", tension=best.tension)
    again = cdpm.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
    )
    assert again.verdict == cdpm.Verdict.YES
    assert again.certificate.verify(lin.A, lin.B_cone, lin.C)
    assert best.poc.verdict == cdpm.Verdict.YES
    assert best.poc.certificate.verify(lin.A, lin.B_cone, lin.C)
    text = best_tension_text(best)
    assert text.startswith(tension_range_text(best.tension_range) + "\n")
    assert "YES: this feasible tension makes the pose POC (certified)" in text
    assert "default tension: NO" in text and "a NO means that none of the" in text
    assert str(best).startswith(
        f"Best tension (objective poc): YES, r_T = {best.reach_margin[0]:.4g} m"
    )
    data = json.loads(json.dumps(best_tension_json(best), allow_nan=False))
    assert data["poc_possible"] == "yes" and data["default"]["verdict"] == "no"


@pytest.mark.slow
def test_margin_objective_finds_the_hand_worked_best_margin(one_joint):
    """With T = 2 s the margin r_T = (1 + cos wT) / (w^2 I) (F = 1 N) peaks
    inside pi <= wT <= 2 pi; the refined search comes within 1% of it."""
    T = 2.0
    best = cdpm.best_tension(one_joint, "straight", "margin", horizon=T)
    poc_only = cdpm.best_tension(one_joint, "straight", "poc", horizon=T)
    t = best.tension[0]
    w = math.sqrt(2 * t / INERTIA)
    assert math.pi <= w * T <= 2 * math.pi
    assert best.reach_margin[0] == pytest.approx((1 + math.cos(w * T)) / (w**2 * INERTIA), rel=2e-3)
    ts = np.linspace(math.pi**2 * INERTIA / (2 * T**2), 2 * math.pi**2 * INERTIA / T**2, 2001)
    ws = np.sqrt(2 * ts / INERTIA)
    peak = np.max((1 + np.cos(ws * T)) / (ws**2 * INERTIA))
    assert best.reach_margin[0] >= 0.99 * peak
    assert best.reach_margin[0] >= poc_only.reach_margin[0]
    assert best.n_candidates > poc_only.n_candidates  # the refinement rounds


def test_best_tension_is_the_batch_on_one_pose():
    robot = cdpm.load_robot(VERTICAL)
    poses = np.array([[0.3, 0.4], [-1.2, 0.9], [0.1, -0.6]])
    batch = cdpm.best_tension_batch(robot, poses)
    for k, x in enumerate(poses):
        one = cdpm.best_tension(robot, x)
        assert one.poc_possible == batch.poc_possible[k]
        np.testing.assert_array_equal(one.tension, batch.tension[k])
        assert one.reach_margin[0] == batch.reach_margin[k]
        assert one.default_verdict == batch.default_verdict[k]
        assert one.poc.verdict.value == {YES: "yes", NO: "no"}.get(int(batch.poc_possible[k]))


def test_best_tension_bad_input_names_the_fix(one_joint):
    with pytest.raises(InputError, match=r"objective must be one of 'poc', 'margin'"):
        cdpm.best_tension(one_joint, "straight", objective="x")
    # a cap of 1e12 N beside tens of newtons: HiGHS stopped with its status
    # unknown at 1e-9 N of tolerance (the round-off of 1e12 is 1e-4)
    vertical = cdpm.load_robot(VERTICAL)
    capped = cdpm.best_tension(vertical, "nominal", tension_cap=1e12)
    assert capped.poc_possible == 1
    assert cdpm.check_equilibrium(vertical, "nominal", capped.tension).feasible
    with pytest.raises(InputError, match="tension_cap must be a positive"):
        cdpm.best_tension(one_joint, "straight", tension_cap=-1)
    with pytest.raises(InputError, match="random_points must be an integer"):
        cdpm.best_tension(one_joint, "straight", random_points=1.5)
    robot = cdpm.load_robot(VERTICAL)
    with pytest.raises(InfeasibleEquilibriumError, match="To fix: try another pose"):
        cdpm.best_tension(robot, NOWHERE)


# ---------------------------------------------------------------- maps


def _assert_map_matches_best_tension(robot, ds, axes):
    names = list(axes)
    grid = np.meshgrid(*[np.asarray(axes[n]) for n in names], indexing="ij")
    base = robot.to_natural(next(iter(robot.poses.values())))
    for index in np.ndindex(grid[0].shape):
        x = base.copy()
        for name, g in zip(names, grid, strict=True):
            x[robot.coordinate_names.index(name)] = g[index]
        sel = {n: ds[n].values[i] for n, i in zip(names, index, strict=True)}
        here = ds.sel(sel)
        try:
            best = cdpm.best_tension(robot, x)
        except InfeasibleEquilibriumError:
            assert int(here["poc_some_tension"]) == NOT_ANALYSED
            assert np.all(np.isnan(here["tension_best"].values))
            continue
        assert int(here["poc_some_tension"]) == best.poc_possible
        np.testing.assert_array_equal(here["tension_best"].values, best.tension)
        assert float(here["reach_margin_best"]) == best.reach_margin[0]
        assert int(here["poc"]) == best.default_verdict


@pytest.mark.slow
def test_map_with_tension_best_equals_best_tension_per_pose(one_joint):
    axes = {"q1": np.linspace(-0.4, 0.4, 5)}
    ds = cdpm.workspace_map(one_joint, axes, tension="best", workers=1)
    assert ds["tension_best"].dims == ("q1", "cable")
    assert list(ds["cable"].values) == ["c1", "c2"]
    assert ds["reach_margin_best"].attrs["units"] == "m"
    assert json.loads(ds.attrs["cdpm_settings"])["tension_search"]["objective"] == "poc"
    # q1 = 0: NO at the least-norm tension, YES for some feasible tension
    centre = ds.sel(q1=0.0)
    assert int(centre["poc"]) == NO and int(centre["poc_some_tension"]) == YES
    _assert_map_matches_best_tension(one_joint, ds, axes)


@pytest.mark.slow
def test_map_with_tension_best_under_gravity_equals_best_tension():
    robot = cdpm.load_robot(VERTICAL)
    axes = {"q1": [-0.5, 0.3, 1.0], "q2": [-1.0, 0.4]}
    ds = cdpm.workspace_map(robot, axes, tension="best", workers=1)
    assert (ds["poc_some_tension"] == YES).sum() >= 2
    _assert_map_matches_best_tension(robot, ds, axes)


def test_map_without_tension_best_leaves_its_criteria_empty(one_joint):
    ds = cdpm.workspace_map(one_joint, {"q1": [0.0, 0.2]}, workers=1)
    assert np.all(ds["poc_some_tension"].values == NOT_ANALYSED)
    assert np.all(np.isnan(ds["reach_margin_best"].values))
    assert np.all(np.isnan(ds["tension_best"].values))
    assert "tension_search" not in json.loads(ds.attrs["cdpm_settings"])


def test_resuming_a_tension_best_store_with_other_settings_is_refused(one_joint, tmp_path):
    store = tmp_path / "best.zarr"
    cdpm.workspace_map(one_joint, {"q1": [0.0, 0.2]}, tension="best", workers=1, store=store)
    with pytest.raises(cdpm.StoreSettingsError, match=r"tension search \(tension 'best'\)"):
        cdpm.workspace_map(one_joint, {"q1": [0.0, 0.2]}, workers=1, store=store)
    with pytest.raises(cdpm.StoreSettingsError, match="objective margin"):
        cdpm.workspace_map(
            one_joint,
            {"q1": [0.0, 0.2]},
            tension="best",
            tension_objective="margin",
            workers=1,
            store=store,
        )
    with pytest.raises(InputError, match="tension_objective='margin' applies to the tension"):
        cdpm.workspace_map(one_joint, {"q1": [0.0]}, tension_objective="margin", workers=1)


# ---------------------------------------------------------------- command line


def test_cli_analyze_tension_best_text(capsys):
    assert main(["analyze", str(ONE_JOINT), "--pose", "straight", "--tension", "best"]) == 0
    out, _ = capsys.readouterr()
    head, _, search = out.partition("Feasible equilibrium tensions")
    assert "Positive output controllability (Theorem 1): NO" in head  # the default
    assert "must be slack" in search
    assert "Best tension (objective poc): YES" in search
    assert "default tension: NO" in search and "tension [N]: c1 = 5, c2 = 0" in search


def test_cli_analyze_tension_best_json(capsys):
    argv = ["analyze", str(ONE_JOINT), "--pose", "straight", "--tension", "best"]
    assert main([*argv, "--objective", "margin", "--horizon", "2", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    best = data["best_tension"]
    assert data["positive_output_controllability"]["verdict"] == "no"
    assert best["poc_possible"] == "yes" and best["objective"] == "margin"
    assert best["tension"]["c1"] > 0 and best["tension"]["c2"] == 0
    assert best["reach_margin"] > 0.2
    assert best["tension_range"]["cables"][1]["must_be_slack"] is True


def test_cli_tension_best_errors_name_the_fix(capsys, tmp_path):
    spec = str(ONE_JOINT)
    assert main(["analyze", spec, "--pose", "straight", "--tension", "best", "1"]) == 1
    assert "give --tension best alone" in capsys.readouterr().err
    assert main(["analyze", spec, "--pose", "straight", "--objective", "margin"]) == 1
    assert "add --tension best" in capsys.readouterr().err
    assert main(["verify", spec, "--pose", "straight", "--tension", "best"]) == 1
    assert "is an option of cdpm analyze and cdpm map" in capsys.readouterr().err
    out = str(tmp_path / "lin.npz")
    assert main(["analyze", spec, "--pose", "straight", "--tension", "best", "-o", out]) == 1
    assert "--format npz writes one linearisation" in capsys.readouterr().err
    # a pose without any equilibrium: the report, the reason, exit status 3
    argv = ["analyze", str(VERTICAL), "--q", *map(str, NOWHERE), "--tension", "best"]
    assert main(argv) == 3
    out, err = capsys.readouterr()
    assert "Tension search: none" in out and "no tension to choose" in err


def test_cli_map_tension_best(capsys, tmp_path):
    store = tmp_path / "m.zarr"
    argv = ["map", str(ONE_JOINT), "--axis", "q1=-0.2:0.2:3", "--tension", "best"]
    assert main([*argv, "--out", str(store), "--workers", "1", "--quiet"]) == 0
    out, _ = capsys.readouterr()
    assert "positive output controllable for some feasible tension (tension search): yes" in out
    ds = cdpm.open_map(store)
    np.testing.assert_array_equal(ds["poc_some_tension"].values, [NO, YES, YES])
