"""POC regions of maps: labels against independent references (grid maps
with the full-turn wrap, sampled maps against a brute-force graph), the
stored variable, and locating a pose."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr
from scipy import ndimage

import cdpm
from cdpm.errors import InputError
from cdpm.maps.regions import attach_regions, label_regions, region_of
from cdpm.numerics import REGION_RADIUS_FACTOR as RADIUS_FACTOR
from cdpm.verdicts import NO, YES
from tests.conftest import MODELS, PAPER_SPEC

VERTICAL_SPEC = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
TWO_CABLES_SPEC = MODELS / "two_link_two_cables" / "two_link_two_cables.yaml"


def _grid(spec, n, endpoint=True, **kwargs):
    values = np.linspace(-math.pi, math.pi, n, endpoint=endpoint)
    return cdpm.workspace_map(spec, {"q1": values, "q2": values}, workers=1, **kwargs)


@pytest.fixture(scope="module")
def paper_map():
    """The paper's arm on a 61 x 61 full-turn grid, -pi and +pi both included."""
    return _grid(PAPER_SPEC, 61)


@pytest.fixture(scope="module")
def vertical_map():
    return _grid(VERTICAL_SPEC, 31)


@pytest.fixture(scope="module")
def two_cables_map():
    return _grid(TWO_CABLES_SPEC, 31)


@pytest.fixture(scope="module")
def sampled_map():
    return cdpm.workspace_map(
        TWO_CABLES_SPEC,
        {"q1": (-math.pi, math.pi), "q2": (-math.pi, math.pi)},
        samples=500,
        seed=3,
        workers=1,
    )


# ------------------------------------------------------------- references


class _UnionFind:
    def __init__(self):
        self.parent = {}

    def find(self, a):
        self.parent.setdefault(a, a)
        while self.parent[a] != a:
            self.parent[a] = self.parent[self.parent[a]]
            a = self.parent[a]
        return a

    def union(self, a, b):
        self.parent[self.find(a)] = self.find(b)


def _reference_torus_labels(poc: np.ndarray, closed: bool) -> np.ndarray:
    """Labels of YES poses on a 2-D full-turn grid: ndimage.label on the
    distinct poses (a closed grid's last row and column are copies of the
    first: YES only when every copy is), then the seam rows and columns
    merged by a union-find; labels spread back to every copy."""
    n = poc.shape[0]
    m = n - 1 if closed else n

    def copies(i):
        return [i, n - 1] if closed and i == 0 else [i]

    yes = np.array(
        [
            [all(poc[a, b] == YES for a in copies(i) for b in copies(j)) for j in range(m)]
            for i in range(m)
        ]
    )
    lab, _ = ndimage.label(yes, structure=[[0, 1, 0], [1, 1, 1], [0, 1, 0]])
    uf = _UnionFind()
    for k in range(m):
        for a, b in ((lab[0, k], lab[m - 1, k]), (lab[k, 0], lab[k, m - 1])):
            if a and b:
                uf.union(a, b)
    merged = np.vectorize(lambda x: uf.find(x) if x else 0)(lab)
    idx = np.arange(n) % m
    return merged[np.ix_(idx, idx)]


def _same_partition(a: np.ndarray, b: np.ndarray) -> None:
    """a and b label the same poses 0 and split the others the same way."""
    np.testing.assert_array_equal(a > 0, b > 0)
    inside = a > 0
    pairs = set(zip(a[inside].tolist(), b[inside].tolist(), strict=True))
    assert len(pairs) == len(np.unique(a[inside])) == len(np.unique(b[inside]))


def _regions(labels) -> list[dict]:
    return json.loads(labels.attrs["regions"])


# ------------------------------------------------------------------ grids


