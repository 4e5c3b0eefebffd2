"""The pose search behind ``cdpm find`` as a library function
(:func:`cdpm.find_poses`, :func:`cdpm.search_box`): known answers on the
shipped gravity arm and free-flying platform, the same poses as the
command, and errors for bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from cdpm.regions.search import DECIMALS, MAX_TRIES, find_poses, search_box
from tests.conftest import MODELS

VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
SPATIAL = MODELS / "spatial_8cable"


@pytest.fixture(scope="module")
def vertical():
    return cdpm.load_robot(VERTICAL)


def test_exported_from_cdpm_and_regions():
    import cdpm.regions

    assert cdpm.find_poses is find_poses is cdpm.regions.find_poses
    assert cdpm.search_box is search_box
    assert {"find_poses", "search_box", "PoseSearch", "SearchBox", "FoundPose"} <= set(cdpm.__all__)


def test_poc_poses_are_yes_ranked_by_reach_margin_and_as_the_command_prints(vertical, capsys):
    search = find_poses(vertical, count=3, tries=300, seed=3)
    assert search.where == "poc" and search.tried == 300 and search.natural.shape == (300, 2)
    # the arm is POC over most of its range; every drawn pose has 4 decimals
    assert 150 < search.poc_yes <= search.statically_feasible <= 300
    assert search.ranked == 200 < search.poc_yes  # rank=200 of the YES poses, drawn at random
    np.testing.assert_array_equal(search.natural, np.round(search.natural, DECIMALS))
    margins = [p.reach_margin for p in search.poses]
    assert len(margins) == 3 and margins == sorted(margins, reverse=True) and margins[-1] > 0.1
    for pose in search.poses:
        np.testing.assert_array_equal(pose.natural, search.natural[pose.index])
        report = cdpm.analyze_pose(vertical, pose.natural)
        assert pose.poc == "yes" and report.poc.verdict.name == "YES"
        assert report.reach_margin[0] == pytest.approx(pose.reach_margin, rel=1e-6)
        assert report.criteria["tension_max"] == pytest.approx(pose.peak_tension, rel=1e-6)
        assert pose.distance is None and not pose.strained
    # the command prints the same search
    argv = ["find", str(VERTICAL), "--count", "3", "--tries", "300", "--seed", "3", "--json"]
    assert main(argv) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["counts"] == {
        "statically_feasible": search.statically_feasible,
        "poc_yes": search.poc_yes,
    }
    assert [p["natural"] for p in printed["poses"]] == [p.natural.tolist() for p in search.poses]
    assert "3 pose(s) of the most reach margin r_T" in str(search)


def test_rank_limits_the_poses_ranked(vertical):
    search = find_poses(vertical, count=2, tries=300, rank=10, seed=3)
    assert search.ranked == 10 < search.poc_yes and len(search.poses) == 2


def test_feasible_poses_near_a_named_pose(vertical):
    box = search_box(vertical, near="nominal", radius=0.2)
    center = vertical.to_natural(vertical.configuration("nominal"))
    assert box.near == "nominal" and box.radius == 0.2
    np.testing.assert_array_equal(box.center, center)
    np.testing.assert_allclose([box.low, box.high], [center - 0.2, center + 0.2])
    search = find_poses(VERTICAL, box, where="feasible", count=4, tries=200)  # a path will do
    np.testing.assert_array_equal(search.natural[0], center)  # the pose itself, first
    peaks = [p.peak_tension for p in search.poses]
    assert len(peaks) == 4 and peaks == sorted(peaks)
    for pose in search.poses:
        assert pose.distance == pytest.approx(np.max(np.abs(pose.natural - center)))
        assert pose.distance <= 0.2 + 1e-12
        eq = cdpm.equilibrium_tension(vertical, pose.natural)
        assert eq.feasible and np.max(eq.tension) == pytest.approx(pose.peak_tension, rel=1e-6)


def test_ranges_narrow_the_box_and_radius_clips_to_them():
    spatial = cdpm.load_robot(SPATIAL)
    box = search_box(spatial, ranges={"platform_joint.z": (0.5, 1.5)})
    np.testing.assert_allclose(box.low[:3], [-2.0, -1.5, 0.5])  # x, y: the anchors' box
    assert "platform_joint.z [0.5, 1.5]" in box.describe()
    box = search_box(spatial, ranges={"platform_joint.z": (0.5, 1.02)}, near="centre", radius=0.05)
    # centre is at z = 1: z clipped to the given range, x unlimited, +-0.05
    np.testing.assert_allclose([box.low[2], box.high[2]], [0.95, 1.02])
    np.testing.assert_allclose([box.low[0], box.high[0]], [-0.05, 0.05])
    fixed = search_box(spatial, ranges={"platform_joint.yaw": (0.3, 0.3)})
    assert "platform_joint.yaw 0.3" in fixed.describe()
    # natural coordinates are kept as given (yaw 4 rad is not turned into 4 - 2 pi)
    box = search_box(spatial, near=[0, 0, 1, 0, 0, 4.0], radius=0.1)
    assert box.center[5] == 4.0 and box.near == "0.0 0.0 1.0 0.0 0.0 4.0"


def test_nothing_found_is_an_empty_result():
    robot = cdpm.maps.override_robot(cdpm.load_robot(VERTICAL), tension_bounds=[(0.0, 1.0)])
    search = find_poses(robot, tries=50)
    assert search.poses == () and search.statically_feasible == 0
    assert "none is POC" in str(search)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"where": "yes"}, r"where must be 'poc' or 'feasible', got 'yes'"),
        ({"count": 0}, r"count 0: give a whole number >= 1"),
        ({"tries": 2.5}, r"tries 2.5: give a whole number >= 1"),
        ({"tries": MAX_TRIES + 1}, r"at most 1,000,000 poses per search"),
        ({"count": 9, "rank": 5}, r"rank 5 is less than count 9"),
        ({"seed": -1}, r"seed -1: give a whole number >= 0"),
        ({"box": "q1"}, r"box must be a SearchBox of this robot"),
        ({"reach": 0.5}, r"reach must be None or a ReachSettings"),
    ],
)
def test_find_poses_input_errors(vertical, kwargs, message):
    with pytest.raises(cdpm.InputError, match=message):
        find_poses(vertical, **kwargs)


def test_a_box_of_another_robot_is_refused(vertical):
    with pytest.raises(cdpm.InputError, match="box must be a SearchBox of this robot"):
        find_poses(vertical, search_box(cdpm.load_robot(SPATIAL)))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"ranges": {"q9": (0, 1)}}, r"ranges: no coordinate 'q9'; coordinates: q1, q2"),
        ({"ranges": {"q1": (1, 0)}}, r"'q1' needs finite low <= high \[rad or m\], got \(1, 0\)"),
        ({"ranges": {"q1": (0, np.inf)}}, r"'q1' needs finite low <= high"),
        ({"ranges": {"q1": 0.5}}, r"'q1' needs \(low, high\)"),
        ({"near": "upright"}, r"pose 'upright' not in spec; poses: nominal"),
        ({"near": [1, 2, 3]}, r"3 entries"),
        ({"near": "nominal", "radius": -1}, r"radius -1: give a finite half-width >= 0"),
        ({"near": "nominal", "radius": "x"}, r"radius 'x': .*give a half-width in rad or m"),
        (
            {"near": [5, 0], "radius": 0.1},
            r"near pose 5.0 0.0: q1 = 5 is more than radius 0.1 outside its range "
            r"\[-3.142, 3.142\]; give a pose within the range or a larger radius",
        ),
    ],
)
def test_search_box_input_errors(vertical, kwargs, message):
    with pytest.raises(cdpm.InputError, match=message):
        search_box(vertical, **kwargs)


def test_the_command_names_its_options_in_new_checks(capsys):
    assert main(["find", str(VERTICAL), "--range", "q1=1:0"]) == 1
    assert "--range 'q1=1:0': LOW 1 is above HIGH 0; give LOW <= HIGH" in capsys.readouterr().err
    assert main(["find", str(VERTICAL), "--seed", "-1"]) == 1
    assert "--seed -1: give a whole number >= 0" in capsys.readouterr().err
