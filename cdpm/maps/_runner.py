"""Running map chunks: in-process, in local worker processes, or on Dask.

Every executor runs the same function on the same chunks (the poses of
chunk k come from the :class:`~cdpm.maps.plan.MapPlan`), so results do not
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

import importlib
import json
import multiprocessing
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from cdpm.errors import CdpmError, InputError, MissingExtraError
from cdpm.numerics import PROGRESS_LOG_INTERVAL
from cdpm.pipeline.compiled import KERNEL_MODULES, load_kernels, notice_on_stderr
from cdpm.pipeline.evaluate import MapJob, single_threaded_blas, zero_equilibrium

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = ["RobotSource", "MapRunInfo", "run_chunks", "ProgressPrinter"]


#: the robot of the spec file with this hash (spec and URDF), as it is: what
#: :meth:`RobotSource.from_robot` compares a robot with (read only), kept so
#: that maps of one model in turn parse its files once
_SPEC_FILE_ROBOTS: dict[str, CableRobot] = {}


@dataclass(frozen=True)
class RobotSource:
    """How a worker rebuilds the robot: the spec path, its hash, the bytes
    of the spec and URDF (relative paths under their common folder), and
    the robot's departures from its spec file (gravity, tension bounds,
    pretension, external wrench: :func:`~cdpm.maps.plan.robot_overrides`)."""

    spec_path: str
    sha256: str
    files: tuple[tuple[str, bytes], ...]
    spec_relpath: str
    overrides: dict = field(default_factory=dict)

    @classmethod
    def from_robot(cls, robot) -> RobotSource:
        from cdpm.maps.plan import robot_overrides

        spec = Path(robot.spec.path).resolve()
        urdf = Path(robot.spec.urdf_path).resolve()
        root = Path(os.path.commonpath([spec.parent, urdf.parent]))
        try:
            files = tuple((str(p.relative_to(root)), p.read_bytes()) for p in (spec, urdf))
        except OSError as exc:
            raise InputError(
                f"cannot read the robot's spec or URDF ({exc}): a map hashes and ships both "
                "files, so load the robot from files that exist"
            ) from exc
        source = cls(str(spec), robot.spec.sha256, files, str(spec.relative_to(root)))
        reference = _SPEC_FILE_ROBOTS.get(source.sha256)
        if reference is None:
            reference = source.load_spec_file()
            _SPEC_FILE_ROBOTS.clear()  # one is enough: maps of one model in turn
            _SPEC_FILE_ROBOTS[source.sha256] = reference
        overrides = robot_overrides(robot, reference)
        return cls(source.spec_path, source.sha256, files, source.spec_relpath, overrides)

    @property
    def key(self) -> str:
        """What identifies the robot: the spec hash and the overrides."""
        return self.sha256 + json.dumps(self.overrides, sort_keys=True)

    def load_spec_file(self):
        """The robot of the spec file as it is (no overrides): from the spec
        path if it is there and unchanged, else from the shipped bytes in a
        temporary folder, deleted once the robot is loaded (a worker loads
        one per process; the folders were left behind in the temporary
        directory)."""
        from cdpm.model.robot import load_robot

        if Path(self.spec_path).is_file():
            robot = load_robot(self.spec_path)
            if robot.spec.sha256 == self.sha256:
                return robot
        with tempfile.TemporaryDirectory(prefix="cdpm-spec-") as name:
            folder = Path(name)
            for rel, data in self.files:
                target = folder / rel
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(data)
            robot = load_robot(folder / self.spec_relpath)
        if robot.spec.sha256 != self.sha256:
            raise CdpmError("the shipped cable spec does not match its hash")  # pragma: no cover
        return robot

    def load(self):
        """The robot: its spec file's, with the overrides applied."""
        from cdpm.maps.plan import override_robot

        robot = self.load_spec_file()
        if not self.overrides:
            return robot
        return override_robot(robot, **self.overrides)


# --------------------------------------------------------------------------
# worker side

_LOCAL = threading.local()


