"""The POC neighbourhood of a pose (cdpm/regions/neighbourhood.py): the radii on a
local refined map, checked against the per-pose analysis."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import cdpm
from cdpm.errors import InputError
from cdpm.regions.neighbourhood import Neighbourhood, poc_neighbourhood
from cdpm.text import neighbourhood_json, neighbourhood_lines, neighbourhood_text
from cdpm.verdicts import NO, NOT_ANALYSED, STATUS_CODES, YES
from tests.conftest import MODELS

TWO_CABLES = MODELS / "two_link_two_cables" / "two_link_two_cables.yaml"
VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
SPATIAL = MODELS / "spatial_8cable" / "spatial_8cable.yaml"


@pytest.fixture(scope="module")
def two_cables():
    return cdpm.load_robot(TWO_CABLES)


@pytest.fixture(scope="module")
def nominal(paper_robot) -> Neighbourhood:
    """The paper's nominal pose (pi/6, pi/3), box half-width 1 rad, default grid."""
    return poc_neighbourhood(paper_robot, "nominal", 1.0)


def _poc(robot, natural) -> cdpm.Verdict:
    """POC verdict of the per-pose analysis (linearise + Theorem 1)."""
    return cdpm.analyze_pose(robot, np.asarray(natural, dtype=float)).poc.verdict


def test_paper_nominal_pose_lies_in_a_ball_of_poc_poses(nominal, paper_robot):
    nb = nominal
    np.testing.assert_allclose(nb.natural, [math.pi / 6, math.pi / 3])
    assert nb.verdict == YES and nb.pose_name == "nominal"
    assert (nb.points, nb.n_poses, nb.axis_rays) == (101, 101**2, 0)
    np.testing.assert_allclose(nb.step, [0.02, 0.02])
    # the radius stops at a suspect edge on the 0.18 rad shell (a diagonal NO
    # line passes between its ends: resampled, r_T falls to 2e-4 m along it),
    # far before the first NO grid pose at 0.94. The edge from 0.16 to 0.18
    # that stopped it before resampling is cleared: r_T falls monotonically
    # along it, to 9e-4 m at its far end
    assert nb.box_bracket == pytest.approx((0.16, 0.18), abs=1e-12)
    near, far = nb.nearest_suspect
    assert (near.distance_box, far.distance_box) == pytest.approx((0.18, 0.18), abs=1e-12)
    assert near.verdict == far.verdict == YES and 0 < far.margin < near.margin < 0.02
    least = nb.suspect_least
    assert least.verdict == YES and 0 < least.margin < 0.1 * far.margin
    assert nb.suspect_cleared > 0 and nb.refined_poses > 0
    assert not nb.whole_box_yes and nb.suspect_edges > 0
    assert nb.nearest.verdict == NO and nb.nearest.distance_box == pytest.approx(0.94)
    np.testing.assert_allclose(nb.nearest.natural, [1.4636, 1.6072], atol=1e-4)
    # the NO line is 0.234 rad away in the 2-norm (0.1745 in the inf-norm)
    assert nb.ball_bracket == pytest.approx((math.hypot(0.2, 0.1), math.hypot(0.22, 0.1)))
    assert nb.counts["yes"] + nb.counts["no"] == nb.n_poses and nb.counts["no"] > 0
    assert neighbourhood_lines(nb)[0] == (
        "POC neighbourhood: radius 0.16 rad (box, inf-norm) on a 101x101 grid of half-width 1 "
        "rad: every sampled pose within it is YES and r_T stays clear of 0 between neighbouring "
        "samples"
    )
    assert (
        "r_T falls to 0.000217 m, still within one step's change of 0, between the sampled "
        "poses at 0.18 and 0.18 (inf-norm), where a NO set thinner than the grid may pass (an "
        "estimate from r_T's sampled slopes, not a proof)" in neighbourhood_lines(nb)[1]
    )


def test_paper_radius_agrees_with_the_per_pose_analysis(nominal, paper_robot):
    nb = nominal
    assert _poc(paper_robot, nb.nearest.natural) == cdpm.Verdict.NO
    r = nb.box_radius
    corners = nb.natural + r * np.array([[1, 1], [1, -1], [-1, 1], [-1, -1], [1, 0], [0, -1]])
    rng = np.random.default_rng(7)
    inside = nb.natural + rng.uniform(-r, r, size=(6, 2))  # off the grid
    for pose in np.vstack([corners, inside]):
        assert _poc(paper_robot, pose) == cdpm.Verdict.YES, pose


#: a NO pose of the paper's arm on a diagonal NO line (c1 and c3 change sign
#: together there), 0.178 rad (inf-norm) from the nominal pose
THIN_NO = np.array([0.22 * math.pi, 0.39 * math.pi])


