"""``cdpm map``: pretension, gravity and tension-bound overrides, output
checks, where the chunks run, and resuming, on the command line and in
:func:`cdpm.workspace_map`."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from cdpm.errors import InputError
from cdpm.maps import open_map, override_robot, workspace_map
from tests.conftest import MODELS, PAPER_SPEC

VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
#: a small gravity map: 9 x 8 poses, some without an equilibrium
AXES = ["--axis", "q1=-pi:pi:9", "--axis", "q2=0.3:2.8:8"]


def _cli(argv, capsys) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _same_variables(a, b, names=("poc", "static_feasible", "status", "tension_min", "tension_max")):
    for name in names:
        np.testing.assert_allclose(
            np.asarray(a[name].values, dtype=float),
            np.asarray(b[name].values, dtype=float),
            rtol=1e-9,
            atol=1e-9,
            err_msg=name,
        )


# ------------------------------------------------------------------ pretension


@pytest.mark.slow
def test_map_pretension_reaches_every_chunk_and_is_stored(tmp_path, capsys):
    from cdpm.pipeline.criteria import CRITERIA
    from cdpm.pipeline.evaluate import evaluate_batch

    store = tmp_path / "pre.zarr"
    where = ["--out", str(store), "--workers", "2", "--chunk-size", "8", "--quiet"]
    argv = ["map", str(VERTICAL), *AXES, "--tension", "pretension", *where]
    code, out, err = _cli([*argv, "--pretension", "3"], capsys)
    assert code == 0, err
    assert "overrides of two_link_vertical.yaml: pretension 3 N (spec 10 N)" in out
    ds = open_map(store)
    settings = json.loads(ds.attrs["cdpm_settings"])
    assert settings["overrides"] == {"pretension": 3.0}
    assert (
        ds.attrs["pretension"] == 3.0 and json.loads(ds.attrs["overrides"]) == settings["overrides"]
    )
    # every chunk, in the worker process too, used 3 N (the spec says 10 N):
    # the same as the pipeline given pretension=3 directly, pose by pose
    robot = cdpm.load_robot(VERTICAL)
    q1, q2 = np.meshgrid(ds.q1.values, ds.q2.values, indexing="ij")
    natural = np.column_stack([q1.ravel(), q2.ravel()])
    batch = evaluate_batch(robot, natural, "pretension", pretension=3.0, margin=False)
    expected = {name: CRITERIA[name].compute(batch) for name in ("poc", "tension_min", "status")}
    for name, values in expected.items():
        np.testing.assert_allclose(
            np.asarray(ds[name].values, dtype=float).ravel(), values, atol=1e-9, err_msg=name
        )
    ok = ds.status.values == 0
    assert ok.sum() > 10 and np.all(ds.tension_min.values[ok] >= 3 - 1e-6)
    assert np.any(ds.tension_min.values[ok] < 10 - 1e-3)  # not the spec's 10 N
    # a resume with another pretension names the difference in CLI words
    code, out, err = _cli([*argv, "--pretension", "4"], capsys)
    assert code == 1
    assert "- pretension: stored 3 N, now 4 N" in err and "add --overwrite" in err


def test_map_pretension_needs_the_pretension_method(tmp_path, capsys):
    argv = ["map", str(VERTICAL), *AXES, "--out", str(tmp_path / "m.zarr"), "--quiet"]
    code, _, err = _cli([*argv, "--pretension", "5"], capsys)
    assert code == 1
    assert "--pretension 5 only applies to --tension pretension" in err
    code, _, err = _cli([*argv, "--tension", "pretension", "--pretension", "0"], capsys)
    assert code == 1 and "--pretension 0 makes the pretension method the min_norm method" in err
    code, _, err = _cli(
        ["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", "--plot", str(tmp_path / "p.png")]
        + ["--tension", "pretension"],
        capsys,
    )
    assert code == 1 and "add --pretension N" in err
    assert not (tmp_path / "m.zarr").exists() and not (tmp_path / "p.png").exists()
    with pytest.raises(InputError, match="applies only to the 'pretension' method"):
        workspace_map(VERTICAL, {"q1": [0.0]}, tension="min_norm", pretension=5, workers=1)


# ----------------------------------------------------- gravity and tension bounds


def _edited_model(tmp_path, gravity: str, bounds: dict[str, str]):
    """The vertical arm with its YAML edited by hand: the reference the
    overrides must equal."""
    folder = tmp_path / "edited"
    shutil.copytree(VERTICAL.parent, folder)
    spec = folder / VERTICAL.name
    text = spec.read_text().replace("gravity: [0, 0, -9.81]", f"gravity: {gravity}")
    for cable, pair in bounds.items():
        text = text.replace(f"  - name: {cable}\n", f"  - name: {cable}\n    tension: {pair}\n")
    spec.write_text(text)
    return cdpm.load_robot(spec)


@pytest.mark.slow
def test_map_gravity_and_tension_bounds_equal_an_edited_spec(tmp_path, capsys):
    store = tmp_path / "g.zarr"
    plain_argv = ["map", str(VERTICAL), *AXES, "--no-margin", "--out", str(store)]
    plain_argv += ["--workers", "2", "--chunk-size", "8", "--quiet"]
    overrides = ["--gravity", "0", "0", "-4"]
    overrides += ["--tension-bounds", "0:30", "--tension-bounds", "c1=1:inf"]
    code, out, err = _cli([*plain_argv, *overrides], capsys)
    assert code == 0, err
    assert (
        "overrides of two_link_vertical.yaml: gravity [0, 0, -4] m/s^2 (spec [0, 0, -9.81]); "
        "tension bounds [N] c1 [1, inf] (spec [0, inf]), c2 [0, 30] (spec [0, inf])"
    ) in out
    ds = open_map(store)
    settings = json.loads(ds.attrs["cdpm_settings"])
    assert settings["overrides"]["gravity"] == [0.0, 0.0, -4.0]
    assert settings["overrides"]["tension_bounds"] == {
        "c1": [1.0, np.inf],
        "c2": [0.0, 30.0],
        "c3": [0.0, 30.0],
        "c4": [0.0, 30.0],
    }
    assert ds.attrs["gravity"] == [0.0, 0.0, -4.0]
    assert json.loads(ds.attrs["cable_tension_bounds"])["c2"] == [0.0, 30.0]
    edited = _edited_model(
        tmp_path,
        "[0, 0, -4]",
        {"c1": "[1, .inf]", "c2": "[0, 30]", "c3": "[0, 30]", "c4": "[0, 30]"},
    )
    reference = workspace_map(
        edited, {"q1": ds.q1.values, "q2": ds.q2.values}, workers=1, margin=False
    )
    _same_variables(ds, reference)
    # the overrides change the map: with the spec's gravity and bounds it differs
    plain = workspace_map(
        VERTICAL, {"q1": ds.q1.values, "q2": ds.q2.values}, workers=1, margin=False
    )
    assert not np.array_equal(ds.tension_min.values, plain.tension_min.values)
    # resuming without the overrides is refused, naming each one
    code, _, err = _cli(plain_argv, capsys)
    assert code == 1
    assert "- gravity: stored [0, 0, -4] m/s^2, now the spec's" in err
    assert "- tension bounds: stored [N] c1 [1, inf]" in err


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (
            ["--tension-bounds", "c9=0:5"],
            r"no cable named 'c9' in two_link_vertical.yaml; cables: c1",
        ),
        (["--tension-bounds", "5:2"], r"--tension-bounds: tension bounds of cable 'c1': maximum 2"),
        (["--tension-bounds=-1:2"], r"minimum -1 N must be finite and >= 0"),
        (["--tension-bounds", "0-5"], r"expected MIN:MAX \(every cable\) or CABLE=MIN:MAX"),
        (["--tension-bounds", "0:5", "--tension-bounds", "0:6"], r"every cable is given twice"),
        (["--gravity", "0", "0", "x"], r"--gravity 0 0 x: .*give three numbers in m/s\^2"),
    ],
)
def test_map_override_errors_name_the_option(option, message, tmp_path, capsys):
    argv = ["map", str(VERTICAL), *AXES, "--out", str(tmp_path / "m.zarr"), *option, "--quiet"]
    code, out, err = _cli(argv, capsys)
    assert code == 1 and re.search(message, err), err
    assert "=None" not in err and "tension_bounds=" not in err
    assert not (tmp_path / "m.zarr").exists()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("1.5e12", r"--pretension: pretension must be finite, >= 0 and <= 1e\+12 N"),
        ("x", r"--pretension: --pretension takes a tension in N: 'x' is not a number"),
    ],
)
def test_pretension_is_read_and_checked_as_an_option(value, message, tmp_path, capsys):
    argv = ["map", str(VERTICAL), *AXES, "--out", str(tmp_path / "m.zarr"), "--quiet"]
    with pytest.raises(SystemExit) as exit_:  # a usage error, before any work
        main([*argv, "--tension", "pretension", "--pretension", value])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and re.search(message, err), err
    assert not (tmp_path / "m.zarr").exists()
    # arithmetic, as everywhere else (argparse's float refused it)
    code, out, err = _cli([*argv, "--tension", "pretension", "--pretension", "2*pi"], capsys)
    assert code == 0, err


def test_override_robot_keeps_the_robot_and_workers_rebuild_it(paper_robot, tmp_path):
    from cdpm.maps._workers import RobotSource

    robot = override_robot(paper_robot, gravity=[0, -9.81, 0], tension_bounds={"c2": (2, 40)})
    assert np.array_equal(paper_robot.gravity, np.zeros(3))  # the original is unchanged
    assert np.array_equal(paper_robot.model.gravity.linear, np.zeros(3))
    np.testing.assert_array_equal(robot.model.gravity.linear, [0, -9.81, 0])
    assert robot.tension_min[1] == 2 and robot.tension_max[1] == 40
    source = RobotSource.from_robot(robot)
    assert source.overrides == {"gravity": [0.0, -9.81, 0.0], "tension_bounds": {"c2": [2.0, 40.0]}}
    rebuilt = source.load()
    np.testing.assert_array_equal(rebuilt.gravity, robot.gravity)
    np.testing.assert_array_equal(rebuilt.tension_min, robot.tension_min)
    q = [0.3, 1.1]
    np.testing.assert_allclose(rebuilt.gravity_torque(q), robot.gravity_torque(q))
    assert np.any(robot.gravity_torque(q) != 0)
    assert RobotSource.from_robot(paper_robot).overrides == {}
    # a worker without the spec file loads the shipped bytes from a temporary
    # folder, which it deletes (one was left behind per worker process)
    import dataclasses
    import tempfile

    elsewhere = dataclasses.replace(source, spec_path=str(tmp_path / "moved.yaml"))
    before = set(Path(tempfile.gettempdir()).glob("cdpm-spec-*"))
    shipped = elsewhere.load()
    assert set(Path(tempfile.gettempdir()).glob("cdpm-spec-*")) == before
    np.testing.assert_array_equal(shipped.tension_min, robot.tension_min)
    np.testing.assert_allclose(shipped.gravity_torque(q), robot.gravity_torque(q))
    with pytest.raises(InputError, match="maximum 0 N leaves the cable no tension"):
        override_robot(paper_robot, tension_bounds=(0, 0))


# ------------------------------------------------------------- what is kept


@pytest.mark.parametrize(
    ("out", "message"),
    [
        (
            "m.png",
            "--out {d}/m.png: a map store is a zarr directory, not an image (.png): give "
            "--out {d}/m.zarr to keep the map, and --plot {d}/m.png to draw it",
        ),
        ("m.PDF", "not an image (.pdf)"),
        ("m.nc", "not a netCDF file (.nc): give --out {d}/m.zarr"),
    ],
)
def test_map_out_named_like_an_image_is_refused_before_any_work(out, message, tmp_path, capsys):
    import cdpm.maps

    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", "--out", str(tmp_path / out), "--quiet"]
    code, stdout, err = _cli(argv, capsys)
    assert code == 1 and message.format(d=tmp_path) in err, err
    assert stdout == "" and not (tmp_path / out).exists()
    with pytest.raises(InputError, match=r"named like an image \(\.png\).*name it e.g."):
        cdpm.maps.workspace_map(PAPER_SPEC, {"q1": [0.0]}, store=tmp_path / "x.png", workers=1)
    assert not (tmp_path / "x.png").exists()


def test_map_without_out_or_plot_is_refused_before_any_work(capsys, monkeypatch):
    import cdpm.maps

    def not_called(*args, **kwargs):  # pragma: no cover - the test fails if reached
        raise AssertionError("the map was computed")

    monkeypatch.setattr(cdpm.maps, "workspace_map", not_called)
    code, out, err = _cli(["map", str(PAPER_SPEC), "--axis", "q1=0:1:3"], capsys)
    assert code == 1 and out == ""
    assert err.startswith("cdpm map: error: nothing would keep this map: add --out STORE")
    assert "and/or --plot IMAGE (e.g. --plot map.png)" in err


# --------------------------------------------------------- where it runs


def test_map_workers_with_a_scheduler_is_refused(tmp_path, capsys):
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", "--out", str(tmp_path / "m.zarr")]
    argv += ["--scheduler", "tcp://127.0.0.1:1", "--workers", "2", "--quiet"]
    code, _, err = _cli(argv, capsys)
    assert code == 1
    assert "--workers 2 counts local processes, and with --scheduler the Dask cluster's" in err
    assert "leave out --workers" in err and not (tmp_path / "m.zarr").exists()
    with pytest.raises(InputError, match="workers=2 counts local processes"):
        workspace_map(PAPER_SPEC, {"q1": [0.0]}, workers=2, scheduler="tcp://127.0.0.1:1")


@pytest.mark.parametrize(
    ("workers", "line"),
    [
        ("1", "running 3 chunks (12 poses) in this process (no worker processes)"),
        ("2", "running 3 chunks (12 poses) in 2 local processes: this one and 1 worker process"),
        (
            "8",
            "running 3 chunks (12 poses) in 3 local processes: this one and 2 worker "
            "processes (8 asked for; at most one per chunk)",
        ),
    ],
)
def test_map_says_where_the_chunks_run(workers, line, tmp_path, capsys):
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:12", "--out", str(tmp_path / "m.zarr")]
    code, out, err = _cli([*argv, "--chunk-size", "4", "--workers", workers, "--quiet"], capsys)
    assert code == 0, err
    assert line in out.splitlines()


def test_map_on_dask_says_which_scheduler_and_keeps_the_overrides(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")

    argv = ["map", str(VERTICAL), "--axis", "q1=0:2:8", "--base", "q2=1", "--no-margin"]
    argv += ["--gravity", "0", "0", "-4", "--out", str(tmp_path / "d.zarr"), "--chunk-size", "4"]
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        address = cluster.scheduler_address
        code, out, err = _cli([*argv, "--scheduler", address, "--quiet"], capsys)
    assert code == 0, err
    assert f"running 2 chunks (8 poses) on the Dask scheduler {address} (1 worker, 1 thread)" in out
    robot = override_robot(cdpm.load_robot(VERTICAL), gravity=[0, 0, -4])
    axes = {"q1": np.linspace(0, 2, 8)}
    reference = workspace_map(robot, axes, base={"q2": 1.0}, workers=1, margin=False)
    _same_variables(open_map(tmp_path / "d.zarr"), reference)


@pytest.mark.slow
def test_map_resume_and_finished_store_say_so(tmp_path, capsys, monkeypatch):
    import cdpm.maps

    real = cdpm.maps.workspace_map

    def stop_after_one_chunk(robot, axes, **kwargs):
        def progress(done, total, index):
            if index >= 0:
                raise KeyboardInterrupt

        return real(robot, axes, **{**kwargs, "progress": progress})

    store = tmp_path / "m.zarr"
    argv = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:12", "--out", str(store)]
    argv += ["--workers", "1", "--chunk-size", "4"]
    monkeypatch.setattr(cdpm.maps, "workspace_map", stop_after_one_chunk)
    assert _cli(argv, capsys)[0] == 130
    monkeypatch.setattr(cdpm.maps, "workspace_map", real)
    code, out, err = _cli(argv, capsys)
    assert code == 0, err
    lines = out.splitlines()
    assert (
        f"resuming {store}: 1 of 3 chunks done (4 of 12 poses); computing the remaining "
        "2 chunks (8 poses)"
    ) in lines
    assert "running 2 chunks (8 poses) in this process (no worker processes)" in lines
    assert " 8/8 poses" in err and "/12 poses" not in err
    # a finished store: nothing to compute, said so, and still the summary
    code, out, err = _cli([*argv, "--plot", str(tmp_path / "m.png")], capsys)
    assert code == 0, err
    assert (
        f"the store {store} already holds the whole map (3 chunks, 12 poses); nothing to compute"
    ) in out
    assert "two_link_planar.yaml: 12 poses; positive output controllable: yes" in out
    assert f"map read from {store}" in out and f"plot written to {tmp_path / 'm.png'}" in out
    assert "running" not in out and "poses/s" not in err and "0/0" not in err


def test_workspace_map_announces_and_progress_true_prints_it(tmp_path, capsys):
    seen = []
    workspace_map(
        PAPER_SPEC,
        {"q1": np.linspace(0, 1, 8)},
        workers=1,
        chunk_size=4,
        store=tmp_path / "a.zarr",
        announce=seen.append,
    )
    assert [(i.n_chunks, i.done_chunks, i.executor, i.processes) for i in seen] == [
        (2, 0, "this process", 1)
    ]
    capsys.readouterr()
    workspace_map(
        PAPER_SPEC,
        {"q1": np.linspace(0, 1, 8)},
        workers=1,
        chunk_size=4,
        store=tmp_path / "a.zarr",
        progress=True,
    )
    err = capsys.readouterr().err
    assert "already holds the whole map (2 chunks, 8 poses); nothing to compute" in err
    assert "0/0 poses" not in err


def test_progress_is_plain_lines_when_stderr_is_not_a_terminal():
    import io

    from cdpm.maps._progress import ProgressPrinter

    log = io.StringIO()  # not a terminal
    bar = ProgressPrinter(100, stream=log)
    for done in (10, 50, 100):
        bar(done, 100)
    text = log.getvalue()
    assert "\r" not in text
    assert text.endswith("\n") and "100/100 poses" in text and "done in" in text
    # the first update and the last one: the interval keeps logs short
    assert text.count("\n") == 2


@pytest.mark.parametrize("tty", [False, True])
def test_an_interrupted_map_logs_where_it_stopped(tty, monkeypatch):
    """Ctrl-C during a map with progress=True: the bar's last line is the
    state when it stopped (in a log, not the last line of up to
    PROGRESS_LOG_INTERVAL seconds before), ended by a newline."""
    import io

    import cdpm.maps
    from cdpm.maps import _progress

    log = io.StringIO()
    log.isatty = lambda: tty
    monkeypatch.setattr(_progress.sys, "stderr", log)
    real_finished = []

    def run_chunks(robot, plan, job, todo, sink, workers, scheduler, progress, *rest):
        for done in (4, 8, 12):  # 4 poses a chunk; the 2nd and 3rd within the interval
            progress(done, 36, done // 4 - 1)
            real_finished.append(done)
        raise KeyboardInterrupt

    monkeypatch.setattr(cdpm.maps, "run_chunks", run_chunks)
    with pytest.raises(KeyboardInterrupt):
        cdpm.workspace_map(PAPER_SPEC, {"q1": np.linspace(0, 1, 36)}, workers=1, progress=True)
    lines = log.getvalue().replace("\r", "\n").splitlines()
    assert real_finished == [4, 8, 12]
    assert "12/36 poses" in lines[-1] and log.getvalue().endswith("\n")


def test_view_notes_a_map_made_with_other_equilibrium_settings(tmp_path):
    from cdpm.cli.view import map_settings_note

    vertical = cdpm.load_robot(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
    axes = {"q1": [0.2, 0.5], "q2": [1.0]}
    same = cdpm.workspace_map(vertical, axes, workers=1)
    assert map_settings_note(same, vertical) is None
    other = cdpm.workspace_map(vertical, axes, tension="pretension", pretension=5, workers=1)
    note = map_settings_note(other, vertical)
    assert "tension 'pretension'" in note and "pretension 5" in note
    assert "map colours and panel verdicts can differ" in note
