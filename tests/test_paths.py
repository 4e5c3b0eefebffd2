"""Paths of POC poses through maps (cdpm.poc_path) and `cdpm path`."""

from __future__ import annotations

import dataclasses
import heapq
import inspect
import json
import math
import re
import socket
from collections import deque

import numpy as np
import pytest
import xarray as xr

import cdpm
from cdpm import plotting
from cdpm.cli import main
from cdpm.errors import InputError
from cdpm.maps.regions import attach_regions, label_regions
from cdpm.regions.paths import (
    NotConnectedError,
    POCPath,
    poc_path,
    suspect_region_splits,
    suspect_region_steps,
)
from cdpm.text import path_json, path_text
from cdpm.verdicts import NO, NOT_ANALYSED, YES
from tests.conftest import MODELS, PAPER_SPEC

VERTICAL_SPEC = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
TWO_CABLES_SPEC = MODELS / "two_link_two_cables" / "two_link_two_cables.yaml"
N = 31
TURN = np.linspace(-math.pi, math.pi, N)  # closed: -pi and +pi are one pose
NOMINAL = [math.pi / 6, math.pi / 3]


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """31 x 31 full-turn maps of three models, written to zarr stores."""
    folder = tmp_path_factory.mktemp("path_maps")
    out = {}
    for name, spec in (
        ("paper", PAPER_SPEC),
        ("vertical", VERTICAL_SPEC),
        ("two_cables", TWO_CABLES_SPEC),
    ):
        store = folder / f"{name}.zarr"
        cdpm.workspace_map(spec, {"q1": TURN, "q2": TURN}, workers=1, store=store)
        out[name] = store
    return out


@pytest.fixture(scope="module")
def paper(stores):
    return attach_regions(cdpm.open_map(stores["paper"]))


@pytest.fixture(scope="module")
def two_cables(stores):
    return cdpm.open_map(stores["two_cables"])  # no poc_region: labelled on the fly


# -------------------------------------------------------------- references


def _neighbours(i: int, j: int, m: int = N - 1):
    """Face neighbours of distinct pose (i, j) on the m x m torus."""
    return [((i + 1) % m, j), ((i - 1) % m, j), (i, (j + 1) % m), (i, (j - 1) % m)]


def _distinct_yes(ds) -> np.ndarray:
    poc = ds.poc.transpose("q1", "q2").values == YES
    yes = poc[:-1, :-1].copy()
    yes[0, :] &= poc[-1, :-1]
    yes[:, 0] &= poc[:-1, -1]
    yes[0, 0] &= poc[-1, -1]
    return yes


def _bfs_steps(yes: np.ndarray, start, goal) -> int:
    seen, queue = {start: 0}, deque([start])
    while queue:
        p = queue.popleft()
        if p == goal:
            return seen[p]
        for q in _neighbours(*p):
            if yes[q] and q not in seen:
                seen[q] = seen[p] + 1
                queue.append(q)
    raise AssertionError("goal not reached")


def _widest_bottleneck(yes, margin, start, goal) -> float:
    """Largest smallest margin over paths start -> goal (a widest-path
    Dijkstra with a max-heap)."""
    best = {start: margin[start]}
    heap = [(-margin[start], start)]
    while heap:
        neg, p = heapq.heappop(heap)
        if p == goal:
            return -neg
        for q in _neighbours(*p):
            if yes[q]:
                width = min(-neg, margin[q])
                if width > best.get(q, -np.inf):
                    best[q] = width
                    heapq.heappush(heap, (-width, q))
    raise AssertionError("goal not reached")


def _distinct_margin(ds, name) -> np.ndarray:
    m = ds[name].transpose("q1", "q2").values
    out = m[:-1, :-1].copy()
    out[0, :] = np.minimum(out[0, :], m[-1, :-1])
    out[:, 0] = np.minimum(out[:, 0], m[:-1, -1])
    out[0, 0] = min(out[0, 0], m[-1, -1])
    return out