def test_a_no_line_between_grid_poses_stops_the_radius(paper_robot):
    assert _poc(paper_robot, THIN_NO) == cdpm.Verdict.NO
    distance = float(np.abs(THIN_NO - [math.pi / 6, math.pi / 3]).max())
    radii = {}
    for R in (0.5, 1.0, "pi/6"):
        nb = poc_neighbourhood(paper_robot, "nominal", R)
        assert not nb.whole_box_yes, R  # the 0.5 grid misses the line's poses
        assert nb.box_radius < distance, R
        radii[R] = (nb.box_radius, float(nb.step.max()))
    # the three boxes agree on the radius up to their grid steps
    values = [r for r, _ in radii.values()]
    assert max(values) - min(values) <= max(h for _, h in radii.values()) + 1e-12
    assert radii[0.5][0] == pytest.approx(0.17) and radii["pi/6"][0] == pytest.approx(
        0.1676, abs=1e-4
    )


def test_whole_box_yes_gives_at_least_r(paper_robot):
    nb = poc_neighbourhood(paper_robot, "nominal", 0.1, points=21)
    assert nb.whole_box_yes and nb.nearest is None and nb.nearest_suspect is None
    assert nb.box_bracket == (0.1, None) and nb.ball_bracket == (0.1, None)
    assert nb.counts == {"yes": 441, "no": 0, "marginal": 0, "not_analysed": 0}
    assert nb.suspect_edges == 0
    assert "the whole box, so the radius is at least 0.1 rad" in neighbourhood_lines(nb)[0]
    # print and a notebook cell show a summary; neighbourhood_text the report's lines
    assert str(nb).splitlines()[0] == (
        "POC neighbourhood of pose 'nominal' (two_link_planar.yaml): radius at least 0.1 rad "
        "(box, inf-norm), at least 0.1 rad (ball, 2-norm)"
    )
    assert nb._repr_html_().startswith("<pre>POC neighbourhood of pose &#x27;nominal&#x27;")


def test_growing_the_box_beyond_the_region_keeps_the_radius(paper_robot):
    # the same grid step (0.04 rad) in a box of half-width 1.2 and 2 rad
    small = poc_neighbourhood(paper_robot, "nominal", 1.2, points=61)
    large = poc_neighbourhood(paper_robot, "nominal", 2.0, points=101)
    assert small.box_bracket == pytest.approx(large.box_bracket, abs=1e-12)
    assert small.box_bracket == pytest.approx((0.16, 0.2), abs=1e-12)  # the line: 0.1745
    np.testing.assert_allclose(small.nearest.natural, large.nearest.natural, atol=1e-12)
    for a, b in zip(small.nearest_suspect, large.nearest_suspect, strict=True):
        np.testing.assert_allclose(a.natural, b.natural, atol=1e-12)
    assert small.ball_bracket == pytest.approx(large.ball_bracket, abs=1e-12)


def test_refining_narrows_the_bracket(paper_robot):
    fine = poc_neighbourhood(paper_robot, "nominal", 1.0, points=201)
    # the NO line's nearest pose is 0.1745 rad away (inf-norm), within the bracket
    assert fine.box_bracket == pytest.approx((0.17, 0.18), abs=1e-12)


def test_pose_at_the_edge_of_a_region_has_a_small_radius(two_cables):
    # at q1 = 0 the two-cable arm is YES for q2 in about (-pi/2, -0.684)
    nb = poc_neighbourhood(two_cables, [0.0, -0.70], 0.2)
    assert nb.verdict == YES
    # r_T nearly 0 on the last YES poses: the radius stops a step before them
    # (a grid of step 1e-4 finds the first NO pose 0.013 away)
    assert nb.box_bracket == pytest.approx((0.012, 0.016), abs=1e-12)
    assert nb.nearest.distance_box == pytest.approx(0.016, abs=1e-12)
    assert nb.nearest.verdict == NO
    assert _poc(two_cables, nb.nearest.natural) == cdpm.Verdict.NO
    assert _poc(two_cables, nb.natural + [0.012, 0.012]) == cdpm.Verdict.YES


def test_no_pose_has_radius_zero(two_cables):
    nb = poc_neighbourhood(two_cables, "nominal", 0.2)
    assert nb.verdict == NO and nb.n_poses == 1
    assert nb.box_bracket == (0.0, 0.0) and nb.ball_bracket == (0.0, 0.0)
    assert nb.box_radius == nb.ball_radius == 0.0
    np.testing.assert_allclose(nb.nearest.natural, nb.natural)
    assert neighbourhood_lines(nb) == [
        "POC neighbourhood: radius 0: the pose itself is NO (no neighbourhood evaluated)"
    ]
    plain = json.loads(json.dumps(neighbourhood_json(nb)))
    assert plain["box_radius"] == 0 and plain["verdict"] == "no"
    assert str(nb) == (
        "POC neighbourhood of pose 'nominal' (two_link_two_cables.yaml): radius 0 (the pose "
        "itself is NO)"
    )


