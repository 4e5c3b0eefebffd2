"""Running map chunks: in-process, in local worker processes, or on Dask.

Every executor runs the same function on the same chunks (the poses of
chunk k come from the :class:`~cdpm.maps.plan.MapPlan`), so results do not
depend on where a chunk ran. :func:`run_chunks` picks the executor, says
what runs where, loads here once what every chunk needs, and writes each
finished chunk to the map's sink; the executors live beside it: local
worker processes (and how workers rebuild the robot) in
:mod:`cdpm.maps._workers`, Dask in :mod:`cdpm.maps._dask`; the progress
bar and the run's sentences in :mod:`cdpm.maps._progress`.
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Callable
from dataclasses import replace

from cdpm.maps._dask import run_dask
from cdpm.maps._interrupts import interrupts_held
from cdpm.maps._progress import MapRunInfo
from cdpm.maps._workers import EVALUATION_MODULES, RobotSource, run_processes
from cdpm.pipeline.compiled import load_kernels, notice_on_stderr
from cdpm.pipeline.evaluate import single_threaded_blas, zero_equilibrium

__all__ = ["run_chunks", "interrupts_held"]


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
    with contextlib.ExitStack() as stack:
        # set-up: imports and the kernels' loading, where an interrupt
        # broke an import or was lost in numba's callbacks
        with interrupts_held():
            stack.enter_context(single_threaded_blas())  # imports SciPy's BLAS
            if scheduler is None and kernels:
                # compiled (first run after an install) or loaded here, once,
                # and not counted in the progress rate or in every worker at once
                load_kernels(notice_on_stderr if progress is not None else None)
            if scheduler is None:
                # what a chunk's evaluation imports on first use (the analysers
                # and scipy: a quarter of a second) is imported before the first
                # chunk, as the workers' fork server does: set-up, not a chunk
                for name in EVALUATION_MODULES:
                    importlib.import_module(name)
        try:
            _run(
                robot, plan, job, todo, finished, workers, sink, scheduler, source, started, kernels
            )
        except SystemError as exc:
            if not _interrupt_in(exc):
                raise
            # Ctrl-C while a compiled kernel called back into Python (numba)
            raise KeyboardInterrupt from None


def _run(robot, plan, job, todo, finished, workers, sink, scheduler, source, started, kernels):
    """The chunks ``todo`` on the executor the map asked for."""
    if scheduler is not None:
        run_dask(plan, job, todo, finished, scheduler, source, started)
    elif workers <= 1 or len(todo) == 1:
        started(executor="this process", processes=1)
        for index in todo:
            finished(index, job.evaluate(robot, plan.natural(index)))
    else:
        run_processes(
            robot, plan, job, todo, finished, workers, sink.writer, source, started, kernels
        )


def _interrupt_in(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is among the causes of ``exc``: numba
    turns one raised while a kernel called back into Python into a
    SystemError, "returned a result with an exception set"."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False