def _check_walk(ds, path: POCPath) -> None:
    """Consecutive waypoints are face neighbours on the torus, every one YES
    and in the path's region; coordinates and natural agree with the map."""
    labels = ds.poc_region if "poc_region" in ds else label_regions(ds)
    pos = path.indices % (N - 1)
    for a, b in zip(pos[:-1], pos[1:], strict=True):
        assert (int(b[0]), int(b[1])) in _neighbours(int(a[0]), int(a[1]))
    poc = ds.poc.transpose("q1", "q2").values
    lab = labels.transpose("q1", "q2").values
    for i, j in path.indices:
        assert poc[i, j] == YES and lab[i, j] == path.region
    np.testing.assert_array_equal(path.coordinates["q1"], TURN[path.indices[:, 0]])
    np.testing.assert_array_equal(path.natural[:, 1], TURN[path.indices[:, 1]])
    assert path.natural_names == ("q1", "q2")
    assert path.length == pytest.approx(path.steps * 2 * math.pi / (N - 1))


# -------------------------------------------------------------------- paths


def test_shortest_path_is_a_shortest_walk_of_poc_poses(paper):
    path = poc_path(paper, NOMINAL, [2.5, -2.0])
    assert isinstance(path, POCPath) and path.region == 1
    _check_walk(paper, path)
    assert path.dims == ("q1", "q2") and path.indices.shape == (path.n_waypoints, 2)
    start = tuple(int(x) for x in path.indices[0] % (N - 1))
    goal = tuple(int(x) for x in path.indices[-1] % (N - 1))
    assert path.steps == _bfs_steps(_distinct_yes(paper), start, goal)
    assert path.margin_variable in ("reach_margin", "poc_margin")
    assert path.min_margin == pytest.approx(np.min(path.margins)) and path.min_margin > 0
    assert "POC path (shortest) in region 1" in path_text(path)
    assert str(path).startswith("POC path (shortest) in region 1: ")
    assert len(str(path).splitlines()) == 1  # a summary; path_text lists the waypoints


def test_maximin_path_keeps_the_largest_smallest_margin(paper):
    start, goal = NOMINAL, [-2.0, -1.5]
    shortest = poc_path(paper, start, goal)
    widest = poc_path(paper, start, goal, maximise_margin=True)
    _check_walk(paper, widest)
    assert widest.maximise_margin and widest.min_margin >= shortest.min_margin
    margin = _distinct_margin(paper, widest.margin_variable)
    s = tuple(int(x) for x in widest.indices[0] % (N - 1))
    g = tuple(int(x) for x in widest.indices[-1] % (N - 1))
    assert widest.min_margin == pytest.approx(
        _widest_bottleneck(_distinct_yes(paper), margin, s, g), rel=1e-12
    )
    assert widest.steps >= shortest.steps


def test_maximin_path_from_a_start_of_small_margin_widens_the_rest(paper):
    """The start's and goal's margins are given: from a start whose margin
    is the smallest on any path, every path tied and the shortest of them
    was taken; the waypoints between them now have the largest smallest
    margin there is (a widest-path search with the ends left out)."""
    start, goal = [TURN[6], TURN[5]], [-2.0, -1.5]
    widest = poc_path(paper, start, goal, maximise_margin=True)
    shortest = poc_path(paper, start, goal)
    _check_walk(paper, widest)
    margin = _distinct_margin(paper, widest.margin_variable)
    s = tuple(int(x) for x in widest.indices[0] % (N - 1))
    g = tuple(int(x) for x in widest.indices[-1] % (N - 1))
    assert widest.min_margin == margin[s] < 0.01  # the start is the bottleneck
    inner = margin.copy()
    inner[s] = inner[g] = np.inf
    best = _widest_bottleneck(_distinct_yes(paper), inner, s, g)
    assert np.min(widest.margins[1:-1]) == pytest.approx(best, rel=1e-12)
    assert best > 4 * np.min(shortest.margins[1:-1])  # 0.077 against 0.018 m


def test_a_path_across_the_seam_takes_the_short_way(paper):
    path = poc_path(paper, [2.9, 0.5], [-2.9, 0.5])
    assert path.steps <= 3  # across +-pi, not 28 steps the long way round
    assert path.seam_crossings
    k = path.seam_crossings[0]
    assert abs(path.coordinates["q1"][k + 1] - path.coordinates["q1"][k]) > math.pi
    # the seam pose is shown at the end the path comes from
    onto_seam = poc_path(paper, [2.9, 0.5], [math.pi, 0.5])
    assert onto_seam.coordinates["q1"].tolist() == pytest.approx([TURN[-2], TURN[-1]])
    assert not onto_seam.seam_crossings
    # along the seam pose, the goal given at -pi: its last step does not
    # move in q1 (pi to -pi is one pose) and crosses no seam
    along = poc_path(paper, [math.pi, TURN[3]], [-math.pi, TURN[6]])
    assert along.coordinates["q1"].tolist() == pytest.approx([math.pi] * 3 + [-math.pi])
    assert not along.seam_crossings and "crosses the seam" not in path_text(along)


