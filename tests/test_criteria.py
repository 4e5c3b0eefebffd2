"""The criteria registry: every map variable comes from it, and a new
criterion is a function plus an entry (here: n_taut, and one registered by
the test itself)."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.pipeline.criteria import CRITERIA, Criterion, PoseBatch, register, verdict_criteria
from tests.conftest import MODELS

VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
SPATIAL = MODELS / "spatial_8cable" / "spatial_8cable.yaml"


def _poses(robot, n, seed, spread=0.3):
    base = robot.to_natural(next(iter(robot.poses.values())))
    return base + np.random.default_rng(seed).uniform(-spread, spread, (n, robot.nv))


@pytest.mark.parametrize("spec", [VERTICAL, SPATIAL], ids=["vertical", "spatial"])
def test_n_taut_counts_the_free_inputs_of_linearise(spec):
    """n_taut equals the number of taut cables (f* > 0) of cdpm.linearise's
    equilibrium at each pose, and -1 where there is no equilibrium."""
    robot = cdpm.load_robot(spec)
    natural = _poses(robot, 12, seed=3)
    out = cdpm.evaluate_poses(robot, natural)
    assert out["n_taut"].dtype == np.int16
    checked = 0
    for x, n_taut, status in zip(natural, out["n_taut"], out["status"], strict=True):
        if status != cdpm.STATUS_CODES["ok"]:
            assert n_taut == -1
            continue
        lin = cdpm.linearise(robot, robot.from_natural(x))
        assert n_taut == np.count_nonzero(lin.tension > 0)
        assert n_taut == np.count_nonzero(lin.equilibrium.taut)
        checked += 1
    assert checked >= 4
    # gravity needs taut cables: every analysed pose has some
    assert np.all(out["n_taut"][out["status"] == 0] >= 1)


def test_n_taut_is_zero_at_zero_tension(paper_robot):
    natural = np.random.default_rng(0).uniform(-np.pi, np.pi, (50, 2))
    out = cdpm.evaluate_poses(paper_robot, natural)
    np.testing.assert_array_equal(out["n_taut"], 0)


def test_map_variables_and_attributes_come_from_the_registry(paper_robot):
    ds = cdpm.workspace_map(paper_robot, {"q1": [0.1, 0.5], "q2": [1.0, 2.0, 3.0]}, workers=1)
    # plus the region labels: a whole-map quantity, labelled once the chunks are done
    assert set(ds.data_vars) == set(CRITERIA) | {"poc_region"}
    for name, criterion in CRITERIA.items():
        attrs = ds[name].attrs
        assert attrs["long_name"] == criterion.attrs(paper_robot)["long_name"]
        if criterion.flags is not None:
            assert attrs["flag_values"] == list(criterion.flags.values())
        if criterion.units is not None:
            assert attrs["units"] == criterion.units
        assert ds[name].dtype == np.dtype(criterion.dtype)
    assert ds["output_frame_position"].attrs["frame"] == "tip"
    assert "n_taut" in ds.attrs["cdpm_settings"]


def test_report_shows_every_criterion_as_a_map_would(paper_robot):
    report = cdpm.analyze_pose(paper_robot, "nominal")
    assert set(report.criteria) == set(CRITERIA)
    assert report.criteria["poc"] == cdpm.VERDICT_CODES[report.poc.verdict.value]
    assert report.criteria["n_taut"] == 0
    from cdpm.dynamics.reach import reach_margins_at

    r = reach_margins_at(paper_robot, report.linearisation)  # the per-pose linearisation
    assert report.criteria["reach_margin"] == pytest.approx(r.value[0], rel=1e-12)
    text = str(report)
    assert (
        "Map criteria" in text and "n_taut:" in text and "poc:                    yes (1)" in text
    )
    assert report.as_dict()["criteria"]["n_taut"] == 0


def test_plot_help_lists_the_verdict_criteria(capsys):
    from cdpm.cli import main

    with pytest.raises(SystemExit):
        main(["plot", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert ", ".join(verdict_criteria()) in text


def test_a_new_criterion_is_a_function_and_an_entry(paper_robot):
    """Register the smallest singular value of the output Jacobian: maps
    and reports carry it with no other change."""

    def output_sigma_min(batch: PoseBatch) -> np.ndarray:
        jac = batch.kin.output_jacobian  # (N, p, nv)
        return np.linalg.svd(jac, compute_uv=False)[:, -1]

    register(
        Criterion(
            "output_sigma_min",
            "float64",
            np.nan,
            "smallest singular value of the output Jacobian",
            output_sigma_min,
            units="m",
        )
    )
    try:
        with pytest.raises(ValueError, match="already registered"):
            register(CRITERIA["output_sigma_min"])
        q1, q2 = 0.3, 1.1
        ds = cdpm.workspace_map(paper_robot, {"q1": [q1], "q2": [q2]}, workers=1)
        # tip x = cos q1 + cos(q1 + q2): its gradient's norm
        expected = np.hypot(np.sin(q1) + np.sin(q1 + q2), np.sin(q1 + q2))
        assert float(ds["output_sigma_min"].values.squeeze()) == pytest.approx(expected, rel=1e-12)
        assert ds["output_sigma_min"].attrs["units"] == "m"
        report = cdpm.analyze_pose(paper_robot, [q1, q2])
        assert report.criteria["output_sigma_min"] == pytest.approx(expected, rel=1e-12)
    finally:
        CRITERIA.pop("output_sigma_min", None)


def test_tol_reaches_maps_and_is_checked(paper_robot):
    ds = cdpm.workspace_map(paper_robot, {"q1": [0.2]}, workers=1, tol=1e-6)
    assert '"tol": 1e-06' in ds.attrs["cdpm_settings"]
    with pytest.raises(cdpm.InputError, match=r"tol must be an angle in \(0, 1\) rad"):
        cdpm.workspace_map(paper_robot, {"q1": [0.2]}, workers=1, tol=-1)


def test_viewer_overlay_colours_any_plotted_criterion(paper_robot):
    from cdpm.verdicts import VERDICT_RGB
    from cdpm.viewer.overlay import color_choices, map_points

    assert {"verdict", "margin", "n_taut", "wrench_closure"} <= set(color_choices())
    ds = cdpm.workspace_map(paper_robot, {"q1": [0.1, 0.5], "q2": [0.5, 2.0]}, workers=1)
    _, colors = map_points(ds, color_by="wrench_closure")
    codes = ds["wrench_closure"].transpose("q1", "q2").values.reshape(-1)
    np.testing.assert_allclose(colors, [VERDICT_RGB[int(c)] for c in codes])
    _, blue = map_points(ds, color_by="tension_max")  # all 0 N: one colour
    assert np.allclose(blue, blue[0])
    with pytest.raises(cdpm.InputError, match="use one of verdict, margin, poc"):
        map_points(ds, color_by="y")


def test_register_refuses_what_maps_cannot_store():
    def zeros(batch):
        return np.zeros(len(batch))

    with pytest.raises(ValueError, match="already registered; pass replace=True"):
        register(CRITERIA["n_taut"])
    with pytest.raises(ValueError, match=r"extra dimensions \['joint'\] are not supported"):
        register(Criterion("per_joint", "float64", np.nan, "x", zeros, dims=("joint",)))
    with pytest.raises(ValueError, match="is not a numpy dtype"):
        register(Criterion("odd", "nonsense", 0, "x", zeros))
    with pytest.raises(ValueError, match="must be an identifier"):
        register(Criterion("two words", "float64", 0, "x", zeros))
    assert "per_joint" not in CRITERIA and "odd" not in CRITERIA
    # replace=True: the same name again (a notebook cell run twice)
    entry = CRITERIA["n_taut"]
    assert register(entry, replace=True) is entry


def test_a_worker_without_a_criterion_says_how_to_register_it(paper_robot):
    from cdpm.pipeline.evaluate import MapJob

    job = MapJob("min_norm", True, 1e-9, (*CRITERIA, "defined_in_main_only"))
    with pytest.raises(cdpm.InputError, match=r"'defined_in_main_only' are not registered"):
        job.evaluate(paper_robot, np.zeros((1, 2)))


def test_evaluate_poses_checks_its_input(paper_robot):
    with pytest.raises(cdpm.InputError, match=r"shape \(N, 2\)"):
        cdpm.evaluate_poses(paper_robot, np.zeros((3, 3)))
    with pytest.raises(cdpm.InputError, match="non-finite"):
        cdpm.evaluate_poses(paper_robot, np.array([[0.0, np.nan]]))
    with pytest.raises(cdpm.InputError, match="tol must be an angle"):
        cdpm.evaluate_poses(paper_robot, np.zeros((1, 2)), tol=5)
    one = cdpm.evaluate_poses(paper_robot, np.array([0.5, 1.0]))  # one pose, flat
    assert one["poc"].shape == (1,)
    with pytest.raises(cdpm.InputError, match=r"pose 1: pose 'nope' not in spec"):
        cdpm.evaluate_poses(paper_robot, ["nominal", "nope"])
    with pytest.raises(cdpm.InputError, match=r"pose 0: 'q9' is not a joint or coordinate"):
        cdpm.evaluate_poses(paper_robot, [{"q9": 1.0}])


def test_evaluate_poses_takes_poses_as_the_per_pose_functions_do(paper_robot):
    # pose names, {coordinate: value} (others 0, as in a spec's poses),
    # natural coordinates and arithmetic strings, in one list: the same
    # values as the array of their natural coordinates
    nominal = paper_robot.to_natural(paper_robot.configuration("nominal"))
    poses = ["nominal", {"q1": 0.5}, [0.5, 1.0], ["pi/6", "pi/3"]]
    mixed = cdpm.evaluate_poses(paper_robot, poses)
    array = np.array([nominal, [0.5, 0.0], [0.5, 1.0], [np.pi / 6, np.pi / 3]])
    plain = cdpm.evaluate_poses(paper_robot, array)
    for name in plain:
        np.testing.assert_array_equal(mixed[name], plain[name], err_msg=name)
    alone = cdpm.evaluate_poses(paper_robot, "nominal")
    np.testing.assert_array_equal(alone["reach_margin"], plain["reach_margin"][:1])
    assert cdpm.evaluate_poses(paper_robot, [])["poc"].shape == (0,)  # no poses, as a list
    names = cdpm.evaluate_poses(paper_robot, np.array(["nominal", "nominal"]))  # numpy strings
    np.testing.assert_array_equal(names["reach_margin"], plain["reach_margin"][[0, 0]])
    # strings that are numbers are coordinates: one pose, not two pose names
    one = cdpm.evaluate_poses(paper_robot, ["pi/6", "pi/3"])
    np.testing.assert_array_equal(one["reach_margin"], plain["reach_margin"][3:])


def test_arrays_read_strings_as_single_numbers_are_read():
    from cdpm.errors import float_array

    np.testing.assert_array_equal(
        float_array([["pi/2", 0.1], ["2*pi/3", 1.0000000000000002]]),
        [[np.pi / 2, 0.1], [2 * np.pi / 3, 1.0000000000000002]],  # numbers stay exact
    )
    np.testing.assert_array_equal(float_array(np.array(["0.5", "-1e-300"])), [0.5, -1e-300])
    for bad, message in ((["pi", True], "booleans are not numbers"), (["x"], "'x' is not")):
        with pytest.raises(ValueError, match=message):
            float_array(bad)
    # numpy reads [True, 0.5] as [1.0, 0.5] and bytes as strings; 10**400 overflows
    for bad, message in (
        ([True, 0.5], "booleans are not numbers"),
        ([[0.1, np.True_], [0.2, 0.3]], "booleans are not numbers"),
        ([b"1"], "bytes are not numbers"),
        (bytearray(b"12"), "bytes are not numbers"),  # numpy read [49, 50]
        ([memoryview(b"1")], "bytes are not numbers"),
        (np.array([True, 0.5], dtype=object), "booleans are not numbers"),
        ([np.array([True, 0.5], dtype=object)], "booleans are not numbers"),
    ):
        with pytest.raises(TypeError, match=message):
            float_array(bad)
    with pytest.raises(ValueError, match="too large for a float"):
        float_array([10**400, 1])
    with pytest.raises(cdpm.InputError, match=r"'x' is not a number"):
        cdpm.analyze_pose(cdpm.load_robot(MODELS / "two_link_vertical"), ["x", 0.2])


def test_pretension_method_without_pretension_warns(paper_robot):
    with pytest.warns(cdpm.EquilibriumWarning, match="pretension of 0 N is the 'min_norm'"):
        cdpm.evaluate_poses(paper_robot, np.zeros((1, 2)), "pretension")


def test_analysis_without_outputs_is_trivially_poc():
    from cdpm.analysis.batch import analyse_systems

    A = np.zeros((2, 4, 4))
    A[:, 0, 2] = A[:, 1, 3] = 1.0
    B = np.zeros((2, 4, 3))
    B[:, 2:] = np.random.default_rng(0).normal(size=(2, 2, 3))
    res = analyse_systems(A, B, np.zeros((2, 0, 4)), np.ones((2, 3), bool))
    np.testing.assert_array_equal(res.poc, cdpm.VERDICT_CODES["yes"])
    for i in range(2):
        one = cdpm.positive_controllability(A[i], B[i])
        assert res.positive_controllable[i] == cdpm.VERDICT_CODES[one.verdict.value]
