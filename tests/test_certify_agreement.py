"""Certified boxes against the per-pose analyser: many random poses inside
every proven box of certified maps, on the shipped zero-load models and on
randomised variants of the paper arm (anchors, outputs, several cables per
link), must get the box's verdict from :func:`cdpm.evaluate_poses`, and a
YES box's margin bound must lie below every sampled pose's reach margin."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.certify.box import certify_boxes
from cdpm.verdicts import MARGINAL, NO, YES
from tests.conftest import MODELS, paper_spec_copy, paper_spec_text


def _disagreements(robot, boxes, samples: int, seed: int = 0) -> tuple[int, int, int]:
    """(poses checked, verdict disagreements, margin-bound violations) over
    every decided box of ``boxes`` (a CertifiedBoxes): ``samples`` random
    poses per box and its two corners, all analysed in one batch."""
    rng = np.random.default_rng(seed)
    decided = np.flatnonzero(boxes.verdict != MARGINAL)
    if decided.size == 0:
        return 0, 0, 0
    lo, hi = boxes.lower[decided], boxes.upper[decided]
    u = rng.uniform(size=(decided.size, samples, lo.shape[1]))
    qs = lo[:, None] + u * (hi - lo)[:, None]
    qs = np.concatenate([qs, lo[:, None], hi[:, None]], axis=1)  # (D, samples + 2, nv)
    got = cdpm.evaluate_poses(robot, qs.reshape(-1, lo.shape[1]))
    poc = np.asarray(got["poc"]).reshape(decided.size, -1)
    expect = boxes.verdict[decided][:, None]
    wrong = int(np.sum(poc != expect))
    top = np.asarray(got["reach_margin"]) + np.asarray(got["reach_margin_error"])
    top = top.reshape(decided.size, -1)
    yes = boxes.verdict[decided] == YES
    bound = boxes.margin_lower[decided][yes][:, None]
    violations = int(np.sum(~(top[yes] >= bound)))
    return int(qs.shape[0] * qs.shape[1]), wrong, violations


@pytest.mark.parametrize("name", ["two_link_planar", "two_link_two_cables"])
def test_every_box_of_a_certified_patch_agrees_with_the_analyser(name):
    robot = cdpm.load_robot(MODELS / name / f"{name}.yaml")
    edges = np.linspace(0.2, 1.8, 9)
    cmap = cdpm.certify_map(robot, {"q1": edges, "q2": edges}, min_fraction=0.125)
    f = cmap.fractions()
    assert f["yes"] + f["no"] > 0.5, f
    checked, wrong, violations = _disagreements(robot, cmap.boxes, samples=12)
    assert checked > 2000
    assert wrong == 0 and violations == 0
    assert cmap.verify(robot)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["two_link_planar", "two_link_two_cables"])
def test_every_box_of_a_certified_torus_agrees_with_the_analyser(name):
    robot = cdpm.load_robot(MODELS / name / f"{name}.yaml")
    edges = np.linspace(-np.pi, np.pi, 31)
    cmap = cdpm.certify_map(robot, {"q1": edges, "q2": edges}, min_fraction=0.125)
    f = cmap.fractions()
    assert f["undecided"] < 0.25, f
    checked, wrong, violations = _disagreements(robot, cmap.boxes, samples=10)
    assert checked > 50000
    assert wrong == 0 and violations == 0
    assert cmap.verify(robot)


def _random_variant(tmp_path, rng, k: int):
    """The paper arm with random anchors, one or two tip outputs and 3 to 6
    cables (each on link1 or link2), at zero load."""
    text = paper_spec_text()
    head, _, rest = text.partition("cables:\n")
    _, _, tail = rest.partition("outputs:\n")
    cables = []
    for i in range(int(rng.integers(3, 7))):
        base = rng.uniform(-1.5, 1.5, 2)
        link = "link1" if rng.uniform() < 0.5 else "link2"
        at = rng.uniform([-0.4, -0.2], [0.4, 0.2])
        cables.append(
            f"  - name: c{i + 1}\n    route:\n"
            f"      - {{frame: base, point: [{base[0]:.3f}, {base[1]:.3f}, 0]}}\n"
            f"      - {{frame: {link}, point: [{at[0]:.3f}, {at[1]:.3f}, 0], relative_to: com}}\n"
        )
    outputs = "  - {name: tip_x, frame: tip, component: x}\n"
    if rng.uniform() < 0.5:
        outputs += "  - {name: tip_y, frame: tip, component: y}\n"
    poses = tail[tail.index("poses:") :]
    spec = head + "cables:\n" + "".join(cables) + "outputs:\n" + outputs + poses
    folder = tmp_path / f"v{k}"
    folder.mkdir()
    return cdpm.load_robot(paper_spec_copy(folder, spec))


@pytest.mark.parametrize("seed", range(6))
def test_random_variants_agree_box_by_box(tmp_path, seed):
    rng = np.random.default_rng(100 + seed)
    robot = _random_variant(tmp_path, rng, seed)
    centres = rng.uniform(-3.0, 3.0, (300, 2))
    half = rng.choice([0.002, 0.01, 0.03], (300, 1))
    boxes = certify_boxes(robot, centres - half, centres + half)
    checked, wrong, violations = _disagreements(robot, boxes, samples=15, seed=seed)
    assert wrong == 0 and violations == 0, (seed, wrong, violations)
    assert np.all(boxes.verify(robot)[boxes.verdict != MARGINAL])
    # the variants are not all undecided: something is proven on most
    counts = {v: int(np.sum(boxes.verdict == v)) for v in (YES, NO, MARGINAL)}
    assert counts[YES] + counts[NO] > 0, counts