def test_six_dof_model_with_default_points(tmp_path):
    nb = poc_neighbourhood(SPATIAL, "centre", 0.2)
    # 3^6 grid, 12 axis and 64 corner rays of 10 points, corners shared
    assert (nb.points, nb.axis_rays, nb.corner_rays, nb.ray_points) == (3, 12, 64, 10)
    assert nb.n_poses == 3**6 + (12 + 64) * 10 - (12 + 64)
    assert nb.verdict == YES and nb.unit == "m or rad"
    assert nb.box_bracket == pytest.approx((0.1, 0.12), abs=1e-12)
    near = nb.nearest
    assert near.verdict == NOT_ANALYSED and near.status == STATUS_CODES["no_equilibrium"]
    assert near.describe() == "not analysed (no equilibrium)"
    robot = cdpm.load_robot(SPATIAL)
    assert not cdpm.equilibrium_tension(robot, near.natural).feasible
    assert cdpm.equilibrium_tension(robot, nb.natural + 0.1 * np.sign(near.offset)).feasible
    path = tmp_path / "nb.json"
    path.write_text(json.dumps(neighbourhood_json(nb)))
    plain = json.loads(path.read_text())
    assert plain["nearest"]["description"] == "not analysed (no equilibrium)"
    assert plain["rays"] == {"axis": 12, "corner": 64}


def test_pretension_reaches_the_pipeline():
    robot = cdpm.load_robot(VERTICAL)
    q = [-2.5, -1.2]
    light = poc_neighbourhood(
        robot, q, 0.1, points=11, rays=False, tension="pretension", pretension=1
    )
    heavy = poc_neighbourhood(
        robot, q, 0.1, points=11, rays=False, tension="pretension", pretension=100
    )
    assert light.whole_box_yes and light.pretension == 1.0
    assert not heavy.whole_box_yes and heavy.box_radius < 0.1
    near = heavy.nearest.natural
    assert not cdpm.equilibrium_tension(robot, near, method="pretension", pretension=100).feasible
    assert cdpm.equilibrium_tension(robot, near, method="pretension", pretension=1).feasible


def test_coordinates_scale_and_rays(paper_robot):
    nb = poc_neighbourhood(paper_robot, "nominal", 1.0, coordinates=["q2"], points=11, rays=False)
    assert nb.coordinates == ("q2",) and nb.n_poses == 11
    # every sampled pose is YES, but r_T falls from 0.15 to 0.03 over the first
    # step and to about 7e-5 at dq2 = 0.262 (a NO line passes). Resampled, the
    # first step clears (r_T falls steeply but stays clear of 0); the second
    # keeps its dip, to 2.4e-4 at dq2 = 0.2625: radius 0.2 (it was 0)
    assert nb.counts["yes"] == 11 and nb.nearest is None and not nb.whole_box_yes
    assert nb.box_bracket == pytest.approx((0.2, 0.4), abs=1e-12)
    assert [p.distance_box for p in nb.nearest_suspect] == pytest.approx([0.2, 0.4])
    assert nb.suspect_least.offset[0] == pytest.approx(0.2625)
    assert neighbourhood_lines(nb)[1] == (
        "  box radius in [0.2, 0.4] rad: it stops there: r_T falls to 0.00024 m, still within "
        "one step's change of 0, between the sampled poses at 0.2 and 0.4 (inf-norm), where a "
        "NO set thinner than the grid may pass (an estimate from r_T's sampled slopes, not a "
        "proof; every sampled pose is YES)"
    )
    scaled = poc_neighbourhood(paper_robot, "nominal", 1.0, scale={"q2": 0.5})
    np.testing.assert_allclose(scaled.step, [0.02, 0.01])
    assert scaled.unit == "scaled units"
    # the q2 offset of the nearest NO pose, divided by its scale, is within the box
    assert abs(scaled.nearest.offset[1]) / 0.5 <= scaled.nearest.distance_box + 1e-12
    rays = poc_neighbourhood(paper_robot, "nominal", 0.3, points=1)
    assert (rays.axis_rays, rays.corner_rays, rays.n_poses) == (4, 4, 1 + 8 * 10)
    assert math.isnan(rays.step[0]) and rays.counts["yes"] == 81
    # the (+1, +1) corner ray crosses the diagonal NO line between 0.15 and 0.18
    assert rays.box_bracket == pytest.approx((0.15, 0.18), abs=1e-12)
    np.testing.assert_allclose(
        rays.nearest_suspect[1].natural - rays.natural, [0.18, 0.18], atol=1e-12
    )