@pytest.mark.parametrize("which", ["paper_map", "vertical_map", "two_cables_map"])
def test_grid_labels_equal_the_reference_labelling(which, request):
    ds = request.getfixturevalue(which)
    labels = label_regions(ds)
    assert labels.name == "poc_region" and labels.dtype == np.int32
    assert labels.dims == ("q1", "q2")
    poc = ds.poc.transpose("q1", "q2").values
    reference = _reference_torus_labels(poc, closed=True)
    _same_partition(labels.values, reference)
    # numbered by decreasing size, sizes counting each pose once
    regions = _regions(labels)
    sizes = [r["size"] for r in regions]
    assert [r["label"] for r in regions] == list(range(1, len(regions) + 1))
    assert sizes == sorted(sizes, reverse=True)
    distinct = labels.values[:-1, :-1]
    assert sizes == [int(np.count_nonzero(distinct == r["label"])) for r in regions]
    assert set(np.unique(labels.values)) == set(range(len(regions) + 1))


def test_region_counts_tell_the_models_apart(paper_map, vertical_map, two_cables_map):
    # the paper's arm: one region over the whole torus; gravity: the straight
    # and folded arm (q2 = 0, +-pi, NO on this grid) split it; two cables: NO areas
    assert len(_regions(label_regions(paper_map))) == 1
    assert len(_regions(label_regions(vertical_map))) == 4
    assert len(_regions(label_regions(two_cables_map))) >= 5


def test_minus_pi_and_plus_pi_slices_share_labels(paper_map, vertical_map):
    for ds in (paper_map, vertical_map):
        lab = label_regions(ds).transpose("q1", "q2").values
        np.testing.assert_array_equal(lab[0, :], lab[-1, :])
        np.testing.assert_array_equal(lab[:, 0], lab[:, -1])
    assert "q1, q2" in label_regions(paper_map).attrs["description"]
    assert label_regions(paper_map).attrs["wrapped_axes"] == "q1,q2"


def test_open_full_turn_grid_wraps_last_to_first():
    ds = _grid(TWO_CABLES_SPEC, 30, endpoint=False)  # max - min + step = 2 pi
    labels = label_regions(ds)
    reference = _reference_torus_labels(ds.poc.transpose("q1", "q2").values, closed=False)
    _same_partition(labels.values, reference)
    assert labels.attrs["wrapped_axes"] == "q1,q2"


def test_paper_nominal_pose_is_in_a_region(paper_map):
    label = region_of(paper_map, [math.pi / 6, math.pi / 3])
    assert label == 1
    assert region_of(paper_map, {"q1": math.pi / 6, "q2": math.pi / 3}) == label
    assert region_of(paper_map, np.array([math.pi / 6, math.pi / 3])) == label


def _synthetic(poc: np.ndarray, units: str = "rad", closed: bool = True) -> xr.Dataset:
    n1, n2 = poc.shape
    q1 = np.linspace(-math.pi, math.pi, n1, endpoint=closed)
    q2 = np.linspace(0.0, 1.0, n2)
    return xr.Dataset(
        {"poc": (("q1", "q2"), poc.astype(np.int8))},
        coords={
            "q1": ("q1", q1, {"units": units}),
            "q2": ("q2", q2, {"units": "m"}),
        },
        attrs={"axes": ["q1", "q2"], "robot_coordinates": ["q1", "q2"], "base": [0.0, 0.0]},
    )


def test_a_region_across_the_seam_is_one_region_with_a_wrapping_bbox():
    poc = np.full((9, 4), NO)
    poc[:2, 1:3] = YES  # next to q1 = -pi
    poc[-3:, 1:3] = YES  # next to q1 = +pi (the last row is -pi again)
    labels = label_regions(_synthetic(poc))
    assert np.unique(labels.values).tolist() == [0, 1]
    (region,) = _regions(labels)
    assert region["size"] == 8  # rows -pi, -3pi/4, pi/2, 3pi/4: +pi is -pi again
    lo, hi = region["bbox"]["q1"]
    assert region["wraps"] == ["q1"] and lo > hi
    assert lo == pytest.approx(math.pi / 2) and hi == pytest.approx(-3 * math.pi / 4)
    assert region["bbox"]["q2"] == pytest.approx([1 / 3, 2 / 3])
    # a translation never wraps: the same verdicts are two regions
    in_metres = label_regions(_synthetic(poc, units="m"))
    assert [r["size"] for r in _regions(in_metres)] == [6, 4]


