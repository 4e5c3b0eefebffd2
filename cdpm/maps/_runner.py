"""Running map chunks: in-process, in local worker processes, or on Dask.

Every executor runs the same function on the same chunks (the poses of
chunk k come from the :class:`~cdpm.maps._plan.MapPlan`), so results do not
depend on where a chunk ran. With ``workers=N`` locally, N - 1 worker
processes get the plan once and then only chunk indices, and the calling
process computes chunks too while none of theirs is ready; with a zarr
store workers write their own chunks (region and done marker), so the
driver does no serial I/O for them. Dask tasks
return the chunk's arrays and the driver writes them (remote workers may
not see the store).

Workers rebuild the robot from its spec: local processes from the spec
path, Dask workers from the spec and URDF bytes shipped with each task (a
remote worker need not see the driver's files); both check the spec hash.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from cdpm.errors import CdpmError, InputError, MissingExtraError
from cdpm.maps._evaluate import MapJob

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.robot import CableRobot

__all__ = ["RobotSource", "run_chunks", "ProgressPrinter"]


@dataclass(frozen=True)
class RobotSource:
    """How a worker rebuilds the robot: the spec path, its hash, and the
    bytes of the spec and URDF (relative paths under their common folder)."""

    spec_path: str
    sha256: str
    files: tuple[tuple[str, bytes], ...]
    spec_relpath: str

    @classmethod
    def from_robot(cls, robot) -> RobotSource:
        spec = Path(robot.spec.path).resolve()
        urdf = Path(robot.spec.urdf_path).resolve()
        root = Path(os.path.commonpath([spec.parent, urdf.parent]))
        files = tuple((str(p.relative_to(root)), p.read_bytes()) for p in (spec, urdf))
        return cls(str(spec), robot.spec.sha256, files, str(spec.relative_to(root)))

    def load(self):
        """The robot, from the spec path if it is there and unchanged, else
        from the shipped bytes in a temporary folder."""
        from cdpm.robot import load_robot

        if Path(self.spec_path).is_file():
            robot = load_robot(self.spec_path)
            if robot.spec.sha256 == self.sha256:
                return robot
        folder = Path(tempfile.mkdtemp(prefix="cdpm-spec-"))
        for rel, data in self.files:
            target = folder / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        robot = load_robot(folder / self.spec_relpath)
        if robot.spec.sha256 != self.sha256:
            raise CdpmError("the shipped cable spec does not match its hash")  # pragma: no cover
        return robot


# --------------------------------------------------------------------------
# worker side

_LOCAL = threading.local()


def _state(source: RobotSource):
    """The robot of this thread, built once per spec hash (robots hold
    Pinocchio data buffers, so threads do not share them)."""
    cache = getattr(_LOCAL, "cache", None)
    if cache is None:
        cache = _LOCAL.cache = {}
    if source.sha256 not in cache:
        cache[source.sha256] = source.load()
    return cache[source.sha256]


def compute_chunk(source: RobotSource, job: MapJob, index: int, natural) -> tuple[int, dict]:
    """Evaluate one chunk in a worker; returns (index, arrays)."""
    with single_threaded_blas():
        return index, job.evaluate(_state(source), natural)


#: what a local worker process computes: set once by :func:`_init_process`
_WORKER: dict = {}


def single_threaded_blas():
    """A context limiting BLAS to one thread (threadpoolctl, when installed).

    Maps run a great many tiny linear-algebra calls, which a multithreaded
    BLAS only slows down (its threads spin between calls, and worker
    processes already use the cores). SciPy's own BLAS is loaded first so
    that the limit covers it too.
    """
    import contextlib

    import scipy.linalg  # noqa: F401 - load SciPy's BLAS before limiting it

    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional (the maps extra has it)
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _init_process(source: RobotSource | None = None, plan=None, job=None, writer=None) -> None:
    # Ctrl-C goes to the whole process group: the driver handles it and
    # stops the workers, which must not print tracebacks of their own
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER["blas"] = single_threaded_blas()  # for the life of the worker
    if source is not None:
        _WORKER.update(robot=_state(source), plan=plan, job=job, writer=writer)


def _process_chunk(index: int) -> tuple[int, dict | None]:
    """Compute chunk ``index`` in a local worker process; with a writer the
    worker stores it itself (data and done marker) and returns no data."""
    plan, writer = _WORKER["plan"], _WORKER["writer"]
    data = _WORKER["job"].evaluate(_WORKER["robot"], plan.natural(index))
    if writer is None:
        return index, data
    writer.write(index, data)
    return index, None


# --------------------------------------------------------------------------
# progress


class ProgressPrinter:
    """A one-line progress bar on stderr: poses done, poses/s and ETA.

    Args:
        total: number of poses to compute in this run.
        label: text before the bar.
        stream: where to print (stderr by default).
        interval: seconds between redraws.
    """

    def __init__(self, total: int, label: str = "map", stream=None, interval: float = 0.2):
        self.total, self.label = total, label
        self.stream = stream or sys.stderr
        self.interval = interval
        self.start = time.perf_counter()
        self.last = 0.0
        self.done = 0

    def __call__(self, done: int, total: int, index: int | None = None) -> None:
        self.done, self.total = done, total
        now = time.perf_counter()
        if now - self.last >= self.interval or done >= total:
            self.last = now
            self._draw(now)

    def _draw(self, now: float) -> None:
        elapsed = max(now - self.start, 1e-9)
        rate = self.done / elapsed
        frac = self.done / self.total if self.total else 1.0
        width = 24
        bar = "#" * int(round(frac * width))
        eta = (self.total - self.done) / rate if rate > 0 else float("nan")
        text = (
            f"\r{self.label} [{bar:<{width}}] {self.done}/{self.total} poses "
            f"{100 * frac:5.1f}%  {rate:,.0f} poses/s  ETA {_clock(eta)}"
        )
        self.stream.write(text)
        if self.done >= self.total:
            self.stream.write(f"  done in {_clock(elapsed)}\n")
        self.stream.flush()


def _clock(seconds: float) -> str:
    if seconds != seconds or seconds == float("inf"):
        return "--:--"
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


# --------------------------------------------------------------------------
# driver side


def run_chunks(
    robot,
    plan,
    job,
    todo: list[int],
    sink,
    workers: int,
    scheduler,
    progress: Callable[[int, int, int], None] | None,
) -> None:
    """Compute the chunks ``todo`` and write each to ``sink`` as it finishes;
    ``job`` is the :class:`~cdpm.maps._evaluate.MapJob` every chunk runs."""
    total = sum(plan.chunk_size(k) for k in todo)
    state = {"done": 0}

    def finished(index: int, data: dict | None) -> None:
        if data is not None:  # None: a worker wrote the chunk itself
            sink.write(index, data)
        state["done"] += plan.chunk_size(index)
        if progress is not None:
            progress(state["done"], total, index)

    if progress is not None:
        progress(0, total, -1)
    if not todo:
        return
    with single_threaded_blas():
        _run(robot, plan, job, todo, sink, workers, scheduler, finished)


def _run(robot: CableRobot, plan, job, todo, sink, workers, scheduler, finished) -> None:
    if scheduler is not None:
        _run_dask(robot, plan, job, todo, finished, scheduler)
    elif workers <= 1 or len(todo) == 1:
        for index in todo:
            finished(index, job.evaluate(robot, plan.natural(index)))
    else:
        writer = getattr(sink, "writer", None)
        _run_processes(robot, plan, job, todo, finished, workers, writer)


#: modules the fork server imports once, so that workers start warm
_PRELOAD = [
    "cdpm.maps._evaluate",
    "cdpm.maps._store",
    "cdpm.analysis",
    "cdpm.analysis.batch",
    "cdpm.equilibrium",
    "cdpm.linearisation",
    "pinocchio",
    "zarr",
]


def _context():
    methods = multiprocessing.get_all_start_methods()
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD + ["cdpm.maps._runner"])
        return ctx
    return multiprocessing.get_context("spawn")


_FORK_SERVER: dict = {}


def _start_fork_server(ctx) -> threading.Thread | None:
    """Start the fork server (with its preloaded modules) in a thread, once
    per process; returns that thread."""
    if ctx.get_start_method() != "forkserver":
        return None
    thread = _FORK_SERVER.get("thread")
    if thread is None:
        from multiprocessing import forkserver

        thread = threading.Thread(target=forkserver.ensure_running, daemon=True)
        thread.start()
        _FORK_SERVER["thread"] = thread
    return thread


def prestart_workers() -> None:
    """Start what local worker processes are forked from (the fork server
    importing Pinocchio, zarr and cdpm) in the background now, so that it
    is ready when the first chunks are handed out."""
    _start_fork_server(_context())


def _run_processes(robot: CableRobot, plan, job, todo, finished, workers: int, writer=None) -> None:
    """Chunks on ``workers - 1`` local worker processes plus this process.

    Each worker builds the robot once (initializer) and then gets only
    chunk indices; with a ``writer`` (a store on this file system) workers
    write their chunks themselves. This process computes a chunk whenever
    none of the workers' chunks is ready, so the workers' start-up overlaps
    useful work and small maps gain from workers too.
    """
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    source = RobotSource.from_robot(robot)
    pending = list(reversed(todo))
    n_proc = min(workers - 1, len(todo) - 1)
    ctx = _context()
    executor = ProcessPoolExecutor(
        max_workers=n_proc,
        mp_context=ctx,
        initializer=_init_process,
        initargs=(source, plan, job, writer),
    )
    # the fork server imports its modules before it forks a worker: start it
    # in the background (the first submit would wait for it) and compute
    # chunks here meanwhile
    starting = _start_fork_server(ctx)
    running = set()
    try:
        while pending or running:
            if starting is None or not starting.is_alive():
                while pending and len(running) < 2 * n_proc:
                    running.add(executor.submit(_process_chunk, pending.pop()))
            done, running = wait(running, timeout=0, return_when=FIRST_COMPLETED)
            if not done and pending:  # nothing ready: compute one here
                index = pending.pop()
                data = job.evaluate(robot, plan.natural(index))
                finished(index, data)
                continue
            if not done:
                done, running = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                finished(*future.result())
    except BaseException as exc:
        for future in running:
            future.cancel()
        # stop the workers now rather than after their current chunk
        for process in list(getattr(executor, "_processes", {}).values()):
            process.terminate()
        executor.shutdown(wait=False, cancel_futures=True)
        if isinstance(exc, BrokenProcessPool):
            raise CdpmError(
                "a map worker process stopped unexpectedly (its message is above). If a script "
                "calls workspace_map at its top level, put the call under "
                '`if __name__ == "__main__":`: local workers import the script; workers=1 '
                "runs without worker processes. Finished chunks stay in the store: re-running "
                "resumes."
            ) from exc
        raise
    executor.shutdown(wait=True)


def _run_dask(robot: CableRobot, plan, job, todo, finished, scheduler) -> None:
    try:
        import distributed
    except ImportError as exc:
        raise MissingExtraError(
            "running a map on a Dask cluster needs dask.distributed: pip install 'cdpm[maps]'"
        ) from exc
    own = isinstance(scheduler, str)
    if own:
        try:
            client = distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise InputError(
                f"cannot reach the Dask scheduler at {scheduler!r}: {exc}; start one with "
                "`dask scheduler` (and workers with `dask worker ADDRESS`) or drop --scheduler "
                "to use local processes"
            ) from exc
    else:
        client = scheduler
    try:
        source = RobotSource.from_robot(robot)
        n_workers = max(1, sum(client.nthreads().values()))
        pending = list(reversed(todo))
        queue = distributed.as_completed()

        def submit() -> None:
            index = pending.pop()
            queue.add(
                client.submit(compute_chunk, source, job, index, plan.natural(index), pure=False)
            )

        for _ in range(min(len(pending), 2 * n_workers)):
            submit()
        for future in queue:
            finished(*future.result())
            future.release()
            if pending:
                submit()
    finally:
        if own:
            client.close()