def test_same_start_and_goal_is_a_path_of_one_pose(paper):
    path = poc_path(paper, [0.6, 1.0], [0.62, 1.03])  # both nearest (0.628, 1.047)
    assert path.n_waypoints == 1 and path.steps == 0 and path.length == 0


def test_not_connected_names_both_regions(two_cables):
    labels = label_regions(two_cables)
    regions = json.loads(labels.attrs["regions"])
    lab = labels.values
    poses = []
    for label in (1, 2):
        i, j = np.argwhere(lab == label)[0]
        poses.append([float(TURN[i]), float(TURN[j])])
    with pytest.raises(NotConnectedError) as info:
        poc_path(two_cables, poses[0], poses[1])
    err = info.value
    assert isinstance(err, InputError)
    assert (err.start_region, err.goal_region) == (1, 2)
    sizes = (regions[0]["size"], regions[1]["size"])
    assert (err.start_size, err.goal_size) == sizes
    assert str(err) == (
        f"start (q1={poses[0][0]:.4g}, q2={poses[0][1]:.4g}) is in POC region 1 "
        f"({sizes[0]} poses); goal (q1={poses[1][0]:.4g}, q2={poses[1][1]:.4g}) is in "
        f"region 2 ({sizes[1]} poses): no path of POC poses joins them"
    )
    # the paper's pose is NO on this model
    with pytest.raises(NotConnectedError, match=r"is in no POC region: its verdict there is NO"):
        poc_path(two_cables, NOMINAL, poses[1])


def test_not_connected_on_a_hand_made_map():
    poc = np.full((6, 7), NO, dtype=np.int8)
    poc[:, :2] = YES
    poc[:, 4:] = YES
    q1, q2 = np.linspace(0.0, 1.0, 6), np.linspace(0.0, 0.6, 7)
    ds = xr.Dataset(
        {"poc": (("q1", "q2"), poc)},
        coords={"q1": ("q1", q1, {"units": "m"}), "q2": ("q2", q2, {"units": "m"})},
    )
    with pytest.raises(NotConnectedError, match=r"region 2 \(12 poses\).*region 1 \(18 poses\)"):
        poc_path(ds, [0.0, 0.0], [1.0, 0.6])
    path = poc_path(ds, [0.0, 0.0], [1.0, 0.1])
    assert path.steps == 6 and np.isnan(path.min_margin) and path.margin_variable is None
    with pytest.raises(InputError, match="no margins"):
        poc_path(ds, [0.0, 0.0], [1.0, 0.1], maximise_margin=True)
    with pytest.raises(InputError, match="off the map"):
        poc_path(ds, [0.0, 0.0], [1.2, 0.1])


def test_sampled_path_steps_within_the_radius():
    ds = cdpm.workspace_map(
        PAPER_SPEC,
        {"q1": (-math.pi, math.pi), "q2": (-math.pi, math.pi)},
        samples=600,
        seed=2,
        workers=1,
    )
    labels = label_regions(ds)
    path = poc_path(ds, NOMINAL, [2.5, -2.0])
    assert path.dims == ("sample",) and path.indices.shape[1] == 1
    x = np.stack([path.coordinates["q1"], path.coordinates["q2"]], axis=1)
    step = np.abs(np.diff(x, axis=0))
    step = np.minimum(step, 2 * math.pi - step)
    lengths = np.sqrt((step**2).sum(axis=1))
    assert np.all(lengths <= labels.attrs["radius"] * (1 + 1e-12))
    assert path.length == pytest.approx(lengths.sum())
    samples = path.indices[:, 0]
    assert np.all(ds.poc.values[samples] == YES)
    assert np.all(labels.values[samples] == path.region)
    widest = poc_path(ds, NOMINAL, [2.5, -2.0], maximise_margin=True)
    assert widest.min_margin >= path.min_margin


def test_path_json_is_strict_json(paper):
    path = poc_path(paper, NOMINAL, [1.0, 0.5])
    data = json.loads(json.dumps(path_json(path), allow_nan=False))
    assert data["region"] == 1 and data["n_waypoints"] == len(data["coordinates"]["q1"]) == 6
    assert data["waypoints"][0] == data["start_pose"] == {"q1": TURN[18], "q2": TURN[20]}
    assert data["waypoints"][-1] == data["goal_pose"] == {"q1": TURN[20], "q2": TURN[17]}
    assert data["suspect_steps"] == list(path.suspect_steps)