def _state(source: RobotSource):
    """The robot of this thread, built once per spec hash and overrides
    (robots hold Pinocchio data buffers, so threads do not share them)."""
    cache = getattr(_LOCAL, "cache", None)
    if cache is None:
        cache = _LOCAL.cache = {}
    if source.key not in cache:
        cache[source.key] = source.load()
    return cache[source.key]


def compute_chunk(source: RobotSource, job: MapJob, index: int, natural) -> tuple[int, dict]:
    """Evaluate one chunk in a worker; returns (index, arrays)."""
    with single_threaded_blas():
        return index, job.evaluate(_state(source), natural)


#: what a local worker process computes: set once by :func:`_init_process`
_WORKER: dict = {}


def _init_process(
    source: RobotSource | None = None, plan=None, job=None, writer=None, driver: int | None = None
) -> None:
    # Ctrl-C goes to the whole process group: the driver handles it and
    # stops the workers, which must not print tracebacks of their own
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if driver is not None:
        threading.Thread(target=_exit_with_driver, args=(driver,), daemon=True).start()
    _WORKER["blas"] = single_threaded_blas()  # for the life of the worker
    if source is not None:
        _WORKER.update(robot=_state(source), plan=plan, job=job, writer=writer)


#: longest an interrupted map waits for its worker processes to finish
#: starting (the fork server's imports take about a second) before it stops
#: those started [s]
WORKER_START_SECONDS = 30.0

#: how often a worker checks that the process that started it is alive [s]
DRIVER_CHECK_SECONDS = 0.5


def _exit_with_driver(driver: int) -> None:
    """End this worker soon after the process that started it ends, however
    it ends (SIGKILL leaves it no chance to stop its workers): a chunk being
    written then has no done marker, so a resumed map recomputes it."""
    while _process_alive(driver):
        time.sleep(DRIVER_CHECK_SECONDS)
    os._exit(0)


def _process_alive(pid: int) -> bool:
    """True while process ``pid`` runs (a zombie, dead but not yet reaped,
    counts as ended)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            state = stat.read().rsplit(b")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True
    return state not in (b"Z", b"X")


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

    On a terminal the bar is redrawn in place (``\r``); elsewhere (a log
    file, a pipe) it prints one plain line at most every
    PROGRESS_LOG_INTERVAL seconds, and the last one.

    Args:
        total: number of poses to compute in this run.
        label: text before the bar.
        stream: where to print (stderr by default).
        interval: seconds between redraws on a terminal.
    """

    def __init__(self, total: int, label: str = "map", stream=None, interval: float = 0.2):
        self.total, self.label = total, label
        self.stream = stream or sys.stderr
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(isatty()) if callable(isatty) else False
        self.interval = interval if self.tty else max(interval, PROGRESS_LOG_INTERVAL)
        self.start = time.perf_counter()
        self.last = 0.0
        self.done = 0

    def __call__(self, done: int, total: int, index: int | None = None) -> None:
        self.done, self.total = done, total
        now = time.perf_counter()
        if now - self.last >= self.interval or done >= total:
            self.last = now
            self._draw(now)

    def stopped(self) -> None:
        """End an interrupted run's bar where it stands: its state then, as
        a line of its own (a log's last line would otherwise be up to
        PROGRESS_LOG_INTERVAL seconds old)."""
        if self.done >= self.total:
            return
        self._draw(time.perf_counter())
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()

    def _draw(self, now: float) -> None:
        elapsed = max(now - self.start, 1e-9)
        rate = self.done / elapsed
        frac = self.done / self.total if self.total else 1.0
        width = 24
        bar = "#" * int(round(frac * width))
        eta = (self.total - self.done) / rate if rate > 0 else float("nan")
        text = (
            f"{self.label} [{bar:<{width}}] {self.done}/{self.total} poses "
            f"{100 * frac:5.1f}%  {rate:,.0f} poses/s  ETA {_clock(eta)}"
        )
        self.stream.write(("\r" if self.tty else "") + text)
        if self.done >= self.total:
            self.stream.write(f"  done in {_clock(elapsed)}")
        if self.done >= self.total or not self.tty:
            self.stream.write("\n")
        self.stream.flush()


