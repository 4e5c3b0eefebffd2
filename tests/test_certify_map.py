"""Certified maps (cdpm.certify.map.certify_map): cells subdivided until
proven, volume fractions, certified regions joined through shared faces,
and agreement with the per-pose analyser inside every decided box."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.certify.map import certify_map
from cdpm.verdicts import MARGINAL, NO, YES
from tests.conftest import MODELS, PAPER_SPEC


@pytest.fixture(scope="module")
def planar():
    return cdpm.load_robot(PAPER_SPEC)


@pytest.fixture(scope="module")
def small(planar):
    axes = {"q1": [0.45, 0.5, 0.55], "q2": [1.0, 1.05, 1.1]}
    return certify_map(planar, axes, min_fraction=0.25)


def test_cells_near_the_nominal_pose_are_proven_and_agree(planar, small):
    f = small.fractions()
    assert f["yes"] + f["no"] + f["undecided"] == pytest.approx(1.0)
    assert f["yes"] > 0.9
    # the boxes tile the four cells
    assert small.volumes.sum() == pytest.approx(0.1 * 0.1)
    assert small.verify(planar)
    rng = np.random.default_rng(0)
    for lo, hi, v in zip(small.lower, small.upper, small.verdict, strict=True):
        if v == MARGINAL:
            continue
        qs = rng.uniform(lo, hi, (20, 2))
        assert np.all(np.asarray(cdpm.evaluate_poses(planar, qs)["poc"]) == v)
    labels = small.regions()
    assert labels.max() == 1 and np.all((labels > 0) == (small.verdict == YES))
    assert "certified map over q1, q2" in str(small)


def test_regions_join_across_a_full_turn(planar):
    """Boxes at the two ends of a full-turn axis share the face at +-pi;
    on an axis that does not wrap they do not."""
    from cdpm.certify.map import face_pairs

    lo = np.array([[-np.pi, 0.0], [1.0, 0.0], [-1.0, 0.5]])
    hi = np.array([[-1.0, 1.0], [np.pi, 1.0], [1.0, 0.6]])
    a, b = face_pairs(lo, hi, (True, False))[:2]
    pairs = {tuple(sorted(x)) for x in zip(a.tolist(), b.tolist(), strict=True)}
    assert (0, 1) in pairs and (0, 2) in pairs and (1, 2) in pairs
    a, b = face_pairs(lo, hi, (False, False))[:2]
    pairs = {tuple(sorted(x)) for x in zip(a.tolist(), b.tolist(), strict=True)}
    assert (0, 1) not in pairs and (0, 2) in pairs
    m = certify_map(planar, {"q1": np.linspace(-np.pi, np.pi, 3)}, base=[0.0, 1.0])
    assert m.wraps == (True,)


def test_one_output_two_cables_has_proven_no_volume():
    robot = cdpm.load_robot(MODELS / "two_link_two_cables" / "two_link_two_cables.yaml")
    m = certify_map(robot, {"q1": [0.4, 0.6], "q2": [0.9, 1.1]}, min_fraction=0.25)
    assert m.fractions()["no"] > 0.5 and m.verify(robot)
    assert np.all(m.regions()[m.verdict == NO] == 0)


def test_a_loaded_robot_is_certified_where_its_taut_set_is_constant():
    robot = cdpm.load_robot(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
    m = certify_map(robot, {"q1": [0.7, 0.8, 0.9], "q2": [-1.5, -1.4, -1.3]}, min_fraction=0.25)
    assert m.fractions()["yes"] > 0.5 and m.verify(robot)
    assert np.all(m.verdict != NO)  # loaded boxes prove YES only


def test_a_robot_in_neither_case_is_undecided_at_once_with_the_reason(tmp_path):
    from tests.conftest import neither_case_spec

    robot = cdpm.load_robot(neither_case_spec(tmp_path))
    m = certify_map(robot, {"q1": [0.0, 0.5, 1.0], "q2": [0.0, 1.0]})
    assert m.verdict.tolist() == [MARGINAL, MARGINAL]
    assert all("loaded boxes cannot be certified" in c.reason for c in m.certificates)


@pytest.mark.parametrize(
    ("axes", "match"),
    [
        ({"q9": [0, 1]}, r"unknown coordinate 'q9'"),
        ({"q1": [1.0, 0.5]}, r"increasing"),
        ({"q1": [0.5]}, r"at least two"),
        ({}, r"axes must map"),
    ],
)
def test_bad_axes_are_clear_errors(planar, axes, match):
    with pytest.raises(cdpm.InputError, match=match):
        certify_map(planar, axes)


def test_unverified_names_the_boxes_whose_proof_fails(planar, small):
    """A map whose one YES box was widened (its proof no longer covers it)
    fails verify, and unverified names that box only."""
    import dataclasses

    assert small.unverified(planar).size == 0
    k = int(np.flatnonzero(small.verdict == YES)[0])
    upper = small.boxes.upper.copy()
    upper[k] += 0.3
    broken = dataclasses.replace(small, boxes=dataclasses.replace(small.boxes, upper=upper))
    assert not broken.verify(planar)
    assert broken.unverified(planar).tolist() == [k]
