"""Killed maps: no process outlives the command, and the resumed map equals
an uninterrupted one value by value."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

import cdpm
from tests.processes import wait_gone

VERTICAL = Path(__file__).parent.parent / "models" / "two_link_vertical"
N = 81


def _command(out: Path) -> list[str]:
    return [
        sys.executable, "-m", "cdpm", "map", str(VERTICAL),
        "--axis", f"q1=-pi:pi:{N}", "--axis", f"q2=-pi:pi:{N}",
        "--out", str(out), "--workers", "2", "--chunk-size", "256", "--quiet",
    ]  # fmt: skip


@pytest.fixture(scope="module")
def reference():
    axes = {"q1": np.linspace(-np.pi, np.pi, N), "q2": np.linspace(-np.pi, np.pi, N)}
    return cdpm.workspace_map(VERTICAL, axes, workers=1, chunk_size=256)


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs /proc")
@pytest.mark.parametrize("trial", range(4))
def test_killed_map_leaves_no_process_and_resumes_exactly(tmp_path, reference, trial):
    rng = random.Random(trial)
    how = (signal.SIGKILL, signal.SIGTERM)[trial % 2]
    out = tmp_path / "m.zarr"
    marker = uuid.uuid4().hex
    # a process killed with SIGKILL leaves its temporary folders (Python's
    # multiprocessing makes one): in tmp_path, not in the system's
    env = {**os.environ, "CDPM_TEST_MARK": marker, "TMPDIR": str(tmp_path)}
    run = subprocess.Popen(_command(out), env=env, stderr=subprocess.PIPE, text=True)
    # kill once some chunks are done, at a random moment after
    end = time.monotonic() + 120
    while time.monotonic() < end and not any((out / ".cdpm" / "done").glob("*")):
        time.sleep(0.05)
    time.sleep(rng.uniform(0.0, 1.0))
    run.send_signal(how)
    code = run.wait(timeout=60)
    stderr = run.stderr.read()
    if how == signal.SIGTERM and code != 0:
        assert code == 130, stderr
        assert "interrupted" in stderr and "Traceback" not in stderr
    left = wait_gone(marker, 5.0)
    assert not left, f"processes left after {how.name}: {left}"
    again = subprocess.run(_command(out), env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert not wait_gone(marker, 5.0)
    resumed = cdpm.open_map(out)
    for name in ("poc", "status", "reach_margin", "y", "tension_max"):
        np.testing.assert_array_equal(resumed[name].values, reference[name].values, err_msg=name)


def test_run_killed_while_labelling_regions_resumes(tmp_path):
    """A run killed while it wrote ``poc_region`` leaves the array on disk but
    not in the consolidated metadata; the next run rewrites it."""
    import json

    out = tmp_path / "m.zarr"
    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(-3, 3, 9)}
    first = cdpm.workspace_map(VERTICAL, axes, store=out, workers=1)
    meta = json.loads((out / "zarr.json").read_text())
    meta["consolidated_metadata"]["metadata"].pop("poc_region")
    (out / "zarr.json").write_text(json.dumps(meta))
    again = cdpm.workspace_map(VERTICAL, axes, store=out, workers=1)
    np.testing.assert_array_equal(again["poc_region"].values, first["poc_region"].values)


def test_an_interrupted_store_write_stops_before_the_interrupt_goes_on():
    """Ctrl-C (or SIGTERM, read as Ctrl-C) while a store write runs in
    zarr's event loop: the write is cancelled and has stopped when the
    interrupt reaches the caller. Before, it ran on, and zarr's exit
    handler, closing its loop 0.2 s later, printed "Cannot close a running
    event loop" when the write was slower than that (a loaded machine)."""
    import asyncio

    from cdpm.maps._zarr_calls import sync

    stopped = []

    async def slow_write():
        try:
            await asyncio.sleep(5.0)
        finally:
            stopped.append(time.monotonic())

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.2)
        start = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            sync(slow_write())
        assert stopped, "the write was still running when the interrupt went on"
        assert stopped[0] - start < 2.0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("twice", [False, True], ids=["once", "again-while-closing"])
