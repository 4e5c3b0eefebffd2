"""Map workers: how they rebuild the robot, what each keeps, and the local
worker processes that compute a map's chunks beside the calling process.

Workers rebuild the robot from its spec (:class:`RobotSource`): local
processes from the spec path, Dask workers from the spec and URDF bytes
shipped with each task (a remote worker need not see the driver's files);
both check the spec hash, and each thread builds its robot once.

With ``workers=N`` locally (:func:`run_processes`), N - 1 worker processes
get the plan once and then only chunk indices, and the calling process
computes chunks too while none of theirs is ready; with a zarr store
workers write their own chunks (region and done marker), so the driver
does no serial I/O for them. The processes are forked from a fork server
that imports the heavy modules once (:func:`prestart_workers` starts it
early, with Ctrl-C blocked); it imports ``cdpm.forkserver.quiet`` first
and ``cdpm.forkserver.ready`` last, so that Ctrl-C does not interrupt its
imports. Workers ignore Ctrl-C (the driver stops them, and waits for the
pool to have shut down) and end soon after the driver does, however it
ends.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from cdpm.errors import CdpmError, InputError
from cdpm.maps.plan import override_robot, robot_overrides
from cdpm.model.robot import load_robot
from cdpm.pipeline.compiled import KERNEL_MODULES
from cdpm.pipeline.evaluate import MapJob, single_threaded_blas

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = [
    "RobotSource",
    "compute_chunk",
    "prestart_workers",
    "unimportable_main",
    "run_processes",
    "EVALUATION_MODULES",
]


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
# local worker processes: the fork server and the pool


#: what evaluating a chunk imports on first use (the analysers and SciPy)
EVALUATION_MODULES = [
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
    *EVALUATION_MODULES,
    "pinocchio",
    "zarr",
    "cdpm.maps._workers",
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
        thread = threading.Thread(target=_fork_server_started, daemon=True)
        thread.start()
        _FORK_SERVER["thread"] = thread
    return thread


def _fork_server_started() -> None:
    """Start the fork server with Ctrl-C blocked (:func:`_without_ctrl_c`);
    its resource tracker first, whose start unblocks Ctrl-C in the calling
    thread once it has started it."""
    # multiprocessing: loaded on first use
    from multiprocessing import forkserver, resource_tracker

    resource_tracker.ensure_running()
    _without_ctrl_c(forkserver.ensure_running)


def _without_ctrl_c(start, *args) -> None:
    """Call ``start`` (which starts Python processes) with Ctrl-C blocked
    in this thread, as multiprocessing starts its resource tracker: a
    process started here begins with Ctrl-C blocked, which Ctrl-C in the
    first tenths of a second of its interpreter's start (its imports)
    would otherwise stop with a traceback or "Fatal Python error" on
    stderr. The fork server unblocks it once it is ready
    (``cdpm.forkserver.ready``); worker processes ignore it anyway. Signals
    reach this process through its main thread, which this does not
    change."""
    blocked = hasattr(signal, "pthread_sigmask")
    if blocked:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        start(*args)
    finally:
        if blocked:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def unimportable_main() -> str | None:
    """Why worker processes could not start here, or None.

    Local workers start like Python's ``spawn``: each first runs the main
    module again (from its file, ``__main__.__file__``, or by its name
    after ``python -m``), as a module named ``__mp_main__``. A script piped
    on stdin (``python - < script``) has the file name ``<stdin>``, which
    does not exist, so every worker would stop before computing anything;
    a script that calls the map outside ``if __name__ == "__main__":`` would
    start the map again in every worker. (``python -c``, an interactive
    session and a package's ``__main__`` are not run again: their workers
    start.)
    """
    main = sys.modules.get("__main__")
    if main is None:
        return None
    name = getattr(getattr(main, "__spec__", None), "name", None)
    if name is not None and (name == "__main__" or name.endswith(".__main__")):
        return None  # python -m package: workers do not run it again
    path = getattr(main, "__file__", None)
    if path is None:
        return None
    if name is None and not os.path.isfile(path):
        return (
            f"the main script {path!r} is not a file that worker processes can run "
            "(a script on stdin?); save it to a file to use several workers"
        )
    line = _unguarded_main_line(main, path)
    if line is None:
        return None
    return (
        f"{os.path.basename(path)} calls it at line {line} outside "
        '`if __name__ == "__main__":`, and every worker process runs the script again; '
        "put the map under that guard to use several workers"
    )


def _unguarded_main_line(main, path: str) -> int | None:
    """The line of the main module's top-level code that the current call
    comes from, when it is not under ``if __name__ == "__main__":``; None
    when it is, when the call does not come from there (a function called
    later, another module's code), or when the file cannot be read."""
    frame = sys._getframe(1)
    while frame is not None:
        if frame.f_code.co_name == "<module>" and frame.f_globals is vars(main):
            break
        frame = frame.f_back
    else:
        return None
    line = frame.f_lineno
    try:
        # ast: loaded on first use
        import ast

        tree = ast.parse(Path(path).read_bytes(), filename=path)
    except (OSError, SyntaxError, ValueError):
        return None
    for node in tree.body:
        if isinstance(node, ast.If) and node.end_lineno is not None:
            guarded = _main_guard_branch(node)
            if guarded and guarded[0].lineno <= line <= (guarded[-1].end_lineno or line):
                return None
    return line


def _main_guard_branch(node) -> list:
    """The statements of ``if __name__ == "__main__":`` (or the ``else`` of
    ``!=``) that only the main process runs; [] for another ``if``."""
    # ast: loaded on first use
    import ast

    test = node.test
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1):
        return []
    sides = [test.left, test.comparators[0]]
    names = [isinstance(x, ast.Name) and x.id == "__name__" for x in sides]
    mains = [isinstance(x, ast.Constant) and x.value == "__main__" for x in sides]
    if not ((names[0] and mains[1]) or (names[1] and mains[0])):
        return []
    if isinstance(test.ops[0], ast.Eq):
        return node.body
    if isinstance(test.ops[0], ast.NotEq):
        return node.orelse
    return []


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
    # concurrent: loaded on first use
    from concurrent.futures import Future

    def start() -> None:
        try:
            for _ in range(n):
                ready.append(executor.submit(_worker_ready))
        except Exception as exc:  # a broken pool: the map raises it
            ready.append(Future())
            ready[-1].set_exception(exc)

    # with Ctrl-C blocked: the fork server, or with spawn each worker, may
    # start here
    thread = threading.Thread(
        target=_without_ctrl_c, args=(start,), name="cdpm-start-workers", daemon=True
    )
    thread.start()
    return thread


def run_processes(
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
    # multiprocessing: loaded on first use
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
        for process in list((getattr(executor, "_processes", None) or {}).values()):
            process.terminate()
        _shut_down(executor)
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


def _shut_down(executor) -> None:
    """Shut the pool ``executor`` down, its workers stopped, and wait until
    its thread that tends them has closed its pipes and ended.

    Not waiting for it (``shutdown(wait=False)``) left that thread closing
    the pool's wake-up pipe while Python's exit, in another thread, wrote to
    it to wake the thread up: about one interrupted map in twenty ended
    with "OSError: [Errno 9] Bad file descriptor" after its message. The
    wait is short (the workers are stopped); a second Ctrl-C ends it, and
    the thread is then waited for as before (by Python at exit)."""
    executor.shutdown(wait=True, cancel_futures=True)