def test_seam_pose_is_yes_only_when_both_copies_are():
    poc = np.full((9, 3), NO)
    poc[0, :] = YES  # -pi is YES, its copy at +pi is NO
    labels = label_regions(_synthetic(poc))
    assert not labels.values.any()
    poc[-1, :] = YES
    labels = label_regions(_synthetic(poc))
    assert labels.values[0].tolist() == labels.values[-1].tolist() == [1, 1, 1]


def test_marginal_and_not_analysed_poses_are_in_no_region():
    poc = np.full((9, 3), YES)
    poc[4, :] = 2  # MARGINAL
    poc[:, 2] = -1
    labels = label_regions(_synthetic(poc, closed=False))  # 9 values of an open turn
    assert not labels.values[4].any() and not labels.values[:, 2].any()
    assert len(_regions(labels)) == 1  # joined round the back of the turn


def test_regions_attribute_lists_the_largest():
    poc = np.where(np.add.outer(np.arange(50), np.arange(50)) % 2 == 0, YES, NO)
    labels = label_regions(_synthetic(poc, units="m"))  # every YES pose alone
    assert labels.attrs["n_regions"] == 1250 == labels.values.max()
    regions = _regions(labels)
    assert len(regions) == 1000 and regions[-1]["label"] == 1000
    assert "lists the 1000 largest of 1250" in labels.attrs["description"]


# ---------------------------------------------------------------- sampled


def test_sampled_regions_equal_a_brute_force_graph(sampled_map):
    labels = label_regions(sampled_map)
    assert labels.dims == ("sample",) and labels.attrs["adjacency"] == "radius"
    x = np.stack([sampled_map.q1.values, sampled_map.q2.values], axis=1)
    diff = np.abs(x[:, None, :] - x[None, :, :])
    diff = np.minimum(diff, 2 * math.pi - diff)  # both angles span a full turn
    dist = np.sqrt((diff**2).sum(axis=-1))
    nearest = np.where(np.eye(len(x), dtype=bool), np.inf, dist).min(axis=1)
    radius = labels.attrs["radius"]
    assert radius == pytest.approx(RADIUS_FACTOR * nearest.mean(), rel=1e-12)
    yes = sampled_map.poc.values == YES
    uf = _UnionFind()
    for i, j in zip(*np.nonzero((dist <= radius) & yes[:, None] & yes[None, :]), strict=True):
        uf.union(int(i), int(j))
    reference = np.array([uf.find(i) + 1 if yes[i] else 0 for i in range(len(x))])
    _same_partition(labels.values, reference)
    sizes = [r["size"] for r in _regions(labels)]
    assert sizes == sorted(sizes, reverse=True) and sum(sizes) == yes.sum()
    assert len(sizes) > 1


def test_sampled_radius_is_a_parameter(sampled_map):
    tight = label_regions(sampled_map, radius=0.0)
    assert len(_regions(tight)) == int((sampled_map.poc.values == YES).sum())
    wide = label_regions(sampled_map, radius=10.0)
    assert len(_regions(wide)) == 1
    with pytest.raises(InputError, match="finite distance >= 0"):
        label_regions(sampled_map, radius=-1)
    with pytest.raises(InputError, match="sampled maps only"):
        label_regions(_synthetic(np.full((5, 3), YES)), radius=0.1)


def _one_axis_samples(low, high, n=500, seed=1):
    """The paper's arm sampled along q1 only (q2 at its base value): YES at
    every sample, so any split is the rule's."""
    ds = cdpm.workspace_map(PAPER_SPEC, {"q1": (low, high)}, samples=n, seed=seed, workers=1)
    assert np.all(ds.poc.values == YES)
    return ds


def _with_no_at(ds, samples):
    poc = ds.poc.values.copy()
    poc[samples] = NO
    return ds.assign(poc=(ds.poc.dims, poc, ds.poc.attrs))


