"""One run per map store: a second run on a busy store refuses at once, a
lock left by a killed run is taken over, and the store ends complete."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.maps._lock import StoreBusyError, lock_path, store_lock
from cdpm.verdicts import NOT_ANALYSED, STATUS_CODES
from tests.processes import lock_held_elsewhere

VERTICAL = Path(__file__).parent.parent / "models" / "two_link_vertical"


def _map_command(out: Path, n: int = 61) -> list[str]:
    return [
        sys.executable, "-m", "cdpm", "map", str(VERTICAL),
        "--axis", f"q1=-pi:pi:{n}", "--axis", f"q2=-pi:pi:{n}",
        "--out", str(out), "--workers", "1", "--chunk-size", "256", "--quiet",
    ]  # fmt: skip


def _wait_for(predicate, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return False


@pytest.mark.slow
def test_second_run_on_a_busy_store_refuses(tmp_path):
    out = tmp_path / "busy.zarr"
    first = subprocess.Popen(_map_command(out), stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_for(lambda: (out / ".cdpm" / "created").is_file(), 60)
        start = time.monotonic()
        second = subprocess.run(_map_command(out), capture_output=True, text=True, timeout=60)
        assert second.returncode == 1
        assert time.monotonic() - start < 15
        assert "is being written by another run (pid" in second.stderr
        assert f"pid {first.pid} on" in second.stderr
        assert "Traceback" not in second.stderr
        assert first.wait(timeout=300) == 0, first.stderr.read()
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    ds = cdpm.open_map(out)
    assert int((ds["status"].values == STATUS_CODES["pending"]).sum()) == 0
    assert np.all((ds["poc"].values != NOT_ANALYSED) | (ds["status"].values != 0))
    assert not lock_path(out).exists()


@pytest.mark.slow
def test_lock_of_a_killed_run_is_taken_over_and_the_map_resumes(tmp_path):
    out = tmp_path / "killed.zarr"
    first = subprocess.Popen(_map_command(out), stderr=subprocess.DEVNULL)
    assert _wait_for(lambda: any((out / ".cdpm" / "done").glob("*")), 120)
    first.send_signal(signal.SIGKILL)
    first.wait()
    assert lock_path(out).exists()  # left behind, but no longer locked
    again = subprocess.run(_map_command(out), capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    reference = cdpm.workspace_map(
        VERTICAL,
        {"q1": np.linspace(-np.pi, np.pi, 61), "q2": np.linspace(-np.pi, np.pi, 61)},
        workers=1,
        chunk_size=256,
    )
    resumed = cdpm.open_map(out)
    for name in ("poc", "status", "reach_margin", "y"):
        np.testing.assert_array_equal(resumed[name].values, reference[name].values)


def test_lock_in_process(tmp_path):
    store = tmp_path / "m.zarr"
    with store_lock(store):
        record = json.loads(lock_path(store).read_text())
        assert record["pid"] == os.getpid()
        # a lock is per open file: a second acquisition (as another run would) fails
        assert lock_held_elsewhere(store)
    assert not lock_path(store).exists()


def test_busy_store_error_names_the_fix(tmp_path):
    store = tmp_path / "m.zarr"
    with store_lock(store):
        pid = os.fork()
        if pid == 0:
            try:
                with store_lock(store):
                    os._exit(0)
            except StoreBusyError as exc:
                ok = "wait for it to finish or stop it" in str(exc) and str(os.getppid()) in str(
                    exc
                )
                os._exit(0 if ok else 9)
        _, status = os.waitpid(pid, 0)
        assert os.WEXITSTATUS(status) == 0


@pytest.mark.parametrize("content", ["", "not json", '{"pid": 999999999, "host": "x"}'])
def test_stale_or_garbled_lock_files_are_taken_over(tmp_path, content):
    store = tmp_path / "m.zarr"
    lock_path(store).write_text(content)
    with store_lock(store):
        assert json.loads(lock_path(store).read_text())["pid"] == os.getpid()