def _clock(seconds: float) -> str:
    if seconds != seconds or seconds == float("inf"):
        return "--:--"
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


# --------------------------------------------------------------------------
# what runs where


def _count(n: int, word: str, plural: str | None = None) -> str:
    """``1 chunk``, ``2 chunks``."""
    return f"{n} {word}" if n == 1 else f"{n} {plural or word + 's'}"


@dataclass(frozen=True)
class MapRunInfo:
    """What a map run computes and where, for the line a caller prints
    before the chunks start (:meth:`lines`).

    Attributes:
        n_chunks, n_poses: chunks and poses of the whole map.
        done_chunks, done_poses: those already in the store (resumed).
        store: the store's path, or None for a map in memory.
        executor: ``"none"`` (nothing to compute), ``"this process"``,
            ``"local"`` (worker processes and this one) or ``"dask"``.
        processes: local processes computing chunks, this one included.
        workers_asked: the ``workers`` asked for (local runs).
        scheduler: the Dask scheduler's address.
        dask_workers, dask_threads: the Dask cluster's workers and threads.
    """

    n_chunks: int
    n_poses: int
    done_chunks: int = 0
    done_poses: int = 0
    store: str | None = None
    executor: str = "none"
    processes: int = 0
    workers_asked: int | None = None
    scheduler: str | None = None
    dask_workers: int = 0
    dask_threads: int = 0

    @property
    def todo_chunks(self) -> int:
        return self.n_chunks - self.done_chunks

    @property
    def todo_poses(self) -> int:
        return self.n_poses - self.done_poses

    def lines(self) -> list[str]:
        """What is resumed and where the chunks run, in words."""
        if self.todo_chunks == 0:
            return [
                f"the store {self.store} already holds the whole map "
                f"({_count(self.n_chunks, 'chunk')}, {self.n_poses} poses); nothing to compute"
            ]
        lines = []
        if self.done_chunks:
            lines.append(
                f"resuming {self.store}: {self.done_chunks} of {self.n_chunks} chunks done "
                f"({self.done_poses} of {self.n_poses} poses); computing the remaining "
                f"{_count(self.todo_chunks, 'chunk')} ({self.todo_poses} poses)"
            )
        what = f"running {_count(self.todo_chunks, 'chunk')} ({self.todo_poses} poses)"
        if self.executor == "dask":
            where = (
                f"on the Dask scheduler {self.scheduler} ({_count(self.dask_workers, 'worker')}, "
                f"{_count(self.dask_threads, 'thread')})"
            )
        elif self.executor == "local":
            where = (
                f"in {self.processes} local processes: this one and "
                f"{_count(self.processes - 1, 'worker process', 'worker processes')}"
            )
            if self.workers_asked and self.workers_asked > self.processes:
                where += f" ({self.workers_asked} asked for; at most one per chunk)"
        else:
            where = "in this process"
            if self.workers_asked and self.workers_asked > 1:
                where += f" ({self.workers_asked} asked for; at most one per chunk)"
            else:
                where += " (no worker processes)"
        return lines + [f"{what} {where}"]


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
    announce: Callable[[MapRunInfo], None] | None = None,
    source: RobotSource | None = None,
) -> None:
    """Compute the chunks ``todo`` and write each to ``sink`` as it finishes;
    ``job`` is the :class:`~cdpm.pipeline.evaluate.MapJob` every chunk runs.

    ``announce`` is called once, before the first chunk, with a
    :class:`MapRunInfo` saying what runs where (also when nothing is left
    to compute); ``source`` (default: built from ``robot``) is how workers
    rebuild the robot.
    """
    total = sum(plan.chunk_size(k) for k in todo)
    pending = set(todo)
    done = [k for k in range(plan.n_chunks) if k not in pending]
    info = MapRunInfo(
        n_chunks=plan.n_chunks,
        n_poses=plan.n_poses,
        done_chunks=len(done),
        done_poses=sum(plan.chunk_size(k) for k in done),
        store=None if getattr(sink, "path", None) is None else str(sink.path),
        workers_asked=None if scheduler is not None else workers,
    )

    def started(**where) -> None:
        if announce is not None:
            announce(replace(info, **where))
        if progress is not None and todo:
            progress(0, total, -1)

    state = {"done": 0}

    def finished(index: int, data: dict | None) -> None:
        if data is not None:  # None: a worker wrote the chunk itself
            sink.write(index, data)
        state["done"] += plan.chunk_size(index)
        if progress is not None:
            progress(state["done"], total, index)

    if not todo:
        started(executor="none")
        return
    source = source or RobotSource.from_robot(robot)
    kernels = not zero_equilibrium(robot, job.tension)
    with single_threaded_blas():
        if scheduler is None and kernels:
            # compiled (first run after an install) or loaded here, once, and
            # not counted in the progress rate or in every worker at once
            load_kernels(notice_on_stderr if progress is not None else None)
        if scheduler is None:
            # what a chunk's evaluation imports on first use (the analysers
            # and scipy: a quarter of a second) is imported before the first
            # chunk, as the workers' fork server does: set-up, not a chunk
            for name in _EVALUATION_MODULES:
                importlib.import_module(name)
        if scheduler is not None:
            _run_dask(plan, job, todo, finished, scheduler, source, started)
        elif workers <= 1 or len(todo) == 1:
            started(executor="this process", processes=1)
            for index in todo:
                finished(index, job.evaluate(robot, plan.natural(index)))
        else:
            _run_processes(
                robot, plan, job, todo, finished, workers, sink.writer, source, started, kernels
            )