def test_one_axis_samples_join_consecutive_samples_only():
    """Over one axis, random samples leave gaps several times their mean:
    the mean-distance radius split 500 YES samples into about 100 regions.
    There only consecutive samples are neighbours, within twice the largest
    gap: one region, across the seam of a full turn; a NO sample always
    separates (the samples either side of it are often closer than the
    radius), and a turn sampled only in part does not close."""
    full = _one_axis_samples(-math.pi, math.pi)
    labels = label_regions(full)
    q1 = full.q1.values
    gaps = np.diff(np.sort(q1))
    assert labels.attrs["adjacency"] == "consecutive" and labels.attrs["n_regions"] == 1
    assert labels.attrs["radius"] == pytest.approx(2 * gaps.max(), rel=1e-12)
    assert gaps.max() > 4 * gaps.mean()  # what the old radius, 3 mean distances, cut at
    assert "full-turn seam" not in labels.attrs["description"]
    order = np.argsort(q1)
    # two NO samples cut the turn into two arcs, whose sizes are the samples between them
    cut = _with_no_at(full, [order[100], order[300]])
    sizes = sorted(r["size"] for r in _regions(label_regions(cut)))
    assert sizes == [199, 299]
    # one NO sample leaves one arc, joined across the seam at +-pi
    one = label_regions(_with_no_at(full, [order[250]]))
    assert one.attrs["n_regions"] == 1 and _regions(one)[0]["wraps"] == ["q1"]
    # a part of a turn: the first and last samples are not neighbours
    part = _one_axis_samples(-1.0, 2.0, n=300)
    order = np.argsort(part.q1.values)
    assert label_regions(part).attrs["n_regions"] == 1
    assert label_regions(_with_no_at(part, [order[120]])).attrs["n_regions"] == 2
    # two samples of an angle: their shorter arc, across the seam; an arc of
    # more than half a turn joins nothing (the step would be drawn the other way)
    from cdpm.maps.regions import MapLayout, sample_edges

    def layout(*q1):
        values = (np.array(q1),)
        return MapLayout("sample", ("q1",), ("sample",), values, ("rad",), ("modulo",), (len(q1),))

    edges, lengths = sample_edges(layout(-3.0, 3.0), np.array([True, True]), radius=1.0)
    assert edges.tolist() == [[0], [1]] and lengths == pytest.approx([2 * math.pi - 6.0])
    edges, _ = sample_edges(layout(-2.9, 1.0, -3.0), np.array([True, True, False]), radius=10.0)
    assert edges.shape[1] == 0  # -2.9 to 1.0 is 3.9 rad one way, through -3.0 the other
    # a path from one end of the turn to the other goes the short way, across the seam
    path = cdpm.poc_path(full, {"q1": -3.0}, {"q1": 3.0})
    steps = np.abs(np.diff(path.coordinates["q1"]))
    assert path.n_waypoints < 40 and steps.max() > 6.0  # one step across the seam


# ------------------------------------------------------- stored variable


def test_attach_regions_writes_the_store_idempotently(tmp_path):
    store = tmp_path / "vertical.zarr"
    axes = {"q1": np.linspace(-math.pi, math.pi, 13), "q2": np.linspace(-math.pi, math.pi, 13)}
    ds = cdpm.workspace_map(VERTICAL_SPEC, axes, workers=1, store=store)
    assert "poc_region" in ds  # the map labels its regions when it completes
    ds = ds.drop_vars("poc_region")
    out = attach_regions(ds, store)
    assert "poc_region" in out and "poc_region" not in ds
    stored = cdpm.open_map(store)
    np.testing.assert_array_equal(stored.poc_region.values, out.poc_region.values)
    assert _regions(stored.poc_region) == _regions(out.poc_region)
    again = attach_regions(stored, store)  # a re-run replaces the labels
    np.testing.assert_array_equal(cdpm.open_map(store).poc_region.values, again.poc_region.values)
    # the store still resumes with the same settings, and keeps its labels
    resumed = cdpm.workspace_map(VERTICAL_SPEC, axes, workers=1, store=store)
    np.testing.assert_array_equal(resumed.poc.values, stored.poc.values)
    assert region_of(str(store), [0.0, math.pi / 2]) == region_of(out, [0.0, math.pi / 2])