def test_path_repr_is_short(paper):
    path = poc_path(paper, NOMINAL, [1.0, 0.5])
    assert repr(path) == (
        f"POCPath(region=1, waypoints=6, length={path.length:.4g}, "
        f"min_margin={path.min_margin:.4g}, suspect_steps={path.suspect_steps})"
    )
    one = poc_path(paper, [0.6, 1.0], [0.62, 1.03])
    assert "1 waypoint, 0 steps" in path_text(one)


def test_pose_names_in_python(paper):
    by_name = poc_path(paper, "nominal", [1.0, 0.5])
    assert by_name.start_pose == poc_path(paper, NOMINAL, [1.0, 0.5]).start_pose
    assert cdpm.region_of(paper, "nominal") == cdpm.region_of(paper, NOMINAL) == 1
    with pytest.raises(InputError, match="pose 'home' not in spec"):
        cdpm.region_of(paper, "home")


def _thin_line_map() -> xr.Dataset:
    """11 x 7 grid (step 0.1 m): r_T 0.1, but 0.05 on columns q1 = 0.4 and 0.5
    of rows q2 <= 0.2 (a thin NO line may pass between them); a wall of
    unanalysed poses above, and at q2 = 0.6 a way round with r_T = 0.045."""
    poc = np.full((11, 7), YES, dtype=np.int8)
    r = np.full((11, 7), 0.1)
    r[4:6, :3] = 0.05
    poc[4:6, 3:6], r[4:6, 3:6] = NOT_ANALYSED, np.nan
    r[3:7, 6] = [0.06, 0.045, 0.045, 0.06]
    q1, q2 = np.linspace(0.0, 1.0, 11), np.linspace(0.0, 0.6, 7)
    units = {"units": "m"}
    return xr.Dataset(
        {"poc": (("q1", "q2"), poc), "reach_margin": (("q1", "q2"), r)},
        coords={"q1": ("q1", q1, units), "q2": ("q2", q2, units)},
    )


def test_suspect_steps_are_flagged_and_avoided_by_maximin():
    ds = _thin_line_map()
    shortest = poc_path(ds, [0.0, 0.0], [1.0, 0.0])
    assert shortest.steps == 10 and shortest.suspect_steps == (4,)
    assert shortest.coordinates["q1"][4:6].tolist() == pytest.approx([0.4, 0.5])
    assert (
        "may cross a NO set thinner than the map's resolution between waypoints 4 and 5 "
        "(q1 0.4 -> 0.5)" in path_text(shortest)
    )
    # the widest path over all steps would cross there (bottleneck 0.05 > 0.045)
    widest = poc_path(ds, [0.0, 0.0], [1.0, 0.0], maximise_margin=True)
    assert widest.suspect_steps == () and widest.min_margin == pytest.approx(0.045)
    assert np.max(widest.coordinates["q2"]) == pytest.approx(0.6)
    # without reach_margin nothing is checked
    plain = poc_path(ds.drop_vars("reach_margin"), [0.0, 0.0], [1.0, 0.0])
    assert plain.suspect_steps is None and "not checked" in path_text(plain)


def test_sampled_path_across_a_thin_no_line_is_flagged():
    # the gravity arm is NO on the line q2 = 0 (straight under gravity); random
    # samples never land on it, so one region spans both sides
    ds = cdpm.workspace_map(
        VERTICAL_SPEC, {"q1": (-3.0, 3.0), "q2": (-3.0, 3.0)}, samples=2000, seed=1, workers=1
    )
    for maximise in (False, True):
        path = poc_path(ds, [0.0, -1.0], [-2.6, 2.4], maximise_margin=maximise)
        q2 = path.coordinates["q2"]
        crossings = [k for k in range(path.steps) if np.sign(q2[k]) != np.sign(q2[k + 1])]
        assert crossings and set(crossings) <= set(path.suspect_steps), (crossings, path)


# --------------------------------------------------------------------- CLI