#: what evaluating a chunk imports on first use (the analysers and SciPy)
_EVALUATION_MODULES = [
    "cdpm.analysis",
    "cdpm.analysis.batch",
    "cdpm.dynamics.equilibrium",
    "cdpm.dynamics.linearisation",
]

#: modules the fork server imports once, so that workers start warm; a name
#: that is not importable is skipped by the fork server
_PRELOAD = [
    "cdpm.pipeline.evaluate",
    "cdpm.maps._store",
    *_EVALUATION_MODULES,
    "pinocchio",
    "zarr",
    "cdpm.maps._runner",
]

#: and, for maps under load, the compiled kernels, which their users import
#: on first use (numba's import and each kernel module's dispatchers cost
#: tenths of a second per process); zero-load maps use none of them, and
#: importing them would delay the fork server, so the first workers, by
#: about half a second
_PRELOAD_KERNELS = ["numba", *KERNEL_MODULES]

#: the fork server's first and last imports: Ctrl-C is ignored between
#: them, so that it does not interrupt the imports with a traceback
_QUIET_START = "cdpm.forkserver.quiet"
_QUIET_END = "cdpm.forkserver.ready"


def _context(kernels: bool = True):
    """The multiprocessing context of local workers: the fork server where
    the platform has one (preloading the kernels too with ``kernels``; the
    first map of a process decides, as the server starts once), else spawn."""
    methods = multiprocessing.get_all_start_methods()
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        modules = _PRELOAD + (_PRELOAD_KERNELS if kernels else [])
        ctx.set_forkserver_preload([_QUIET_START, *modules, _QUIET_END])
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


def prestart_workers(kernels: bool = True) -> None:
    """Start what local worker processes are forked from (the fork server
    importing Pinocchio, zarr and cdpm, and with ``kernels`` the compiled
    kernels) in the background now, so that it is ready when the first
    chunks are handed out."""
    _start_fork_server(_context(kernels))


def _worker_ready() -> None:
    """A task that does nothing: one per worker process starts it."""


def _start_worker_processes(executor, n: int, ready: list) -> threading.Thread:
    """Start the ``n`` processes of the ProcessPoolExecutor ``executor``
    from a background thread, which ends once they are started; returns the
    thread. ``executor.submit`` waits until the fork server, once it has
    imported its modules (about a second), forks a worker: this process
    computes chunks meanwhile instead of waiting in its first submit.
    ``ready`` gets a future per worker, done once it has started (or with
    the error that stopped it)."""
    from concurrent.futures import Future

    def start() -> None:
        try:
            for _ in range(n):
                ready.append(executor.submit(_worker_ready))
        except Exception as exc:  # a broken pool: the map raises it
            ready.append(Future())
            ready[-1].set_exception(exc)

    thread = threading.Thread(target=start, name="cdpm-start-workers", daemon=True)
    thread.start()
    return thread


