"""POC certified on boxes of loaded robots (cdpm.certify.loaded): a YES box
never holds a pose the per-pose analyser calls anything but YES (random
poses and corners of many small boxes, gravity arms and a pretensioned
copy); some boxes do get YES; boxes across a change of the taut set, or
around poses the analysis leaves undecided, stay MARGINAL; the proof is
re-checked by recomputation and fails on a wider box; the generalised
gravity's enclosure holds the robot's value.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.certify import box_kinematics
from cdpm.certify.jet import mean_value
from cdpm.certify.kinematics import box_jets
from cdpm.certify.loaded import certify_loaded, loaded_reason, verify_loaded
from cdpm.dynamics.equilibrium import equilibrium_tensions, statics
from cdpm.errors import InputError
from cdpm.verdicts import MARGINAL, YES
from tests.scaled_models import scaled_copy

MODELS = Path(__file__).resolve().parents[1] / "models"
VERTICAL = MODELS / "two_link_vertical"
ARM = MODELS / "multilink_arm"


@pytest.fixture(scope="module")
def vertical():
    return cdpm.load_robot(VERTICAL)


@pytest.fixture(scope="module")
def arm():
    return cdpm.load_robot(ARM)


@pytest.fixture(scope="module")
def pretensioned(tmp_path_factory):
    """two_link_vertical with the pretension method (10 N): cables held at
    the pretension are free inputs (above f_min = 0)."""
    folder = tmp_path_factory.mktemp("pretensioned")
    spec = scaled_copy(
        VERTICAL / "two_link_vertical.yaml",
        VERTICAL / "two_link_vertical.urdf",
        folder,
        1.0,
        1.0,
        equilibrium={"method": "pretension", "pretension": 10.0},
    )
    return cdpm.load_robot(spec)


def corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 2^nv corners of the box [lo, hi]."""
    picks = np.array(list(itertools.product([0.0, 1.0], repeat=lo.size)))
    return lo + picks * (hi - lo)


def disagreements(robot, lo, hi, verdict, rng, n_inside=50) -> tuple[int, int]:
    """(poses checked, poses not YES) over every YES box: n_inside random
    poses and the corners of each, through cdpm.evaluate_poses."""
    qs = [
        np.vstack([rng.uniform(lo[b], hi[b], (n_inside, robot.nv)), corners(lo[b], hi[b])])
        for b in np.flatnonzero(verdict == YES)
    ]
    if not qs:
        return 0, 0
    qs = np.vstack(qs)
    poc = cdpm.evaluate_poses(robot, qs, margin=False)["poc"]
    return qs.shape[0], int(np.count_nonzero(poc != YES))


