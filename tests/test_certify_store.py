"""Certified maps run in chunks (cdpm.certify.map.certify_map): the same
boxes whatever the chunks and workers, a zarr store read back exactly
(cdpm.open_certified), resumed after an interrupt, refused with other
settings or of another kind, and locked against a second writer."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

import cdpm
from cdpm.certify.map import CellRunInfo, certify_map, default_chunk_size, open_certified
from cdpm.errors import InputError
from cdpm.maps import StoreSettingsError
from cdpm.maps.runtime import StoreBusyError, store_lock
from cdpm.verdicts import MARGINAL, NO, YES
from tests.conftest import PAPER_SPEC

#: 3 x 3 cells of the paper arm across the edge of its proven-NO patch:
#: YES, NO and undecided boxes, cells bisected up to twice per axis
AXES = {"q1": np.linspace(1.40, 1.50, 4), "q2": np.linspace(1.55, 1.65, 4)}
MIN_FRACTION = 0.25


@pytest.fixture(scope="module")
def planar():
    return cdpm.load_robot(PAPER_SPEC)


@pytest.fixture(scope="module")
def reference(planar):
    """The map in memory, one chunk in this process."""
    return certify_map(planar, AXES, min_fraction=MIN_FRACTION, workers=1, chunk_size=9)


def assert_same_map(a, b) -> None:
    """Equal arrays (values and dtypes) and fields, boxes and proofs."""
    for f in dataclasses.fields(a.boxes):
        x, y = getattr(a.boxes, f.name), getattr(b.boxes, f.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape, f.name
            assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), f.name
        else:
            assert x == y, f.name
    for name in ("base", "lower", "upper", "verdict", "margin_lower", "cell"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name
    assert a.coordinates == b.coordinates and a.wraps == b.wraps and a.units == b.units
    assert a.min_fraction == b.min_fraction
    assert all(np.array_equal(x, y) for x, y in zip(a.edges, b.edges, strict=True))


def test_the_reference_map_has_every_verdict(reference):
    assert {int(v) for v in np.unique(reference.verdict)} == {YES, NO, MARGINAL}
    assert np.all(np.diff(reference.cell) >= 0)  # boxes in the order of their cells
    assert reference.units == ("rad", "rad")
    assert reference.provenance["spec_sha256"] == cdpm.load_robot(PAPER_SPEC).spec.sha256


@pytest.mark.parametrize("chunk_size", [1, 2, 4])
def test_chunks_give_the_same_map(planar, reference, chunk_size):
    m = certify_map(planar, AXES, min_fraction=MIN_FRACTION, workers=1, chunk_size=chunk_size)
    assert_same_map(m, reference)


def test_worker_processes_give_the_same_map(planar, reference):
    runs = []
    m = certify_map(
        planar, AXES, min_fraction=MIN_FRACTION, workers=2, chunk_size=2, announce=runs.append
    )
    assert runs and runs[0].executor == "local" and runs[0].processes == 2
    assert_same_map(m, reference)


def test_store_round_trip(planar, reference, tmp_path):
    store = tmp_path / "c.zarr"
    m = certify_map(planar, AXES, min_fraction=MIN_FRACTION, store=store, workers=1, chunk_size=4)
    assert_same_map(m, reference)
    back = open_certified(store)
    assert_same_map(back, reference)
    assert back.verify(planar)
    assert back.provenance["store"] == str(store)
    assert back.provenance["spec"] == str(PAPER_SPEC)
    assert back.provenance["cdpm_version"] == cdpm.__version__
    assert back.provenance["settings"]["min_fraction"] == MIN_FRACTION
    assert back.provenance["created"].endswith("+00:00")
    # the store is plain zarr: every array beside its attributes
    import zarr

    group = zarr.open_group(str(store), mode="r")
    assert group.attrs["cdpm_kind"] == "certified_map"
    assert json.loads(group.attrs["cdpm_certified_settings"])["chunk_size"] == 4
    reasons = group["reason_code"].attrs["reasons"]
    assert np.array_equal(np.array(reasons)[group["reason_code"][...]], reference.boxes.reason)
    assert group["lower"].shape == (len(reference.boxes), 2)
    assert np.array_equal(group["edges_q2"][...], AXES["q2"])
    # run again: read back, nothing certified
    runs = []
    again = certify_map(
        planar, AXES, min_fraction=MIN_FRACTION, store=store, chunk_size=4, announce=runs.append
    )
    assert runs[0].todo_chunks == 0 and "nothing to compute" in runs[0].lines()[0]
    assert_same_map(again, reference)


def test_an_interrupted_run_resumes_its_missing_chunks(planar, reference, tmp_path):
    store = tmp_path / "c.zarr"

    def stop_after_two(done, total, index):
        if done >= 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as stopped:
        certify_map(
            planar,
            AXES,
            min_fraction=MIN_FRACTION,
            store=store,
            workers=1,
            chunk_size=1,
            progress=stop_after_two,
        )
    assert stopped.value.certified_store == str(store)
    assert sorted(p.name for p in (store / ".cdpm" / "done").iterdir()) == ["0", "1"]
    with pytest.raises(InputError, match=r"not finished \(2 chunk\(s\) done\).*again"):
        open_certified(store)
    runs: list[CellRunInfo] = []
    m = certify_map(
        planar,
        AXES,
        min_fraction=MIN_FRACTION,
        store=store,
        workers=1,
        chunk_size=1,
        announce=runs.append,
    )
    assert (runs[0].done_chunks, runs[0].todo_chunks) == (2, 7)
    assert runs[0].lines()[0].startswith(f"resuming {store}: 2 of 9 chunks done")
    assert_same_map(m, reference)
    assert_same_map(open_certified(store), reference)
    assert not (store / ".cdpm" / "parts").exists()  # the chunks' parts are dropped


def test_other_settings_are_refused_and_overwrite_replaces(planar, tmp_path):
    store = tmp_path / "c.zarr"
    certify_map(planar, AXES, min_fraction=MIN_FRACTION, store=store, workers=1)
    with pytest.raises(StoreSettingsError, match=r"min_fraction: stored 0.25, now 0.5"):
        certify_map(planar, AXES, min_fraction=0.5, store=store, workers=1)
    other = {"q1": np.linspace(1.40, 1.50, 3), "q2": AXES["q2"]}
    with pytest.raises(StoreSettingsError, match=r"axis 'q1': stored 3 cells over") as refused:
        certify_map(planar, other, min_fraction=MIN_FRACTION, store=store, workers=1)
    # the default chunk size follows the grid: not named as a difference of its own
    assert "chunk_size" not in str(refused.value) and "now 2 cells over" in str(refused.value)
    m = certify_map(planar, other, min_fraction=0.5, store=store, workers=1, overwrite=True)
    assert m.provenance["settings"]["min_fraction"] == 0.5
    assert [e.size for e in open_certified(store).edges] == [3, 4]


def test_a_sampled_map_store_is_not_a_certified_one(planar, tmp_path):
    sampled = tmp_path / "m.zarr"
    cdpm.workspace_map(planar, {"q1": [0.4, 0.5], "q2": [1.0, 1.1]}, store=sampled, workers=1)
    with pytest.raises(InputError, match=r"is a sampled map \(made by `cdpm map`\).*open_map"):
        open_certified(sampled)
    with pytest.raises(InputError, match=r"holds a sampled map \(cdpm map\), not a certified"):
        certify_map(planar, AXES, min_fraction=MIN_FRACTION, store=sampled, workers=1)
    certified = tmp_path / "c.zarr"
    certify_map(planar, AXES, min_fraction=MIN_FRACTION, store=certified, workers=1)
    with pytest.raises(InputError, match=r"is a certified map.*cdpm.open_certified"):
        cdpm.open_map(certified)
    with pytest.raises(InputError, match="not found"):
        open_certified(tmp_path / "missing.zarr")


def test_a_second_writer_is_refused(planar, tmp_path):
    store = tmp_path / "c.zarr"
    with store_lock(store), pytest.raises(StoreBusyError, match="being written by another run"):
        certify_map(planar, AXES, min_fraction=MIN_FRACTION, store=store, workers=1)


def test_a_store_named_like_an_image_is_refused(planar, tmp_path):
    with pytest.raises(InputError, match=r"named like an image \(.png\).*c.zarr"):
        certify_map(planar, AXES, store=tmp_path / "c.png")


def test_a_robot_in_neither_case_is_stored_undecided_with_its_reason(tmp_path):
    from tests.conftest import neither_case_spec

    robot = cdpm.load_robot(neither_case_spec(tmp_path))
    store = tmp_path / "v.zarr"
    m = certify_map(robot, {"q1": [0.0, 0.5, 1.0], "q2": [0.0, 1.0]}, store=store, workers=4)
    assert m.verdict.tolist() == [MARGINAL, MARGINAL]
    assert all("under load" in str(r) for r in open_certified(store).boxes.reason)


def test_bad_arguments_are_named(planar):
    with pytest.raises(InputError, match="chunk_size must be a positive integer"):
        certify_map(planar, AXES, chunk_size=0)
    with pytest.raises(InputError, match="workers must be a positive integer"):
        certify_map(planar, AXES, workers=0)
    with pytest.raises(InputError, match="workers=2 counts local processes"):
        certify_map(planar, AXES, workers=2, scheduler="tcp://127.0.0.1:1")
    with pytest.raises(InputError, match="leaves the joint limits"):
        certify_map(planar, {"q1": [0.0, 4.0]})
    with pytest.raises(InputError, match="progress must be"):
        certify_map(planar, AXES, progress="yes")


def test_default_chunk_size_depends_on_the_map_alone():
    assert default_chunk_size(9) == 32
    assert default_chunk_size(61 * 61) == 117
    assert default_chunk_size(10**6) == 256


def test_progress_counts_cells(planar, capsys):
    seen = []
    certify_map(
        planar,
        AXES,
        min_fraction=MIN_FRACTION,
        workers=1,
        chunk_size=4,
        progress=lambda done, total, index: seen.append((done, total)),
    )
    assert seen[-1] == (9, 9) and [d for d, _ in seen] == sorted(d for d, _ in seen)
    certify_map(planar, AXES, min_fraction=MIN_FRACTION, workers=1, chunk_size=4, progress=True)
    err = capsys.readouterr().err
    assert "certifying 9 cells in 3 chunk(s) in this process" in err
    assert "9/9 cells 100.0%" in err


@pytest.mark.slow
def test_a_dask_cluster_gives_the_same_map(planar, reference):
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False) as cluster,
        distributed.Client(cluster) as client,
    ):
        runs = []
        m = certify_map(
            planar,
            AXES,
            min_fraction=MIN_FRACTION,
            scheduler=client,
            chunk_size=2,
            announce=runs.append,
        )
    assert runs[0].executor == "dask"
    assert_same_map(m, reference)


@pytest.mark.slow
def test_a_terminated_command_resumes_to_the_same_map(planar, tmp_path):
    """SIGTERM (read as Ctrl-C) stops `cdpm certify --workers 2` with exit
    130 and how to resume; no process is left, and the same command
    certifies the missing chunks into the map an uninterrupted run makes."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from tests.processes import wait_gone

    store = tmp_path / "c.zarr"
    argv = [sys.executable, "-m", "cdpm", "certify", str(PAPER_SPEC), "--axis", "q1=0.6:2:8"]
    argv += ["--axis", "q2=0.6:2:8", "--out", str(store), "--workers", "2", "--chunk-size", "1"]
    marker = f"certify-{os.getpid()}-{time.monotonic_ns()}"
    env = {**os.environ, "CDPM_TEST_MARK": marker}
    run = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    done = store / ".cdpm" / "done"
    end = time.monotonic() + 120
    while time.monotonic() < end and run.poll() is None:
        if done.is_dir() and sum(1 for _ in done.iterdir()) >= 2:
            break
        time.sleep(0.05)
    run.send_signal(signal.SIGTERM)
    out, err = run.communicate(timeout=60)
    assert not wait_gone(marker)
    if run.returncode == 0:  # finished before the signal: nothing to resume
        pytest.skip("the run ended before it could be stopped")
    assert run.returncode == 130, err
    assert re.search(r"finished chunks? (is|are) kept in", err) and "Traceback" not in err
    n_done = sum(1 for _ in done.iterdir())
    assert 0 < n_done < 64
    again = subprocess.run(argv + ["--quiet"], env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    edges = np.linspace(0.6, 2.0, 9)
    whole = certify_map(planar, {"q1": edges, "q2": edges}, workers=1)
    assert_same_map(open_certified(store), whole)


@pytest.mark.slow
def test_a_script_without_the_main_guard_runs_in_one_process_with_a_warning(tmp_path):
    """As workspace_map: worker processes would run such a script again."""
    import subprocess
    import sys

    script = tmp_path / "unguarded.py"
    script.write_text(
        "import cdpm\n"
        f"m = cdpm.certify_map({str(PAPER_SPEC)!r}, {{'q1': [1.4, 1.45, 1.5]}}, "
        "base=[0.0, 1.6], workers=2, chunk_size=1)\n"
        "print(len(m.boxes))\n"
    )
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "certify_map runs with workers=1, not 2: unguarded.py calls it at line 2" in run.stderr
    assert int(run.stdout.split()[-1]) > 0