def test_old_maps_get_labels_on_the_fly(vertical_map):
    old = vertical_map.drop_vars("poc_region")  # a map from before regions
    with_labels = attach_regions(old)
    vertical_map = old
    for pose in ([0.0, math.pi / 2], [-2.0, -1.0], [2.5, 0.3]):
        assert region_of(vertical_map, pose) == region_of(with_labels, pose)


# ---------------------------------------------------------------- locating


def test_region_of_honours_the_wrap_and_the_axis_ends(paper_map):
    # +pi and -pi are one pose; beyond pi wraps round
    assert region_of(paper_map, [math.pi, 1.0]) == region_of(paper_map, [-math.pi, 1.0])
    assert region_of(paper_map, [math.pi + 0.05, 1.0]) == region_of(paper_map, [-math.pi, 1.0])
    poc = np.full((5, 3), YES)
    ds = _synthetic(poc, units="m")
    assert region_of(ds, [math.pi + 0.7, 0.0]) == 1  # within half a step (pi/4)
    with pytest.raises(InputError, match=r"q1 = 4.*off the map: axis q1 covers"):
        region_of(ds, [4.0, 0.0])
    with pytest.raises(InputError, match=r"pose has 3 value\(s\); give 2"):
        region_of(ds, [0.0, 0.0, 0.0])
    with pytest.raises(InputError, match="not on this map"):
        region_of(ds, {"q1": 0.0, "q3": 0.0})
    with pytest.raises(InputError, match="lacks the map axis"):
        region_of(ds, {"q1": 0.0})
    with pytest.raises(InputError, match="not a number"):
        region_of(ds, ["a", 0.0])


def test_region_of_checks_coordinates_off_the_axes():
    axes = {"q1": np.linspace(0.0, 1.5, 7)}
    ds = cdpm.workspace_map(PAPER_SPEC, axes, base={"q2": math.pi / 3}, workers=1)
    label = region_of(ds, [0.5])
    assert label > 0 and region_of(ds, [0.5, math.pi / 3]) == label
    assert region_of(ds, {"q1": 0.5, "q2": math.pi / 3}) == label
    with pytest.raises(InputError, match="holds q2 at its base value 1.047"):
        region_of(ds, [0.5, 0.2])


def test_region_of_on_a_sampled_map(sampled_map):
    labels = label_regions(sampled_map).values
    i = int(np.flatnonzero(labels == 1)[0])
    pose = [float(sampled_map.q1[i]), float(sampled_map.q2[i])]
    assert region_of(sampled_map, pose) == 1
    ds = sampled_map.isel(sample=np.flatnonzero(sampled_map.q1.values < 0))
    with pytest.raises(InputError, match="off the map: its nearest sample"):
        region_of(ds, [1.5, 0.0])


def test_region_sizes_count_a_seam_pose_once(paper_map):
    # the paper's arm is YES almost everywhere: one region; its size counts
    # the 60 x 60 distinct poses, not the 61 x 61 grid values
    labels = label_regions(paper_map)
    size = _regions(labels)[0]["size"]
    yes = int(np.count_nonzero(paper_map.poc.values == YES))
    distinct_yes = int(np.count_nonzero(paper_map.poc.values[:-1, :-1] == YES))
    assert size <= distinct_yes < yes
    assert "a pose on a full-turn seam" in labels.attrs["description"]
    assert (
        "is counted once, so they can sum to fewer than the YES poses"
        in (labels.attrs["description"])
    )


def test_region_of_takes_a_pose_name_of_the_maps_spec(paper_map, tmp_path):
    assert region_of(paper_map, "nominal") == region_of(paper_map, [math.pi / 6, math.pi / 3])
    with pytest.raises(InputError, match="pose 'home' not in spec"):
        region_of(paper_map, "home")
    moved = paper_map.assign_attrs(spec=str(tmp_path / "gone.yaml"))
    with pytest.raises(InputError, match="spec .*gone.yaml is not found"):
        region_of(moved, "nominal")
