"""What a map run tells its user: the progress bar and the run's prose.

:class:`ProgressPrinter` draws poses done, poses/s and ETA on stderr
(redrawn in place on a terminal, plain lines in a log or a pipe);
:class:`MapRunInfo` says what a run computes and where (what is resumed
from the store, in this process, in local worker processes or on a Dask
cluster) in the sentences printed before the chunks start.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

from cdpm.numerics import PROGRESS_LOG_INTERVAL

__all__ = ["ProgressPrinter", "MapRunInfo"]


class ProgressPrinter:
    """A one-line progress bar on stderr: items done (poses by default),
    items/s and ETA.

    On a terminal the bar is redrawn in place (``\r``); elsewhere (a log
    file, a pipe) it prints one plain line at most every
    PROGRESS_LOG_INTERVAL seconds, and the last one.

    Args:
        total: number of poses to compute in this run.
        label: text before the bar.
        stream: where to print (stderr by default).
        interval: seconds between redraws on a terminal.
        unit: what is counted (``"poses"``, ``"cells"``).
        decimals: decimals of the rate (few items a second need one).
    """

    def __init__(
        self,
        total: int,
        label: str = "map",
        stream=None,
        interval: float = 0.2,
        unit: str = "poses",
        decimals: int = 0,
    ):
        self.total, self.label = total, label
        self.unit, self.decimals = unit, decimals
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
            f"{self.label} [{bar:<{width}}] {self.done}/{self.total} {self.unit} "
            f"{100 * frac:5.1f}%  {rate:,.{self.decimals}f} {self.unit}/s  ETA {_clock(eta)}"
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
# what runs where, in words


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