def test_poses_outside_the_joint_limits_are_counted(paper_robot):
    nb = poc_neighbourhood(paper_robot, "nominal", 3.0, points=7, rays=False)
    offsets = np.linspace(-3.0, 3.0, 7)
    q = nb.natural[:, None] + offsets[None, :]
    inside = np.abs(q) <= math.pi
    expected = 49 - np.count_nonzero(inside[0][:, None] & inside[1][None, :])
    assert nb.outside_limits == expected > 0
    assert any("outside the URDF joint limits" in line for line in neighbourhood_lines(nb))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"radius": 0}, "radius must be a positive"),
        ({"radius": -0.1}, "radius must be a positive"),
        ({"radius": math.nan}, "radius must be a positive"),
        ({"radius": math.inf}, "radius must be a positive"),
        ({"radius": "wide"}, "radius must be a number"),
        ({"radius": None}, "radius must be a number"),
        ({"radius": True}, "radius must be a number"),
        ({"radius": [0.1]}, "radius must be a number"),
        ({"points": 4}, "points must be odd"),
        ({"points": 0}, "points must be odd"),
        ({"points": 2.5}, "points must be an odd integer"),
        ({"points": True}, "points must be an odd integer"),
        ({"points": 1001}, "1,002,001 poses"),
        ({"points": 1, "rays": False}, "leave rays on"),
        ({"coordinates": ["q3"]}, "unknown coordinates 'q3'; coordinates: q1, q2"),
        ({"coordinates": []}, "distinct coordinates"),
        ({"coordinates": ["q1", "q1"]}, "distinct coordinates"),
        ({"scale": {"q3": 1.0}}, "not a varied coordinate"),
        ({"scale": {"q1": 0}}, "scale of 'q1' must be a positive"),
        ({"scale": [1, 1]}, "scale must be a mapping"),
        ({"tension": "taut"}, "unknown equilibrium method"),
        ({"tension": "min_norm", "pretension": -1}, "pretension must be finite, >= 0"),
        ({"tol": 2}, "tol must be an angle"),
    ],
)
def test_bad_inputs_raise_input_error(paper_robot, kwargs, match):
    args = {"radius": 0.1, **kwargs}
    with pytest.raises(InputError, match=match):
        poc_neighbourhood(paper_robot, "nominal", **args)


def test_bad_pose_raises_input_error(paper_robot):
    with pytest.raises(InputError, match="pose 'folded' not in spec"):
        poc_neighbourhood(paper_robot, "folded", 0.1)
    with pytest.raises(InputError, match="expected nq=2"):
        poc_neighbourhood(paper_robot, [0.1, 0.2, 0.3], 0.1)


def test_radius_as_expression(paper_robot):
    nb = poc_neighbourhood(paper_robot, [math.pi / 6, math.pi / 3], "pi/8", points=5)
    assert nb.radius == pytest.approx(math.pi / 8)
    assert nb.pose_name is None and neighbourhood_json(nb)["pose"] is None
    # the axis rays (step pi/80) refine the grid steps along the axes through q
    assert nb.box_bracket == pytest.approx((4 * math.pi / 80, 5 * math.pi / 80), abs=1e-12)


def test_pose_name_and_reach_settings_reach_the_result(paper_robot):
    q = paper_robot.configuration("nominal")
    nb = poc_neighbourhood(
        paper_robot, q, 0.1, points=5, rays=False, pose_name="nominal", horizon=0.5
    )
    plain = json.loads(json.dumps(neighbourhood_json(nb)))
    assert plain["pose"] == "nominal" and nb.pose_name == "nominal"
    assert plain["reach"]["horizon"] == 0.5 and nb.reach.horizon == 0.5
    assert plain["suspect_lipschitz_safety"] >= 2


def test_radius_zero_reads_as_such():
    # held by one cable, the gravity arm's nominal pose has no equilibrium a step away
    nb = poc_neighbourhood(VERTICAL, "nominal", 0.3)
    assert nb.verdict == YES and nb.box_radius == 0.0
    assert neighbourhood_lines(nb)[0].startswith(
        "POC neighbourhood: radius 0 on a 63x63 grid of half-width 0.3 rad: the pose is YES, "
        "but the nearest non-YES sampled pose is not analysed (no equilibrium) at 0.00968"
    )
    assert "within 0 rad" not in neighbourhood_text(nb)