def _run_processes(
    robot: CableRobot,
    plan,
    job,
    todo,
    finished,
    workers: int,
    writer,
    source,
    started,
    kernels: bool = True,
) -> None:
    """Chunks on ``workers - 1`` local worker processes plus this process.

    Each worker builds the robot once (initializer) and then gets only
    chunk indices; with a ``writer`` (a store on this file system) workers
    write their chunks themselves. This process computes a chunk whenever
    none of the workers' chunks is ready, so the workers' start-up overlaps
    useful work and small maps gain from workers too. ``kernels``: the
    map's poses need the compiled kernels (a map under load).
    """
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    pending = list(reversed(todo))
    n_proc = min(workers - 1, len(todo) - 1)
    started(executor="local", processes=n_proc + 1)
    ctx = _context(kernels)
    executor = ProcessPoolExecutor(
        max_workers=n_proc,
        mp_context=ctx,
        initializer=_init_process,
        initargs=(source, plan, job, writer, os.getpid()),
    )
    ready: list = []
    starting = _start_worker_processes(executor, n_proc, ready)
    running = set()
    try:
        while pending or running:
            if not starting.is_alive():
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
        starting.join()
        for future in ready:  # a worker that could not start fails the map, however small
            future.result()
    except BaseException as exc:
        for future in running:
            future.cancel()
        # every process it starts is then listed, and stopped; a fork server
        # that never answers is not waited for
        starting.join(timeout=WORKER_START_SECONDS)
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


def _scheduler_lost_errors() -> tuple[type[BaseException], ...]:
    """The exceptions a future's result raises when its scheduler is gone
    (looked up when a map runs on Dask: importing dask.distributed costs a
    third of a second, which local maps and their workers do not pay)."""
    import asyncio
    import concurrent.futures

    errors: list[type[BaseException]] = [
        asyncio.CancelledError,
        concurrent.futures.CancelledError,
        OSError,
        TimeoutError,
    ]
    try:
        from distributed.comm.core import CommClosedError

        errors.append(CommClosedError)
    except ImportError:  # pragma: no cover - dask absent: _run_dask says so
        pass
    return tuple(errors)


def _run_dask(plan, job, todo, finished, scheduler, source, started) -> None:
    try:
        import distributed
    except ImportError as exc:
        raise MissingExtraError(
            "running a map on a Dask cluster needs dask.distributed: pip install 'cdpm[maps]'"
        ) from exc
    own = isinstance(scheduler, str)
    if own:
        try:
            client = distributed.Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise InputError(
                f"cannot reach the Dask scheduler at {scheduler!r}: {exc}; start one with "
                "`dask scheduler` (and workers with `dask worker ADDRESS`) or drop --scheduler "
                "to use local processes"
            ) from exc
    else:
        client = scheduler
    lost = _scheduler_lost_errors()
    try:
        threads = client.nthreads()
        n_workers = max(1, sum(threads.values()))
        started(
            executor="dask",
            scheduler=str(client.scheduler.address if not own else scheduler),
            dask_workers=len(threads),
            dask_threads=sum(threads.values()),
        )
        pending = list(reversed(todo))
        queue = distributed.as_completed()

        def submit() -> None:
            index = pending.pop()
            queue.add(
                client.submit(compute_chunk, source, job, index, plan.natural(index), pure=False)
            )

        for _ in range(min(len(pending), 2 * n_workers)):
            submit()
        done = 0
        for future in queue:
            try:
                result = future.result()
            except lost as exc:
                from cdpm.maps._scheduler import lost_scheduler_error

                address = scheduler if own else str(client.scheduler.address)
                raise lost_scheduler_error(address, done, len(todo), exc) from None
            finished(*result)
            done += 1
            future.release()
            if pending:
                submit()
    finally:
        if own:
            client.close()
