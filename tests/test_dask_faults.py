"""Dask faults during a map: a killed worker is restarted by its nanny and
the map completes; a lost scheduler is one clear error with the resume
hint, and the map resumes on a new scheduler. Every process started here
is stopped, and checked gone."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.errors import InputError
from tests.processes import wait_gone

pytest.importorskip("distributed")

VERTICAL = Path(__file__).parent.parent / "models" / "two_link_vertical"
AXES = {"q1": np.linspace(-np.pi, np.pi, 41), "q2": np.linspace(-np.pi, np.pi, 41)}
DASK = Path(sys.executable).with_name("dask")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _children(pid: int) -> list[int]:
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(stat[1]) == pid and stat[0] not in ("Z", "X"):
                out.append(int(entry.name))
    return out


def _resume_exactly(marker: str, store: Path, reference) -> None:
    """Resume the map on a new cluster: the same values as the reference,
    and no marked process left afterwards."""
    second = Cluster(marker)
    try:
        ds = cdpm.workspace_map(
            VERTICAL, AXES, scheduler=second.address, chunk_size=128, store=store
        )
        _same(ds, reference)
    finally:
        second.stop()
    assert not wait_gone(marker)


class Cluster:
    """A `dask scheduler` and one `dask worker` (with its nanny) as processes."""

    def __init__(self, marker: str):
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        env = {**os.environ, "CDPM_TEST_MARK": marker}
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
        self.scheduler = subprocess.Popen(
            [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
             "--no-dashboard"], start_new_session=True, **quiet,
        )  # fmt: skip
        self._wait_port()
        self.nanny = subprocess.Popen(
            [str(DASK), "worker", self.address, "--nworkers", "1", "--nthreads", "1",
             "--no-dashboard"], start_new_session=True, **quiet,
        )  # fmt: skip
        self._wait_worker()

    def _wait_port(self) -> None:
        end = time.monotonic() + 60
        while time.monotonic() < end:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                return
            except OSError:
                time.sleep(0.1)
        raise RuntimeError("dask scheduler did not start")

    def _wait_worker(self) -> None:
        import distributed

        with distributed.Client(self.address, timeout="30s") as client:
            client.wait_for_workers(1, timeout=60)

    def worker_pid(self) -> int:
        end = time.monotonic() + 30
        while time.monotonic() < end:
            kids = _children(self.nanny.pid)
            grandkids = [g for k in kids for g in _children(k)]
            # the nanny is the `dask worker` process (or its child); the worker its child
            for pid in grandkids or kids:
                return pid
            time.sleep(0.1)
        raise RuntimeError("no worker process")

    def stop(self) -> None:
        for proc in (self.nanny, self.scheduler):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in (self.nanny, self.scheduler):
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


@pytest.fixture(scope="module")
def reference():
    return cdpm.workspace_map(VERTICAL, AXES, workers=1, chunk_size=128)


def _same(a, b) -> None:
    for name in ("poc", "status", "reach_margin", "y"):
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


@pytest.mark.slow
def test_killed_worker_is_restarted_and_the_map_completes(tmp_path, reference):
    marker = uuid.uuid4().hex
    cluster = Cluster(marker)
    try:
        killed = []

        def progress(done, total, index):
            if index >= 0 and not killed:
                pid = cluster.worker_pid()
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)

        ds = cdpm.workspace_map(
            VERTICAL,
            AXES,
            scheduler=cluster.address,
            chunk_size=128,
            store=tmp_path / "w.zarr",
            progress=progress,
        )
        assert killed
        _same(ds, reference)
    finally:
        cluster.stop()
    assert not wait_gone(marker)


@pytest.mark.slow
def test_lost_scheduler_is_one_error_and_the_map_resumes(tmp_path, reference):
    marker = uuid.uuid4().hex
    store = tmp_path / "s.zarr"
    cluster = Cluster(marker)
    try:

        def progress(done, total, index):
            if index >= 0 and cluster.scheduler.poll() is None:
                os.killpg(cluster.scheduler.pid, signal.SIGKILL)

        with pytest.raises(InputError, match="lost the Dask scheduler at .* re-run the same"):
            cdpm.workspace_map(
                VERTICAL,
                AXES,
                scheduler=cluster.address,
                chunk_size=128,
                store=store,
                progress=progress,
            )
    finally:
        cluster.stop()
    assert any((store / ".cdpm" / "done").iterdir())
    _resume_exactly(marker, store, reference)


_LOST_SCHEDULER_SCRIPT = """
import os, signal, sys
import numpy as np
import cdpm
from cdpm.errors import InputError

address, scheduler, store = sys.argv[1], int(sys.argv[2]), sys.argv[3]
axes = {{"q1": np.linspace(-np.pi, np.pi, 41), "q2": np.linspace(-np.pi, np.pi, 41)}}

def progress(done, total, index):
    if index >= 0:
        try:
            os.killpg(scheduler, signal.SIGKILL)
        except ProcessLookupError:
            pass

try:
    cdpm.workspace_map({spec!r}, axes, scheduler=address, chunk_size=128, store=store,
                       progress=progress)
except InputError as exc:
    print(exc, file=sys.stderr)
    sys.exit(1)
"""


@pytest.mark.slow
def test_lost_scheduler_prints_only_cdpms_message(tmp_path, reference):
    """What Dask's client logs while it tries to reconnect to the lost
    scheduler is not printed: the map's stderr is its one message. Before,
    its ERROR lines came first: one, or about 38 with two tracebacks."""
    marker = uuid.uuid4().hex
    store = tmp_path / "q.zarr"
    cluster = Cluster(marker)
    try:
        script = tmp_path / "lost.py"
        script.write_text(_LOST_SCHEDULER_SCRIPT.format(spec=str(VERTICAL)))
        root = str(Path(__file__).resolve().parents[1])
        done = subprocess.run(
            [sys.executable, str(script), cluster.address, str(cluster.scheduler.pid), str(store)],
            env={**os.environ, "CDPM_TEST_MARK": marker, "PYTHONPATH": root},
            capture_output=True,
            text=True,
            timeout=300,
        )
    finally:
        cluster.stop()
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr  # no "distributed.client - ERROR - ..."
    assert lines[-1].startswith("lost the Dask scheduler at ")
    assert "re-run the same command to resume" in lines[-1]
    import logging

    assert not logging.getLogger("distributed.client").filters  # as before the map
    _resume_exactly(marker, store, reference)


@pytest.mark.parametrize(
    ("address", "match"),
    [
        ("garbage", "is not HOST:PORT"),
        ("tcp://127.0.0.1:99999", "outside 1..65535"),
        ("udp://127.0.0.1:8786", "protocol 'udp'"),
        ("tcp://127.0.0.1:x", "is not a number"),
    ],
)
def test_bad_scheduler_addresses_are_refused_before_any_work(tmp_path, address, match):
    store = tmp_path / "never.zarr"
    with pytest.raises(InputError, match=match):
        cdpm.workspace_map(VERTICAL, AXES, scheduler=address, store=store)
    assert not store.exists()


def test_unreachable_scheduler_is_reported_at_once(tmp_path):
    store = tmp_path / "never.zarr"
    start = time.monotonic()
    with pytest.raises(
        InputError,
        match=r"cannot reach the Dask scheduler at tcp://127.0.0.1:\d+ \(Connection refused\)",
    ):
        cdpm.workspace_map(VERTICAL, AXES, scheduler=f"tcp://127.0.0.1:{_free_port()}", store=store)
    assert time.monotonic() - start < 10
    assert not store.exists()
