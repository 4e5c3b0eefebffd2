"""Paths through certified regions (cdpm.regions.certified.certified_path,
cdpm.poc_path on a CertifiedMap) and `cdpm path` on a certified map store."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from dataclasses import dataclass, field

import numpy as np
import pytest

import cdpm
from cdpm.certify.map import CertifiedMap, certify_map
from cdpm.cli import main
from cdpm.errors import InputError
from cdpm.regions.certified import CertifiedPath, certified_path, locate, segment_cover
from cdpm.regions.paths import NotConnectedError
from cdpm.text.regions import certified_path_json, certified_path_text
from cdpm.verdicts import MARGINAL, NO, YES

NOMINAL = [math.pi / 6, math.pi / 3]
#: the paper arm over a full turn of q1 and a band of q2 around the nominal
#: pose: two certified regions, region 1 wrapping across q1 = +-pi
BAND = {"q1": np.linspace(-math.pi, math.pi, 49), "q2": np.linspace(0.8, 1.4, 5)}


@pytest.fixture(scope="module")
def band(paper_robot):
    return certify_map(paper_robot, BAND, min_fraction=1 / 4, workers=1)


def _points_along(path: CertifiedPath, per_step: int = 7) -> np.ndarray:
    """Points (N, d) along every step, ends included, in box coordinates."""
    t = np.linspace(0.0, 1.0, per_step)[:, None]
    return np.concatenate([a + t * (b - a) for a, b in path.steps])


def _assert_proven_along(robot, cmap, path: CertifiedPath) -> None:
    """Every sampled point of every step lies in a YES box of the path's
    region, its own step's box included, and the per-pose analyser says
    YES there."""
    labels = cmap.regions()
    t = np.linspace(0.0, 1.0, 7)
    for (a, b), box in zip(path.steps, path.boxes, strict=True):
        assert np.all(cmap.lower[box] <= a) and np.all(a <= cmap.upper[box])
        assert np.all(cmap.lower[box] <= b) and np.all(b <= cmap.upper[box])
        assert cmap.verdict[box] == YES and labels[box] == path.region
        for x in a + t[:, None] * (b - a):
            held = locate(cmap.lower, cmap.upper, cmap.wraps, x)
            assert np.any((cmap.verdict[held] == YES) & (labels[held] == path.region))
    points = _points_along(path)
    natural = np.tile(cmap.base, (points.shape[0], 1))
    natural[:, [robot.coordinate_names.index(c) for c in cmap.coordinates]] = points
    assert np.all(cdpm.evaluate_poses(robot, natural, margin=False)["poc"] == YES)


def test_segment_cover_meets_exactly_and_never_bridges_a_gap():
    lower = np.array([[0.0, 0.0], [1.0, 0.0]])
    upper = np.array([[1.0, 1.0], [2.0, 1.0]])
    ids, t0, t1 = segment_cover([0.5, 0.5], [1.5, 0.5], lower, upper)
    assert ids.tolist() == [0, 1] and t0.tolist() == [0.0, 0.5] and t1.tolist() == [0.5, 1.0]
    gap_upper = upper.copy()
    gap_upper[0, 0] = np.nextafter(1.0, 0.0)  # one rounding short of the next box
    assert segment_cover([0.5, 0.5], [1.5, 0.5], lower, gap_upper) is None
    assert segment_cover([0.5, 0.5], [0.5, 1.5], lower, upper) is None  # leaves the boxes


@pytest.mark.parametrize("maximise", [False, True])
def test_a_certified_path_lies_in_yes_boxes_and_the_analyser_agrees(paper_robot, band, maximise):
    goal = [-1.2, 1.35]
    path = certified_path(band, NOMINAL, goal, maximise_margin=maximise, robot=paper_robot)
    assert path.region == band.regions()[locate(band.lower, band.upper, band.wraps, NOMINAL)[0]]
    np.testing.assert_allclose(path.waypoints[0], NOMINAL)
    np.testing.assert_allclose(path.waypoints[-1], goal)
    np.testing.assert_allclose(path.natural[[0, -1]], [NOMINAL, goal])
    assert path.n_steps == path.boxes.size == path.margins.size >= 1
    np.testing.assert_array_equal(path.margins, band.margin_lower[path.boxes])
    assert path.min_margin > 0 and path.seam_crossings == ()
    _assert_proven_along(paper_robot, band, path)
    if maximise:  # the bottleneck: every box of the route but the ends' is at least it
        inner = path.route[1:-1]
        assert np.all(band.margin_lower[inner] >= path.threshold)
    text = certified_path_text(path)
    assert text.startswith("certified POC path (") and "no step can cross a NO set" in text
    data = certified_path_json(path)
    assert data["certified"] and data["n_steps"] == path.n_steps
    assert data["waypoints"][0] == pytest.approx({"q1": NOMINAL[0], "q2": NOMINAL[1]})


def test_poc_path_on_a_certified_map_is_the_certified_path(paper_robot, band):
    path = cdpm.poc_path(band, NOMINAL, [-1.2, 1.35])
    assert isinstance(path, CertifiedPath)
    assert path.n_steps == certified_path(band, NOMINAL, [-1.2, 1.35]).n_steps


@dataclass(frozen=True)
class _Boxes:
    """Stand-in for a certified map: cells of a grid with given verdicts
    (what certified_path reads of a CertifiedMap)."""

    coordinates: tuple
    lower: np.ndarray
    upper: np.ndarray
    verdict: np.ndarray
    margin_lower: np.ndarray
    wraps: tuple
    edges: tuple
    base: np.ndarray = field(default_factory=lambda: np.zeros(2))
    boxes: None = None
    units: tuple = ("rad", "rad")

    @property
    def volumes(self):
        return np.prod(self.upper - self.lower, axis=1)

    def regions(self):
        return CertifiedMap.regions(self)


def _cells(columns: str, rows: int = 2) -> _Boxes:
    """q1 a full turn in len(columns) cells, q2 over [0, 1] in ``rows``;
    each column's verdict: Y (YES), N (NO), U (undecided). Margins: 0.1 in
    row 0, 0.5 above."""
    q1 = np.linspace(-math.pi, math.pi, len(columns) + 1)
    q2 = np.linspace(0.0, 1.0, rows + 1)
    i, j = np.meshgrid(np.arange(len(columns)), np.arange(rows), indexing="ij")
    i, j = i.reshape(-1), j.reshape(-1)
    code = {"Y": YES, "N": NO, "U": MARGINAL}
    verdict = np.array([code[columns[k]] for k in i], dtype=np.int8)
    margin = np.where(verdict == YES, np.where(j == 0, 0.1, 0.5), np.nan)
    return _Boxes(
        ("q1", "q2"),
        np.column_stack([q1[i], q2[j]]),
        np.column_stack([q1[i + 1], q2[j + 1]]),
        verdict,
        margin,
        (True, False),
        (q1, q2),
    )


#: columns 0-2 and 7 (joined across q1 = +-pi) and 4-5: two regions, a NO
#: column and an undecided one between them
SEPARATED = "YYYNYYUY"


def _centre(cells: _Boxes, column: int, row: int = 0) -> list[float]:
    k = column * 2 + row
    return list(0.5 * (cells.lower[k] + cells.upper[k]))


def test_every_step_stays_in_its_box_of_the_region():
    cells = _cells(SEPARATED)
    path = certified_path(cells, [-2.9, 0.2], [-0.9, 0.7])
    labels = cells.regions()
    for (a, b), box in zip(path.steps, path.boxes, strict=True):
        assert np.all(cells.lower[box] <= np.minimum(a, b))
        assert np.all(np.maximum(a, b) <= cells.upper[box])
        assert cells.verdict[box] == YES and labels[box] == path.region
    # one straight segment (the YES cells cover it), cut where it changes cell
    assert path.length == pytest.approx(math.hypot(2.0, 0.5))


def test_the_path_wraps_the_short_way_across_pi():
    cells = _cells(SEPARATED)
    start, goal = _centre(cells, 7), _centre(cells, 0)  # either side of q1 = +-pi
    path = certified_path(cells, start, goal)
    assert path.seam_crossings == (1,) and path.n_steps == 2
    assert path.length == pytest.approx(2 * math.pi / 8)  # one cell, not seven
    assert path.waypoints[-1, 0] == pytest.approx(goal[0] + 2 * math.pi)  # runs on past pi
    assert path.map_waypoints[-1, 0] == pytest.approx(goal[0])
    assert path.steps[0, 1, 0] == math.pi and path.steps[1, 0, 0] == -math.pi


def test_maximin_keeps_to_the_boxes_of_larger_margin():
    cells = _cells("YYYYYYYY")
    start, goal = _centre(cells, 1), _centre(cells, 3)  # row 0: margin 0.1
    shortest = certified_path(cells, start, goal)
    assert np.all(cells.margin_lower[shortest.boxes] == 0.1)
    wide = certified_path(cells, start, goal, maximise_margin=True)
    assert wide.threshold == 0.5 and np.all(cells.margin_lower[wide.route[1:-1]] == 0.5)
    assert wide.length > shortest.length


def test_ends_outside_certified_regions_are_named():
    cells = _cells(SEPARATED)
    with pytest.raises(
        NotConnectedError,
        match=r"goal \(q1=1.963, q2=0.25\) is in no certified YES box: the box holding it "
        r"\(q1 \[1.571, 2.356\], q2 \[0, 0.5\]\) is undecided; nearest certified region: 1, "
        r"0.3927 away",
    ):
        certified_path(cells, _centre(cells, 1), _centre(cells, 6))
    with pytest.raises(NotConnectedError, match=r"start .* is proven NO; nearest certified"):
        certified_path(cells, _centre(cells, 3), _centre(cells, 1))
    with pytest.raises(
        NotConnectedError,
        match=r"start \(q1=-1.963, q2=0.25\) is in certified region 1 \(8 YES boxes, 50.0% of "
        r"the mapped volume\); goal \(q1=0.3927, q2=0.25\) is in certified region 2 .*no "
        "certified path joins them",
    ) as caught:
        certified_path(cells, _centre(cells, 1), _centre(cells, 4))
    assert (caught.value.start_region, caught.value.goal_region) == (1, 2)
    assert (caught.value.start_size, caught.value.goal_size) == (8, 4)
    with pytest.raises(InputError, match=r"goal: q2 = 2 is off the map \(q2 from 0 to 1\)"):
        certified_path(cells, _centre(cells, 1), [0.5, 2.0])
    with pytest.raises(InputError, match="goal has 3 values; give 2"):
        certified_path(cells, _centre(cells, 1), [0.5, 1.0, 0.0])


def test_a_pose_name_needs_the_maps_spec(band):
    # a map made in memory records its spec: the name is looked up there
    assert certified_path(band, "nominal", [-1.2, 1.35]).n_steps >= 1
    with pytest.raises(InputError, match="needs the map's robot, but its spec"):
        certified_path(_cells(SEPARATED), "nominal", [0.5, 0.5])


def test_no_yes_box_at_all_says_so(tmp_path):
    from tests.conftest import neither_case_spec

    vertical = neither_case_spec(tmp_path)
    cmap = certify_map(vertical, {"q1": np.linspace(0.0, 0.4, 3)}, workers=1)
    with pytest.raises(NotConnectedError, match="the map has no certified YES box"):
        certified_path(cmap, [0.1], [0.3])


# ----------------------------------------------------------------- the CLI


@pytest.fixture(scope="module")
def band_store(tmp_path_factory, paper_robot):
    store = tmp_path_factory.mktemp("certified") / "band.zarr"
    certify_map(paper_robot, BAND, min_fraction=1 / 4, workers=1, store=store)
    return store


def test_path_command_on_a_certified_store(band_store, tmp_path, capsys):
    image = tmp_path / "path.png"
    argv = ["path", str(band_store), "--from", "nominal", "--to", "-1.2", "1.35"]
    assert main([*argv, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["connected"] and data["certified"] and data["region"] >= 1
    assert data["n_steps"] == len(data["steps"]) >= 1
    assert "suspect_steps" not in data  # those belong to sampled maps
    pytest.importorskip("matplotlib")
    assert main([*argv, "--maximin", "--plot", str(image)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"certified map {band_store}: coordinates q1, q2\n")
    assert "certified POC path (largest smallest margin) in certified region " in out
    assert "warning" not in out and "suspect" not in out
    assert image.stat().st_size > 10_000


def test_path_command_on_a_certified_store_not_connected(band_store, capsys):
    cmap = cdpm.open_certified(band_store)
    undecided = np.flatnonzero(cmap.verdict == MARGINAL)[0]  # across a NO line of the arm
    goal = 0.5 * (cmap.lower[undecided] + cmap.upper[undecided])
    argv = ["path", str(band_store), "--from", "nominal", "--to", *map(repr, goal.tolist())]
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert "cdpm path: not connected: start (q1=0.5236, q2=1.047) is in certified region " in err
    assert f"goal (q1={goal[0]:.4g}, q2={goal[1]:.4g}) is in no certified YES box" in err
    assert main([*argv[:-2], "-1.2", "1.35", "--legs", "3", "--steer"]) == 1
    assert "--legs does not apply to a certified map" in capsys.readouterr().err


@pytest.mark.slow
def test_steering_along_a_certified_path_reaches_every_leg(band_store, capsys):
    argv = ["path", str(band_store), "--from", "nominal", "--to", "-1.2", "1.35", "--steer"]
    assert main([*argv, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    legs = data["steering"]
    assert len(legs) == data["n_steps"] and data["legs_reached"] == len(legs)
    for leg, step in zip(legs, data["steps"], strict=True):
        assert leg["miss"] <= leg["tolerance"] and leg["to"] == leg["from"] + 1
        assert step["margin_lower"] > 0  # both ends of the leg in one certified YES box
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "one leg per step: both ends of each leg in one certified YES box" in out
    assert out.rstrip().endswith(f"{len(legs)} of {len(legs)} legs reached their waypoint's output")


@pytest.mark.slow
def test_a_missed_leg_says_which_by_how_much_and_why(band_store, capsys, monkeypatch):
    import cdpm.steering.shooting

    real = cdpm.steering.shooting.steer

    def missing(robot, q, target, **kwargs):
        result = real(robot, q, target, **{**kwargs, "max_iterations": 1})
        return dataclasses.replace(
            result, reached=False, miss=2 * result.tolerance, status="the reason steer gives"
        )

    monkeypatch.setattr(cdpm.steering.shooting, "steer", missing)
    goal = [NOMINAL[0] + 0.01, NOMINAL[1] + 0.01]  # a step or two from the nominal pose
    argv = ["path", str(band_store), "--from", "nominal", "--to", *map(str, goal), "--steer"]
    assert main(argv) == 4
    out = capsys.readouterr().out
    line = re.search(
        r"^  leg 1 \(waypoints 0 to 1\) missed by (\S+) m, tolerance (\S+) m: (.*)$", out, re.M
    )
    assert line is not None and float(line.group(1)) == pytest.approx(
        2 * float(line.group(2)), rel=0.01
    )
    # the reason, then every attempt: the default duration, more iterations (a near miss), longer
    assert line.group(3).startswith("the reason steer gives; tried T = 1 s (1 simulations, miss ")
    assert line.group(3).count("T = ") == 4


def test_a_path_that_is_not_connected_still_draws_the_map_and_its_ends(band_store, tmp_path):
    """Start in a box that is not proven YES: exit 3, the reason, and the
    picture of the map with the start and the goal marked (where the user
    needs it)."""
    import subprocess
    import sys

    cmap = cdpm.open_certified(band_store)
    no = np.flatnonzero(cmap.verdict != YES)
    yes = np.flatnonzero(cmap.verdict == YES)
    assert no.size and yes.size
    start = 0.5 * (cmap.lower[no[0]] + cmap.upper[no[0]])
    goal = 0.5 * (cmap.lower[yes[0]] + cmap.upper[yes[0]])
    image = tmp_path / "nc.png"
    argv = [
        sys.executable,
        "-m",
        "cdpm",
        "path",
        str(band_store),
        "--from",
        *map(str, start),
        "--to",
        *map(str, goal),
        "--plot",
        str(image),
    ]
    done = subprocess.run(argv, capture_output=True, text=True)
    assert done.returncode == 3, done.stderr
    assert "not connected" in done.stderr and "plot written to" in done.stderr
    assert image.stat().st_size > 10000


def test_an_end_beyond_a_full_turn_is_named_as_the_map_holds_it(paper_robot, capsys, tmp_path):
    """q1 = pi/6 + 2 pi is the nominal pose a full turn on: the path goes
    there, and the output says which pose on the map it took."""
    from cdpm.cli import main

    store = tmp_path / "turn.zarr"
    edges = np.linspace(-np.pi, np.pi, 9)
    certify_map(
        paper_robot, {"q1": edges}, base=[0.0, 1.0], min_fraction=1 / 8, workers=1, store=store
    )
    code = main(["path", str(store), "--from", "0.4", "--to", str(0.5 + 2 * np.pi)])
    out = capsys.readouterr().out
    assert code == 0
    assert "the goal's q1 = 6.78319 is q1 = 0.5 on the map (whole turns" in out
    assert "the start's" not in out