def test_an_interrupt_while_the_store_is_written_waits_for_its_files(tmp_path, monkeypatch, twice):
    """A new store's files are written by a thread while the first chunk is
    computed. Ctrl-C while the run waits for them (a slow disk) reaches the
    caller only once they are written and the thread has ended (also when
    a second Ctrl-C comes while it waits again): no write outlives the run
    or its lock, and the next run resumes the store. Before, the interrupted
    wait let the thread write on into the store the next run made."""
    import threading

    import cdpm.maps._filestore
    from cdpm.maps import _store

    write = cdpm.maps._filestore.write_new_file
    alarms = [0.1, 0.05] if twice else [0.05]

    def slow(path, data):  # 27 files: about half a second
        if len(alarms) == (2 if twice else 1):  # the first file: an interrupt soon
            signal.setitimer(signal.ITIMER_REAL, alarms.pop())
        time.sleep(0.02)
        write(path, data)

    monkeypatch.setattr(cdpm.maps._filestore, "write_new_file", slow)

    def interrupt(signum, frame):
        if alarms:
            signal.setitimer(signal.ITIMER_REAL, alarms.pop())
        raise KeyboardInterrupt

    out = tmp_path / "m.zarr"
    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    cdpm.workspace_map(VERTICAL, axes, workers=1)  # imports: not in the half second
    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            cdpm.workspace_map(VERTICAL, axes, store=out, workers=1)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert not [t for t in threading.enumerate() if t.name == "cdpm-store-files"]
    assert (out / ".cdpm" / "created").is_file()  # every file written
    assert not alarms  # each interrupt came while the run waited
    monkeypatch.setattr(cdpm.maps._filestore, "write_new_file", write)
    again = cdpm.workspace_map(VERTICAL, axes, store=out, workers=1)
    assert "chunks" in again["poc"].encoding  # the store was resumed, not made again
    np.testing.assert_array_equal(
        again["poc"].values, cdpm.workspace_map(VERTICAL, axes, workers=1)["poc"].values
    )
    assert _store.INTERRUPT_SETTLE_SECONDS > 1  # the waits above stayed well within it


def test_a_map_goes_into_an_empty_folder(tmp_path):
    """An empty folder at the store's path (made for the map, or left by a
    run killed at once) takes the map, without --overwrite."""
    out = tmp_path / "m.zarr"
    out.mkdir()
    axes = {"q1": np.linspace(-3, 3, 5), "q2": np.linspace(0, 1, 4)}
    ds = cdpm.workspace_map(VERTICAL, axes, store=out, workers=1)
    assert (out / ".cdpm" / "created").is_file() and ds.sizes["q1"] == 5


@pytest.mark.parametrize("given", ["maker", "coroutine"])
def test_an_interrupt_before_a_store_write_starts_leaves_no_coroutine_behind(monkeypatch, given):
    """Ctrl-C before a store write reaches zarr's event loop (the loop
    starting, an import): the write never starts, and no "coroutine ... was
    never awaited" warning follows it (it did, from the store's skeleton,
    on a Ctrl-C in a map's first half second)."""
    import gc
    import warnings

    from zarr.core import sync as zarr_sync

    from cdpm.maps._zarr_calls import sync

    started = []

    async def write():
        started.append(True)

    def interrupted(coro, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(zarr_sync, "sync", interrupted)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(KeyboardInterrupt):
            sync(write if given == "maker" else write())
        gc.collect()
    assert not started
    assert [str(w.message) for w in caught if "never awaited" in str(w.message)] == []


def test_the_fork_server_ignores_ctrl_c_only_while_it_imports():
    """The fork server of local workers imports its modules with Ctrl-C
    ignored (an early Ctrl-C printed its traceback beside the map's
    one-line message) and gives Ctrl-C back to Python's handler after them;
    a process importing the two modules, as the server does, ends with
    Python's handler."""
    from multiprocessing import forkserver

    from cdpm.maps import _workers

    _workers._context(kernels=True)  # sets the fork server's imports
    preload = forkserver._forkserver._preload_modules
    assert preload[0] == _workers._QUIET_START and preload[-1] == _workers._QUIET_END
    code = (
        "import signal, importlib\n"
        f"importlib.import_module({_workers._QUIET_START!r})\n"
        "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)\n"
        f"importlib.import_module({_workers._QUIET_END!r})\n"
        "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "True"]
