"""``cdpm find``: poses worth analysing, checked pose by pose against the
per-pose analysis, on the shipped gravity arm and on CASPR's CAREX."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from cdpm.model.coordinates import default_ranges
from tests.conftest import MODELS, caspr_models

VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
CASPR, _CASPR_MISSING = caspr_models()


def _find(argv, capsys) -> tuple[int, str, str]:
    code = main(["find", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def _json(argv, capsys) -> dict:
    code, out, err = _find([*argv, "--json"], capsys)
    assert code == 0, err
    return json.loads(out)


def test_find_poc_poses_are_yes_and_ranked_by_reach_margin(capsys):
    result = _json([str(VERTICAL), "--count", "4", "--seed", "3"], capsys)
    robot = cdpm.load_robot(VERTICAL)
    poses = result["poses"]
    assert len(poses) == 4 and result["tried"] == 1000
    assert result["counts"]["poc_yes"] > 100  # the arm is POC over most of its range
    margins = [p["reach_margin"] for p in poses]
    assert margins == sorted(margins, reverse=True) and margins[-1] > 0.1
    for pose in poses:
        assert pose["argv"][0] == "--q" and not pose["strained"]
        report = cdpm.analyze_pose(robot, [float(v) for v in pose["argv"][1:]])
        assert report.poc.verdict.name == "YES"
        assert report.reach_margin[0] == pytest.approx(pose["reach_margin"], rel=1e-6)
        assert report.criteria["tension_max"] == pytest.approx(pose["peak_tension"], rel=1e-6)


def test_find_ranks_near_singular_poses_last(capsys):
    # among these 200 YES poses one needs 3853 N (the budget F is 19.6 N):
    # its linearised reach margin (6.2 m for a 2 m arm) would come first
    result = _json([str(VERTICAL), "--count", "200"], capsys)
    strained = [p["strained"] for p in result["poses"]]
    assert any(strained) and strained == sorted(strained)
    first = strained.index(True)
    worst = result["poses"][first]
    assert worst["peak_tension"] > 10 * result["reach"]["tension_budget"]
    assert worst["reach_margin"] > result["poses"][0]["reach_margin"]
    code, out, _ = _find([str(VERTICAL), "--count", "200"], capsys)
    assert (
        code == 0 and "  * needs more than 10 x F = 196 N of tension: a near-singular pose" in out
    )


def test_find_feasible_near_a_pose_stays_within_the_radius(capsys):
    argv = [str(VERTICAL), "--where", "feasible", "--near", "nominal", "--radius", "0.4"]
    result = _json([*argv, "--count", "6"], capsys)
    robot = cdpm.load_robot(VERTICAL)
    center = robot.to_natural(robot.configuration("nominal"))
    assert result["near"] == "nominal" and result["radius"] == 0.4
    # infeasible areas: some poses of the box are not held, some are
    assert 0 < result["counts"]["statically_feasible"] < result["tried"]
    peaks = [p["peak_tension"] for p in result["poses"]]
    assert len(peaks) == 6 and peaks == sorted(peaks)
    for pose in result["poses"]:
        natural = np.array(pose["natural"])
        assert np.max(np.abs(natural - center)) <= 0.4 + 1e-12
        assert pose["distance"] == pytest.approx(np.max(np.abs(natural - center)))
        eq = cdpm.equilibrium_tension(robot, natural)
        assert eq.feasible and np.max(eq.tension) == pytest.approx(pose["peak_tension"], rel=1e-6)


def test_find_text_is_ready_to_paste(capsys):
    code, out, err = _find([str(VERTICAL), "--near", "0.2", "1", "--count", "2"], capsys)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith(
        "two_link_vertical.yaml: 1000 poses tried, uniform within 0.3 of 0.2 1 "
        "(q1 [-0.1, 0.5], q2 [0.7, 1.3]) (seed 0)"
    )
    assert re.match(
        r"  statically feasible: \d+ \(\d+\.\d%\); positive output controllable", lines[1]
    )
    assert "r_T [m]  POC" in out and "distance  pose" in out
    row = next(line for line in lines if line.startswith("   1 "))
    argv = row[row.index("--q") :].split()
    assert all(len(v.partition(".")[2]) <= 4 for v in argv[1:])
    assert lines[-1] == f"analyse one: cdpm analyze {VERTICAL} {' '.join(argv)}"
    assert main(["analyze", str(VERTICAL), *argv]) == 0
    assert "Positive output controllability (Theorem 1): YES" in capsys.readouterr().out


def test_find_tries_the_near_pose_itself_first(capsys):
    argv = [str(VERTICAL), "--near", "horizontal", "--radius", "0", "--tries", "1"]
    result = _json([*argv, "--where", "feasible"], capsys)
    assert result["poses"][0]["argv"] == ["--pose", "horizontal"]
    assert result["poses"][0]["distance"] == 0


def test_find_none_found_says_how_many_were_tried_and_how_to_widen(capsys):
    argv = [str(VERTICAL), "--tension-bounds", "0:1", "--tries", "200"]
    code, out, err = _find(argv, capsys)
    assert code == 3
    assert "overrides of two_link_vertical.yaml: tension bounds [N] c1 [0, 1]" in out
    assert "statically feasible: 0 (0.0%)" in out
    assert err.startswith(
        "cdpm find: none of the 200 poses tried is positive output controllable (YES) "
        "(none of them statically feasible); widen the search: more poses (--tries 2000)"
    )
    code, out, err = _find([*argv, "--near", "nominal", "--where", "feasible"], capsys)
    assert code == 3
    assert "a larger --radius (now 0.3), no --near (the whole range)" in err
    code, out, _ = _find([*argv, "--json"], capsys)
    assert code == 3 and json.loads(out)["poses"] == []


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--near", "upright"], r"--near upright: pose 'upright' not in spec; poses: nominal"),
        (["--near", "1", "2", "3"], r"--near 1 2 3: .*3 entries"),
        (["--range", "q9=0:1"], r"--range 'q9=0:1': no coordinate 'q9'; coordinates: q1, q2"),
        (["--range", "q1=0:1:3"], r"--range .q1=0:1:3.: give a range NAME=LOW:HIGH"),
        (["--count", "9", "--rank", "5"], r"--rank 5 is less than --count 9"),
        (["--near", "nominal", "--radius", "-1"], r"--radius -1: give a finite half-width >= 0"),
        (["--tries", "0"], r"--tries 0: give a whole number >= 1"),
    ],
)
def test_find_input_errors_name_the_option(argv, message, capsys):
    code, out, err = _find([str(VERTICAL), *argv], capsys)
    assert code == 1 and re.search(message, err), err
    assert out == ""


def test_coordinate_ranges_of_the_shipped_models():
    vertical = cdpm.load_robot(VERTICAL)
    r = default_ranges(vertical)
    low, high, limited = r.low, r.high, r.limited
    np.testing.assert_allclose(low, [-np.pi, -np.pi]) and np.testing.assert_allclose(high, np.pi)
    assert limited.all()
    # a free flyer: x, y, z within the anchors' box, angles a turn (pitch half)
    spatial = cdpm.load_robot(MODELS / "spatial_8cable")
    r = default_ranges(spatial)
    low, high, limited = r.low, r.high, r.limited
    anchors = np.array([c.route[0].point_in_frame for c in spatial.spec.cables])
    np.testing.assert_allclose(low[:3], anchors.min(axis=0))
    np.testing.assert_allclose(high[:3], anchors.max(axis=0))
    np.testing.assert_allclose(low[3:], [-np.pi, -np.pi / 2, -np.pi])
    assert not limited.any()


@pytest.mark.skipif(_CASPR_MISSING is not None, reason=_CASPR_MISSING or "")
def test_find_on_caspr_carex(tmp_path, capsys):
    pytest.importorskip("yourdfpy")
    from cdpm.caspr import CasprWarning, import_caspr

    folder = CASPR / "MCDM" / "CAREX"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasprWarning)
        imported = import_caspr(
            folder / "CAREX_bodies.xml", folder / "CAREX_cables.xml", tmp_path / "CAREX"
        )
    spec = str(imported.spec_path)
    # CAREX's initial pose cannot be held within its cables' bounds ...
    code, _, err = _find([spec, "--near", "initial", "--radius", "0", "--tries", "1"], capsys)
    assert code == 3 and "none of the 1 poses tried" in err
    # ... and about 1 random pose in 50 can: find some near it, and check each
    result = _json([spec, "--near", "initial", "--tries", "400", "--count", "3"], capsys)
    assert 0 < result["counts"]["poc_yes"] < 200
    robot = cdpm.load_robot(spec)
    assert len(result["poses"]) == 3
    for pose in result["poses"]:
        report = cdpm.analyze_pose(robot, pose["natural"])
        assert report.poc.verdict.name == "YES"
        assert report.reach_margin[0] == pytest.approx(pose["reach_margin"], rel=1e-6)
        assert np.all(report.linearisation.equilibrium.tension >= 3 - 1e-9)  # CAREX: [3, 45] N
