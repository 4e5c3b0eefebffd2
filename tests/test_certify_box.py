"""Certified boxes (cdpm.certify.box.certify_box): a YES or NO proven on a
whole box of poses must agree with the per-pose analyser at every pose
sampled in it, its reach-margin bound must hold there, its certificate must
re-check from the model, and a corrupted certificate must not."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import cdpm
from cdpm.certify.box import certify_box, inverse_enclosure
from cdpm.certify.interval import Interval
from cdpm.verdicts import MARGINAL, NO, YES
from tests.conftest import MODELS


def _robot(name: str):
    return cdpm.load_robot(MODELS / name / f"{name}.yaml")


@pytest.fixture(scope="module")
def planar():
    return _robot("two_link_planar")


@pytest.fixture(scope="module")
def two_cables():
    return _robot("two_link_two_cables")


@pytest.fixture(scope="module")
def planar_xy(tmp_path_factory):
    """The paper arm with both tip coordinates as outputs (p = 2)."""
    text = (MODELS / "two_link_planar" / "two_link_planar.yaml").read_text()
    urdf = (MODELS / "two_link_planar" / "two_link_planar.urdf").resolve()
    text = text.replace("urdf: two_link_planar.urdf", f"urdf: {urdf}")
    text = text.replace(
        "  - {name: tip_x, frame: tip, component: x}",
        "  - {name: tip_x, frame: tip, component: x}\n  - {name: tip_y, frame: tip, component: y}",
    )
    path = tmp_path_factory.mktemp("xy") / "planar_xy.yaml"
    path.write_text(text)
    return cdpm.load_robot(path)


def _boxes(seed: int, n: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        c = rng.uniform(-3.0, 3.0, 2)
        h = rng.choice([0.002, 0.01, 0.02])
        yield c - h, c + h


def _check_against_poses(robot, certs, samples: int = 60, seed: int = 0) -> dict[int, int]:
    """Sample poses inside every decided box (corners included) and compare
    with the per-pose analyser; returns the count of each verdict."""
    rng = np.random.default_rng(seed)
    counts = {YES: 0, NO: 0, MARGINAL: 0}
    for cert in certs:
        counts[cert.verdict] += 1
        if cert.verdict == MARGINAL:
            continue
        lo, hi = cert.lower, cert.upper
        qs = np.vstack([rng.uniform(lo, hi, (samples, lo.size)), lo, hi])
        got = cdpm.evaluate_poses(robot, qs)
        poc = np.asarray(got["poc"])
        assert np.all(poc == cert.verdict), (str(cert), np.unique(poc, return_counts=True))
        if cert.verdict == YES:
            # the true r_T lies in [value, value + error]; the bound is below it
            top = np.asarray(got["reach_margin"]) + np.asarray(got["reach_margin_error"])
            assert cert.margin_lower > 0 and np.all(top >= cert.margin_lower), str(cert)
        assert cert.verify(robot)
    return counts


def test_paper_arm_boxes_agree_with_every_sampled_pose(planar):
    certs = [certify_box(planar, lo, hi) for lo, hi in _boxes(1, 40)]
    counts = _check_against_poses(planar, certs)
    assert counts[YES] >= 25  # the paper arm is YES almost everywhere


def test_two_outputs_boxes_agree_with_every_sampled_pose(planar_xy):
    certs = [certify_box(planar_xy, lo, hi) for lo, hi in _boxes(4, 40)]
    counts = _check_against_poses(planar_xy, certs)
    assert counts[YES] >= 5 and max(c.faces.size for c in certs) >= 4


def test_one_output_two_cables_proves_yes_and_no_boxes(two_cables):
    certs = [certify_box(two_cables, lo, hi) for lo, hi in _boxes(2, 40)]
    counts = _check_against_poses(two_cables, certs)
    assert counts[YES] >= 5 and counts[NO] >= 5


def test_a_box_across_a_no_line_is_not_yes(planar):
    # q = (0.70719, 1.2172) lies on a NO line of the paper arm (bisection)
    q = np.array([0.707192653542, 1.2172])
    cert = certify_box(planar, q - 0.005, q + 0.005)
    assert cert.verdict != YES
    assert cert.verify(planar) == (cert.verdict == NO)


def test_the_nominal_box_is_yes_with_a_margin_bound(planar):
    q = np.array([np.pi / 6, np.pi / 3])
    cert = certify_box(planar, q - 0.01, q + 0.01)
    assert cert.verdict == YES and cert.verify(planar)
    r = cdpm.analyze_pose(planar, "nominal").reach_margin
    assert 0.5 * r[0] < cert.margin_lower <= r[0] + r[1]
    assert "certified YES" in str(cert) and "m within T" in str(cert)


def test_corrupted_certificates_are_rejected(planar_xy, two_cables):
    robot = planar_xy
    yes = next(c for lo, hi in _boxes(6, 80) if (c := certify_box(robot, lo, hi)).verdict == YES)
    assert yes.verify(robot) and yes.faces.size >= 4
    broken = [
        dataclasses.replace(
            yes, faces=yes.faces[1:], patches=yes.patches[1:], columns=yes.columns[1:]
        ),
        dataclasses.replace(yes, margin_lower=yes.margin_lower * 1.5),
        dataclasses.replace(yes, upper=yes.upper + 0.5),  # a wider box than proven
        dataclasses.replace(yes, patches=yes.patches * 0.5),  # patches that miss directions
        dataclasses.replace(yes, faces=(yes.faces + 1) % 4),  # patches on the wrong faces
        dataclasses.replace(yes, verdict=MARGINAL),
    ]
    for cert in broken:
        assert not cert.verify(robot)
    # a proving cable swapped for one that does not prove its patch
    wrong = []
    for j in range(robot.n_cables):
        columns = yes.columns.copy()
        columns[0] = j
        wrong.append(dataclasses.replace(yes, columns=columns).verify(robot))
    assert wrong[yes.columns[0]] and not all(wrong)
    no = next(c for lo, hi in _boxes(3, 60) if (c := certify_box(two_cables, lo, hi)).verdict == NO)
    assert no.verify(two_cables)
    assert not dataclasses.replace(no, separator=-no.separator).verify(two_cables)
    assert not dataclasses.replace(no, separator=np.zeros(1)).verify(two_cables)


def test_under_load_a_box_with_a_constant_taut_set_is_proven_and_verified():
    robot = _robot("two_link_vertical")
    cert = certify_box(robot, [0.81177, -1.39128], [0.83177, -1.37128])
    assert cert.verdict == YES and "constant active set" in cert.reason
    assert cert.margin_lower == 0.0 and cert.verify(robot)
    rng = np.random.default_rng(3)
    qs = np.vstack([rng.uniform(cert.lower, cert.upper, (200, 2)), cert.lower, cert.upper])
    assert np.all(np.asarray(cdpm.evaluate_poses(robot, qs)["poc"]) == YES)
    assert not dataclasses.replace(cert, upper=cert.upper + 0.5).verify(robot)
    assert not dataclasses.replace(cert, margin_lower=0.1).verify(robot)


def test_a_robot_in_neither_case_is_undecided_with_the_reason(tmp_path):
    from tests.conftest import neither_case_spec

    robot = cdpm.load_robot(neither_case_spec(tmp_path))
    cert = certify_box(robot, [0.5, 1.0], [0.51, 1.01])
    assert cert.verdict == MARGINAL and "under load" in cert.reason
    assert "loaded boxes cannot be certified" in cert.reason and "'zero'" in cert.reason
    assert not cert.verify(robot)


@pytest.mark.parametrize(
    ("lower", "upper", "match"),
    [
        ([0.2, 0.0], [0.1, 0.1], r"lower > upper for q1"),
        ([0.0, 0.0], [0.1], r"2 lower and 2 upper"),
        ([3.0, 0.0], [3.5, 0.1], r"leaves the joint limits of q1"),
        ([0.0, np.nan], [0.1, 0.1], r"finite"),
    ],
)
def test_bad_boxes_are_clear_errors(planar, lower, upper, match):
    with pytest.raises(cdpm.InputError, match=match):
        certify_box(planar, lower, upper)


def test_a_free_flyer_platform_under_load_is_certified_in_small_boxes():
    """spatial_8cable (a 6-DOF platform under gravity, a pretension): boxes
    of its position proven YES agree with the analyser at every pose tried."""
    from cdpm.certify.box import certify_boxes

    robot = _robot("spatial_8cable")
    q0 = np.asarray(robot.to_natural(robot.poses["centre"]), dtype=float)
    rng = np.random.default_rng(0)
    c = q0 + np.concatenate([rng.uniform(-0.3, 0.3, (30, 3)), np.zeros((30, 3))], axis=1)
    lo, hi = c.copy(), c.copy()
    lo[:, :3] -= 0.005
    hi[:, :3] += 0.005
    boxes = certify_boxes(robot, lo, hi)
    yes = np.flatnonzero(boxes.verdict == YES)
    assert yes.size > 10
    assert np.all(boxes.verify(robot)[yes])
    qs = np.concatenate([rng.uniform(lo[k], hi[k], (15, 6)) for k in yes])
    assert np.all(np.asarray(cdpm.evaluate_poses(robot, qs)["poc"]) == YES)


def test_inverse_enclosure_holds_every_inverse():
    rng = np.random.default_rng(5)
    for _ in range(50):
        A = rng.normal(size=(3, 3))
        M0 = A @ A.T + 3 * np.eye(3)
        w = rng.uniform(0, 0.05, (3, 3))
        w = w + w.T
        M = Interval(M0 - w, M0 + w)
        inv = inverse_enclosure(M)
        assert isinstance(inv, Interval)
        for _ in range(50):
            t = rng.uniform(-1, 1, (3, 3))
            sample = M0 + w * (t + t.T) / 2
            assert np.all(inv.contains(np.linalg.inv(sample)))
    assert isinstance(inverse_enclosure(Interval(np.zeros((2, 2)), np.eye(2))), str)


def test_a_box_where_the_output_jacobian_loses_rank_is_undecided_with_the_reason(planar):
    """At q = (0, 0) the tip's x coordinate is stationary (C_q = 0): no box
    around it is proven, and the reason names the rank drop."""
    cert = certify_box(planar, [-0.01, -0.01], [0.01, 0.01])
    assert cert.verdict == MARGINAL and "C_q may lose rank" in cert.reason
    # away from it the reason is the general one
    far = certify_box(planar, [0.5, 1.0], [0.51, 1.01])
    assert far.verdict == YES and "lose rank" not in far.reason


def test_the_batched_certifier_is_the_single_one_box_by_box(planar_xy):
    """certify_box is certify_boxes on a batch of one: the same verdicts,
    bounds and proofs whatever the batch."""
    from cdpm.certify.box import certify_boxes

    rng = np.random.default_rng(11)
    c = rng.uniform(-3.0, 3.0, (40, 2))
    h = rng.choice([0.002, 0.01, 0.02], (40, 1))
    batch = certify_boxes(planar_xy, c - h, c + h)
    for k in range(40):
        one = certify_box(planar_xy, c[k] - h[k], c[k] + h[k])
        got = batch.certificate(k)
        assert one.verdict == got.verdict and one.reason == got.reason
        assert np.array_equal(one.faces, got.faces) and np.array_equal(one.columns, got.columns)
        assert one.margin_lower == got.margin_lower or (
            np.isnan(one.margin_lower) and np.isnan(got.margin_lower)
        )
    assert np.all(batch.verify(planar_xy) == np.isin(batch.verdict, (YES, NO)))
