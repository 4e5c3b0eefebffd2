"""The largest box around a pose proven POC
(cdpm.regions.neighbourhood.certified_neighbourhood) and its report in
`cdpm analyze --neighbourhood`."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import cdpm
from cdpm.certify.box import certify_box
from cdpm.cli import main
from cdpm.errors import InputError
from cdpm.regions.neighbourhood import certified_neighbourhood
from cdpm.text.regions import certified_neighbourhood_json, certified_neighbourhood_lines
from cdpm.verdicts import MARGINAL, YES
from tests.conftest import MODELS, PAPER_SPEC

VERTICAL_SPEC = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
NOMINAL = np.array([math.pi / 6, math.pi / 3])
#: the paper arm's NO line q1 + q2 ... nearest the nominal pose is 0.1745 rad
#: away in the inf-norm (docs/maps.md): no box reaches past it
NO_LINE_DISTANCE = 0.1745


def test_the_certified_box_at_the_paper_pose_is_proven_and_stops_before_the_no_line(
    paper_robot,
):
    box = certified_neighbourhood(paper_robot, "nominal", 0.5)
    assert box.proven and box.verdict == YES and box.pose_name == "nominal"
    assert 0.1 < box.half_width < NO_LINE_DISTANCE
    assert box.half_width < box.unproven <= 0.5
    np.testing.assert_allclose(box.lower, NOMINAL - box.half_width)
    np.testing.assert_allclose(box.upper, NOMINAL + box.half_width)
    assert box.margin_lower > 0 and not box.clipped
    # the per-pose analyser agrees at a grid over the box, corners included
    axes = [np.linspace(a, b, 9) for a, b in zip(box.lower, box.upper, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)
    result = cdpm.evaluate_poses(paper_robot, grid)
    assert np.all(result["poc"] == YES)
    assert np.min(result["reach_margin"]) >= box.margin_lower
    lines = certified_neighbourhood_lines(box)
    assert lines[0].startswith(
        f"Certified POC box (q +- h over q1, q2, h <= 0.5): half-width h = {box.half_width:.4g}"
    )
    data = certified_neighbourhood_json(box)
    assert data["proven"] and data["half_width"] == box.half_width
    assert data["lower"] == pytest.approx({"q1": box.lower[0], "q2": box.lower[1]})


def test_a_small_radius_is_proven_whole(paper_robot):
    box = certified_neighbourhood(paper_robot, NOMINAL, "pi/100")
    assert box.half_width == pytest.approx(math.pi / 100) and box.unproven is None
    # the proof: the box itself, or the pieces of its bisection, each proven
    if box.reason.startswith("proven POC YES on each of"):
        assert certify_box(paper_robot, box.lower, box.upper).verdict != YES
    else:
        assert certify_box(paper_robot, box.lower, box.upper).verdict == YES


def test_a_loaded_robot_says_why_no_box_is_proven():
    """At the vertical arm's nominal pose the taut set changes (fewer taut
    cables than joints there): no box around it is proven, and why."""
    box = certified_neighbourhood(VERTICAL_SPEC, "nominal", 0.3)
    assert not box.proven and box.half_width == 0 and box.verdict == MARGINAL
    assert "active set" in box.reason or "taut" in box.reason or "bound" in box.reason
    assert certified_neighbourhood_lines(box) == [
        f"Certified POC box (q +- h over q1, q2, h <= 0.3): none proven: {box.reason}"
    ]
    assert certified_neighbourhood_json(box)["margin_lower"] is None


def test_a_loaded_robot_gets_a_box_where_its_taut_set_is_constant():
    box = certified_neighbourhood(VERTICAL_SPEC, [0.82177012, -1.38127972], 0.3)
    assert box.proven and box.half_width > 0.05 and box.margin_lower == 0.0


def test_a_joint_certified_boxes_do_not_support_is_the_reason(tmp_path):
    urdf = (MODELS / "two_link_planar" / "two_link_planar.urdf").read_text()
    (tmp_path / "two_link_planar.urdf").write_text(
        urdf.replace('type="revolute"', 'type="continuous"', 1)
    )
    spec = (MODELS / "two_link_planar" / "two_link_planar.yaml").read_text()
    (tmp_path / "arm.yaml").write_text(spec)
    box = certified_neighbourhood(tmp_path / "arm.yaml", "nominal", 0.05)
    assert not box.proven and "joint 'q1' (RUBZ) is not supported by certified boxes" in box.reason


def test_bad_radius_is_an_input_error(paper_robot):
    with pytest.raises(InputError, match="radius must be a positive finite number"):
        certified_neighbourhood(paper_robot, "nominal", -1)


def test_analyze_reports_the_certified_box(capsys):
    argv = ["analyze", str(PAPER_SPEC), "--pose", "nominal", "--neighbourhood", "0.05"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert (
        "Certified POC box (q +- h over q1, q2, h <= 0.05): half-width h = 0.05 (all of R), "
        "proven POC YES at every pose of it; r_T >= " in out
    )
    assert main([*argv, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    certified = data["certified_neighbourhood"]
    assert certified["proven"] and certified["half_width"] == pytest.approx(0.05)
    assert certified["margin_lower"] > 0 and certified["unproven"] is None


def test_analyze_on_a_loaded_robot_says_the_box_is_not_proven(capsys):
    argv = ["analyze", str(VERTICAL_SPEC), "--pose", "nominal", "--neighbourhood", "0.1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "Certified POC box (q +- h over q1, q2, h <= 0.1): none proven: " in out