def boxes_around(centres: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return centres - half, centres + half


def test_the_loaded_models_are_in_scope(vertical, arm, pretensioned):
    for robot in (vertical, arm, pretensioned):
        assert loaded_reason(robot) == ""


def test_a_method_without_a_least_norm_tension_is_out_of_scope(tmp_path):
    spec = scaled_copy(
        VERTICAL / "two_link_vertical.yaml",
        VERTICAL / "two_link_vertical.urdf",
        tmp_path,
        1.0,
        1.0,
        equilibrium={"method": "zero"},
    )
    robot = cdpm.load_robot(spec)
    assert "'zero'" in loaded_reason(robot)
    with pytest.raises(InputError, match="cannot be certified"):
        certify_loaded(robot, np.zeros((1, 2)), np.full((1, 2), 0.01))
    assert not verify_loaded(robot, np.zeros((1, 2)), np.full((1, 2), 0.01)).any()


@pytest.mark.parametrize("name", ["vertical", "pretensioned"])
def test_yes_boxes_of_the_vertical_arm_hold_only_yes_poses(request, name):
    robot = request.getfixturevalue(name)
    rng = np.random.default_rng(11 if name == "vertical" else 12)
    centres = rng.uniform(-3.1, 3.1, (200, 2))
    half = rng.uniform(0.002, 0.02, (200, 1))
    lo, hi = boxes_around(centres, half)
    verdict, reason, margin = certify_loaded(robot, lo, hi)
    assert set(np.unique(verdict)) <= {YES, MARGINAL}
    yes = verdict == YES
    assert yes.mean() > 0.2, yes.mean()  # measured: about 0.5 (0.4 pretensioned)
    checked, wrong = disagreements(robot, lo, hi, verdict, rng)
    assert checked >= 50 * yes.sum() and wrong == 0
    assert np.all(margin[yes] == 0.0) and np.all(np.isnan(margin[~yes]))
    assert all("reach margin bound not computed" in r for r in reason[yes])
    assert all(r for r in reason)


def test_yes_boxes_of_the_spatial_arm_hold_only_yes_poses(arm):
    rng = np.random.default_rng(13)
    reach = arm.to_natural(arm.poses["reach"])
    centres = reach + rng.uniform(-0.3, 0.3, (60, arm.nv))
    centres[0] = reach
    half = rng.uniform(2e-4, 2e-3, (60, 1))
    lo, hi = boxes_around(centres, half)
    verdict, _, _ = certify_loaded(arm, lo, hi)
    assert verdict[0] == YES  # the spec's named pose 'reach' (7 cables taut)
    assert (verdict == YES).mean() > 0.1  # measured: about 0.25
    checked, wrong = disagreements(arm, lo, hi, verdict, rng, n_inside=50)
    assert checked > 0 and wrong == 0


def test_boxes_holding_an_undecided_pose_are_marginal(vertical, arm):
    """Boxes around poses the analysis calls anything but YES (no
    equilibrium, a stretched arm, the spec's special poses)."""
    rng = np.random.default_rng(14)
    for robot, spread, halves in ((vertical, None, (0.002, 0.02)), (arm, 0.5, (1e-4, 2e-3))):
        if spread is None:
            qs = rng.uniform(-3.1, 3.1, (800, robot.nv))
        else:
            reach = robot.to_natural(robot.poses["reach"])
            qs = reach + rng.uniform(-spread, spread, (500, robot.nv))
        poc = cdpm.evaluate_poses(robot, qs, margin=False)["poc"]
        bad = qs[poc != YES]
        assert bad.shape[0] > 100
        half = rng.uniform(*halves, (bad.shape[0], 1))
        offset = rng.uniform(-1, 1, bad.shape) * half  # the pose anywhere in its box
        verdict, _, _ = certify_loaded(robot, bad + offset - half, bad + offset + half)
        assert not np.any(verdict == YES)
    # the named poses: one cable holds 'nominal' and 'elbow_up' (fewer free
    # cables than joints), 'horizontal' is stretched (C_q singular), and
    # the arm's 'hanging' pose needs no tension (no free cable)
    for robot, names in ((vertical, ("nominal", "horizontal", "elbow_up")), (arm, ("hanging",))):
        q = np.array([robot.to_natural(robot.poses[n]) for n in names])
        verdict, reason, _ = certify_loaded(robot, q - 0.005, q + 0.005)
        assert np.all(verdict == MARGINAL), reason


def test_a_box_across_a_change_of_the_taut_set_is_marginal(vertical):
    """Along a line of poses the taut cables change (c1 takes over from c3
    near q1 = 0.77 at q2 = 1.5) between two YES poses 1e-4 rad apart; the
    box holding both is MARGINAL for that reason, and boxes on either side
    are YES."""
    q2 = 1.5
    grid = np.linspace(0.72, 0.82, 1001)
    qs = np.stack([grid, np.full_like(grid, q2)], axis=1)
    LT, load = statics(vertical, vertical.kinematics_batch(qs, dynamics=True))
    taut = equilibrium_tensions(vertical, LT, load).taut
    change = np.flatnonzero(np.any(taut[1:] != taut[:-1], axis=1))
    assert change.size == 1, change
    k = int(change[0])
    a, b = grid[k], grid[k + 1]
    assert taut[k].tolist() == [False, True, True, False]
    assert taut[k + 1].tolist() == [True, True, False, False]
    poc = cdpm.evaluate_poses(vertical, [[a, q2], [b, q2]], margin=False)["poc"]
    assert np.all(poc == YES)
    lo = np.array([[a - 1e-4, q2 - 1e-3]])
    hi = np.array([[b + 1e-4, q2 + 1e-3]])
    verdict, reason, _ = certify_loaded(vertical, lo, hi)
    assert verdict[0] == MARGINAL
    assert "active set" in reason[0], reason[0]
    # away from the change the same cables stay taut: YES on either side
    lo = np.array([[a - 0.025, q2 - 0.0025], [b + 0.02, q2 - 0.0025]])
    verdict, reason, _ = certify_loaded(vertical, lo, lo + 0.005)
    assert np.all(verdict == YES), reason


def test_verify_rechecks_the_proof_and_rejects_a_wider_box(vertical):
    rng = np.random.default_rng(15)
    centres = rng.uniform(-3.1, 3.1, (100, 2))
    lo, hi = boxes_around(centres, 0.005)
    verdict, _, _ = certify_loaded(vertical, lo, hi)
    yes = verdict == YES
    assert yes.any()
    assert np.array_equal(verify_loaded(vertical, lo, hi), yes)
    # widened by 0.3 rad on each side: no proof covers that
    wide_lo, wide_hi = lo[yes] - 0.3, hi[yes] + 0.3
    assert not verify_loaded(vertical, wide_lo, wide_hi).any()


def test_bad_boxes_are_clear_errors(vertical):
    with pytest.raises(InputError, match=r"\(B, 2\)"):
        certify_loaded(vertical, np.zeros(2), np.ones(2))
    with pytest.raises(InputError, match="lower > upper"):
        certify_loaded(vertical, np.ones((1, 2)), np.zeros((1, 2)))
    with pytest.raises(InputError, match="finite"):
        certify_loaded(vertical, np.full((1, 2), np.nan), np.zeros((1, 2)))
    verdict, reason, margin = certify_loaded(vertical, np.zeros((0, 2)), np.zeros((0, 2)))
    assert verdict.shape == reason.shape == margin.shape == (0,)


@pytest.mark.parametrize("form", ["naive", "mean_value"])
@pytest.mark.parametrize("name", ["vertical", "arm"])
def test_the_gravity_enclosure_holds_the_robots_gravity(request, name, form):
    robot = request.getfixturevalue(name)
    rng = np.random.default_rng(16)
    for width in (1e-3, 0.1):
        centre = rng.uniform(-1.2, 1.2, robot.nv)
        bk = box_kinematics(robot, centre - width / 2, centre + width / 2, form=form)
        qs = rng.uniform(centre - width / 2, centre + width / 2, (100, robot.nv))
        gravity = robot.kinematics_batch(qs, dynamics=True).gravity
        assert np.abs(gravity).max() > 1.0  # a load that tells the models apart
        assert bk.gravity.contains(gravity).all()
        assert bk.gravity.width.max() < 50 * width * np.abs(gravity).max()
        # and the jets the loaded proof reads (their own evaluation frame)
        at_centre, over_box, radius = box_jets(
            robot, (centre - width / 2)[None], (centre + width / 2)[None]
        )
        jet = mean_value(at_centre["gravity"], over_box["gravity"], radius)
        assert jet.contains(gravity).all()
        centre_gravity = robot.kinematics_batch(centre[None], dynamics=True).gravity
        assert at_centre["gravity"].contains(centre_gravity).all()


@pytest.mark.slow
def test_coverage_of_the_vertical_arm():
    """A 31 x 31 grid of cells over [-pi, pi]^2, undecided cells bisected
    four times: a fair share of the sampled map's YES area is certified,
    and every map pose inside a certified box is YES."""
    robot = cdpm.load_robot(VERTICAL)
    edges = np.linspace(-np.pi, np.pi, 32)
    a, b = np.meshgrid(edges[:-1], edges[:-1], indexing="ij")
    lo = np.stack([a.ravel(), b.ravel()], 1)
    hi = lo + (edges[1] - edges[0])
    proven_lo, proven_hi = [], []
    for level in range(5):
        verdict, _, _ = certify_loaded(robot, lo, hi)
        yes = verdict == YES
        proven_lo.append(lo[yes])
        proven_hi.append(hi[yes])
        lo, hi = lo[~yes], hi[~yes]
        if level < 4:
            side = np.argmax(hi - lo, axis=1)
            rows = np.arange(lo.shape[0])
            mid = 0.5 * (lo[rows, side] + hi[rows, side])
            hi1, lo2 = hi.copy(), lo.copy()
            hi1[rows, side] = mid
            lo2[rows, side] = mid
            lo, hi = np.vstack([lo, lo2]), np.vstack([hi1, hi])
    P_lo, P_hi = np.vstack(proven_lo), np.vstack(proven_hi)
    fraction = np.prod(P_hi - P_lo, axis=1).sum() / (2 * np.pi) ** 2
    c = (np.arange(124) + 0.5) / 124 * 2 * np.pi - np.pi
    qs = np.stack(np.meshgrid(c, c, indexing="ij"), -1).reshape(-1, 2)
    poc = cdpm.evaluate_poses(robot, qs, margin=False)["poc"]
    sampled = np.mean(poc == YES)
    assert fraction > 0.25 * sampled, (fraction, sampled)  # measured: 0.30
    inside = np.zeros(qs.shape[0], dtype=bool)
    for a_, b_ in zip(P_lo, P_hi, strict=True):
        inside |= np.all((qs >= a_) & (qs <= b_), axis=1)
    assert inside.sum() > 1000 and np.all(poc[inside] == YES)


def test_the_inverse_enclosures_hold_the_inverses(vertical):
    """M^-1 over wide boxes of the vertical arm: the norm bound in the
    centre's scaling proves boxes the entrywise Neumann bound cannot, and
    both hold every sampled M^-1."""
    from cdpm.certify.inverse import inverse_enclosures, inverse_over_box
    from cdpm.certify.loaded import _split

    rng = np.random.default_rng(17)
    centres = rng.uniform(-3, 3, (100, 2))
    half = 0.1
    at_centre, over_box, radius = box_jets(vertical, centres - half, centres + half)
    M_c, M_b, dM = _split("mass_matrix", at_centre, over_box, radius)
    plain, plain_why = inverse_enclosures(M_b)
    scaled, scaled_why = inverse_over_box(M_b, M_c, dM, radius)
    assert np.all(scaled_why == "") and np.any(plain_why != "")
    for b in range(centres.shape[0]):
        qs = rng.uniform(centres[b] - half, centres[b] + half, (50, 2))
        inverses = np.linalg.inv(vertical.kinematics_batch(qs, dynamics=True).mass_matrix)
        assert scaled[b].contains(inverses).all()
        if plain_why[b] == "":
            assert plain[b].contains(inverses).all()