def test_path_help(capsys):
    with pytest.raises(SystemExit) as info:
        main(["path", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "--from V [V ...]" in out and "--maximin" in out and "--steer" in out
    assert "exit codes: 0 a path was found (and, with --steer, every leg reached" in out
    assert "3 the start and goal are not joined" in out and "4 with\n--steer, a leg missed" in out
    assert "2 usage\nerrors" in out


def test_path_command_prints_the_path(stores, capsys):
    assert main(["path", str(stores["paper"]), "--from", "nominal", "--to", "2.5", "-2"]) == 0
    out = capsys.readouterr().out
    assert "axes q1, q2" in out and "POC path (shortest) in region 1" in out
    assert "waypoints" in out and "smallest" in out
    args = ["path", str(stores["paper"]), "--from", "1/2", "1", "--to", "2.5", "-2"]
    assert main([*args, "--maximin", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["connected"] and data["maximise_margin"] and data["region"] == 1
    assert data["coordinates"]["q1"][0] == pytest.approx(TURN[17])  # 0.419, nearest 0.5
    assert data["coordinates"]["q2"][-1] == pytest.approx(TURN[5])  # -2.094, nearest -2


def test_path_command_not_connected(stores, capsys):
    store = str(stores["two_cables"])
    assert main(["path", store, "--from", "nominal", "--to", "0", "-1"]) == 3
    out, err = capsys.readouterr()
    assert err.startswith("cdpm path: not connected: start (q1=")
    assert "is in no POC region: its verdict there is NO; goal (q1=0, q2=-1.047)" in err
    assert "Traceback" not in err and out == ""
    assert main(["path", store, "--from", "nominal", "--to", "0", "-1", "--json"]) == 3
    data = json.loads(capsys.readouterr().out)
    assert data["connected"] is False and data["start_region"] == 0


def test_path_command_bad_input(stores, tmp_path, capsys):
    store = str(stores["paper"])
    cases = [
        (["path", str(tmp_path / "none.zarr"), "--from", "0", "0", "--to", "1", "1"], "not found"),
        (["path", store, "--from", "1", "2", "3", "--to", "0", "0"], "--from 1 2 3: pose has 3"),
        (["path", store, "--from", "home", "--to", "0", "0"], "pose 'home' not in spec"),
        (["path", store, "--from", "0", "0", "--to", "x", "y"], "--to x y: give numbers"),
        (["path", store, "--from", "0", "0", "--to", "1", "1", "--seconds", "1"], "--view"),
        (["path", store, "--from", "0", "0", "--to", "1", "1", "--legs", "2"], "--steer"),
    ]
    for argv, message in cases:
        assert main(argv) == 1, argv
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err


def test_path_command_off_the_map(tmp_path, capsys):
    store = tmp_path / "slice.zarr"
    cdpm.workspace_map(PAPER_SPEC, {"q1": np.linspace(0.0, 1.0, 5)}, workers=1, store=store)
    assert main(["path", str(store), "--from", "0.5", "--to", "1.5"]) == 1
    assert "--to 1.5: pose q1 = 1.5 is off the map" in capsys.readouterr().err


@pytest.mark.slow
def test_path_command_steers_the_gravity_arm(stores, capsys):
    store = str(stores["vertical"])
    argv = ["path", store, "--from", "0.2", "0.8", "--to", "0.2", "1.25", "--steer", "--legs", "2"]
    assert main([*argv, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["steps"] == 2 and len(data["steering"]) == 2
    for leg in data["steering"]:
        assert math.isfinite(leg["miss"]) and leg["miss"] < 0.1 * leg["distance"]
        assert leg["distance"] > 0.1  # a grid step moves the tip by about 0.2 m
    assert data["legs_reached"] == 2
    assert data["start_pose"] == {"q1": TURN[16], "q2": TURN[19]}
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "steering the nonlinear robot along 2 leg(s)" in out and "miss [m]" in out
    assert out.rstrip().endswith("2 of 2 legs reached their waypoint's output")


def test_path_command_exits_4_when_a_leg_misses(stores, capsys, monkeypatch):
    import cdpm.steering.shooting

    real = cdpm.steering.shooting.steer

    def missing_second_leg(robot, q, target, **kwargs):
        result = real(robot, q, target, **kwargs)
        if abs(robot.to_natural(q)[1] - TURN[20]) < 1e-9:  # the second leg's start
            return dataclasses.replace(result, reached=False)
        return result

    monkeypatch.setattr(cdpm.steering.shooting, "steer", missing_second_leg)
    store = str(stores["vertical"])
    argv = ["path", store, "--from", "0.2", "0.8", "--to", "0.2", "1.25", "--steer", "--legs", "2"]
    assert main(argv) == 4
    out = capsys.readouterr().out
    assert out.rstrip().endswith("1 of 2 legs reached their waypoint's output")
    # the picture's title says so too, naming the leg
    pytest.importorskip("matplotlib")
    import cdpm.plotting.map_plot

    titles = []
    real_plot = cdpm.plotting.map_plot.plot_map

    def recorded(*args, **kwargs):
        fig = real_plot(*args, **kwargs)
        titles.append(fig.get_suptitle())
        return fig

    monkeypatch.setattr(cdpm.plotting.map_plot, "plot_map", recorded)
    assert main([*argv, "--plot", str(stores["vertical"].parent / "legs.png")]) == 4
    leg = re.search(r"^  +2 +(\d+) +(\d+) .* no$", capsys.readouterr().out, re.M)
    assert (
        titles[0]
        .splitlines()[-1]
        .startswith(
            f"steered along 2 leg(s): 1 reached their waypoint's output; missed: leg 2 (waypoints "
            f"{leg.group(1)} to {leg.group(2)}) by "
        )
    )


def test_the_map_counts_the_steps_where_its_regions_may_be_split(stores, paper, capsys):
    """The paper arm's thin diagonal NO lines are not resolved at 31 x 31:
    one region, but steps of it may cross them. The map counts every such
    step of its graph (a path's suspect steps are among them), and `cdpm
    map` says so under the region count."""
    count = suspect_region_steps(paper)
    path = poc_path(paper, NOMINAL, [1.0, 0.5])
    assert 0 < len(path.suspect_steps) <= count
    steps, extra = suspect_region_splits(paper)
    assert steps == count and extra > 0  # without those steps the region falls apart
    no_margin = cdpm.workspace_map(PAPER_SPEC, {"q1": TURN, "q2": TURN}, workers=1, margin=False)
    assert suspect_region_steps(no_margin) is None  # r_T decides; without it, nothing to say
    store = stores["paper"].parent / "again.zarr"
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=-pi:pi:31", "--axis", "q2=-pi:pi:31"]
    assert main([*argv, "--out", str(store), "--quiet"]) == 0
    assert (
        f"  {count} step(s) between neighbouring YES poses may cross a NO set thinner than the "
        "map's resolution" in capsys.readouterr().out
    )


def test_the_map_says_nothing_of_suspect_steps_that_split_no_region(stores, monkeypatch, capsys):
    """Suspect steps whose loss leaves every region whole cannot hide a
    split: the map does not mention them (a 100 % YES map used to)."""
    import cdpm.regions.paths as paths

    monkeypatch.setattr(paths, "suspect_region_splits", lambda ds: (64, 0))
    store = stores["paper"].parent / "quiet.zarr"
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=-pi:pi:11", "--axis", "q2=-pi:pi:11"]
    assert main([*argv, "--out", str(store)]) == 0
    assert "may cross a NO set" not in capsys.readouterr().out


def test_path_command_warns_of_suspect_steps(stores, paper, capsys):
    # the 31 x 31 grid (step 0.21 rad) cannot rule out the paper's diagonal NO lines
    expected = poc_path(paper, NOMINAL, [1.0, 0.5]).suspect_steps
    assert expected
    argv = ["path", str(stores["paper"]), "--from", "nominal", "--to", "1", "0.5"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    k = expected[0]
    assert (
        "  warning: the path may cross a NO set thinner than the map's resolution between "
        f"waypoints {k} and {k + 1} (" in out
    )
    assert main([*argv, "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["suspect_steps"] == list(expected)
    assert err.count("cdpm path: warning: the path may cross") == len(expected)


@pytest.mark.skipif(
    "path" not in inspect.signature(plotting.plot_map).parameters,
    reason="cdpm.plotting.save_map_plot has no path= overlay yet",
)
def test_path_command_plots_the_path(stores, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    image = tmp_path / "path.png"
    argv = ["path", str(stores["paper"]), "--from", "nominal", "--to", "-1.5", "0.8", "--plot"]
    assert main([*argv, str(image)]) == 0
    assert f"plot written to {image}" in capsys.readouterr().out
    assert image.stat().st_size > 10_000


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_path_command_views_the_path_for_seconds(stores, capsys):
    pytest.importorskip("meshcat")
    port = _free_port()
    argv = ["path", str(stores["paper"]), "--from", "nominal", "--to", "1", "0.5", "--view"]
    assert main([*argv, "--port", str(port), "--seconds", "0.5"]) == 0
    out, err = capsys.readouterr()
    assert f"viewer: http://127.0.0.1:{port}/static/  (playing the path" in out
    assert "viewer stopped after " in err
