"""Maps on a Dask cluster: the scheduler's address, checked before a map
does any work, and the executor that runs a map's chunks on its workers.

The address is ``tcp://host:port`` (or ``tls://``, ``ws://``, ``wss://``;
``host:port`` means tcp) with a port in 1..65535; the scheduler must accept a
connection within SCHEDULER_CONNECT_SECONDS, so an address nothing listens
on is reported at once, before the map's store is created.

Each Dask task gets its chunk's poses and the robot's spec and URDF bytes
(:class:`~cdpm.maps._workers.RobotSource`) and returns the chunk's arrays;
the driver writes them (remote workers may not see the store). A
scheduler lost during a map is reported with the hint to resume: the
finished chunks stay in the store; what Dask's client logs meanwhile (its
attempts to reconnect, with their tracebacks) is held back during the map
and dropped, and printed only when the map fails otherwise.
"""

from __future__ import annotations

import contextlib
import logging
import socket
from collections.abc import Iterator

from cdpm.errors import InputError, MissingExtraError
from cdpm.maps._workers import compute_chunk

__all__ = [
    "check_scheduler_address",
    "SCHEDULER_CONNECT_SECONDS",
    "lost_scheduler_error",
    "run_dask",
]

#: seconds to wait for the scheduler to accept a connection
SCHEDULER_CONNECT_SECONDS = 5.0

_SCHEMES = ("tcp", "tls", "ws", "wss")
_START = (
    "start one with `dask scheduler` (and workers with `dask worker ADDRESS`), or leave out "
    "the scheduler (--scheduler) to run on local processes"
)


def check_scheduler_address(address: str, connect: bool = True) -> str:
    """The address, checked; with ``connect`` also that something listens.

    Raises:
        InputError: a malformed address, a bad port, or nothing reachable
            there (the message says which, and how to start a scheduler).
    """
    if not isinstance(address, str) or not address.strip():
        raise InputError(f"scheduler address {address!r} is empty; give e.g. tcp://127.0.0.1:8786")
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme == "inproc":  # a scheduler in this process (LocalCluster(processes=False))
        return text
    if scheme not in _SCHEMES:
        raise InputError(
            f"scheduler address {text!r}: protocol {scheme!r} is not one of "
            f"{', '.join(_SCHEMES)}; give e.g. tcp://127.0.0.1:8786"
        )
    host, colon, port_text = rest.rpartition(":")
    host = host.strip("[]")
    if not colon or not host or "/" in host or "/" in port_text:
        raise InputError(
            f"scheduler address {text!r} is not HOST:PORT; give e.g. tcp://127.0.0.1:8786"
        )
    try:
        port = int(port_text)
    except ValueError:
        raise InputError(
            f"scheduler address {text!r}: port {port_text!r} is not a number; Dask's default "
            "is 8786"
        ) from None
    if not 1 <= port <= 65535:
        raise InputError(
            f"scheduler address {text!r}: port {port} is outside 1..65535; Dask's default is 8786"
        )
    if connect and scheme in ("tcp", "tls"):
        try:
            with socket.create_connection((host, port), timeout=SCHEDULER_CONNECT_SECONDS):
                pass
        except OSError as exc:
            reason = exc.strerror or type(exc).__name__
            if isinstance(exc, TimeoutError):
                reason = f"no answer within {SCHEDULER_CONNECT_SECONDS:g} s"
            raise InputError(
                f"cannot reach the Dask scheduler at {text} ({reason}); {_START}"
            ) from None
    return text


def lost_scheduler_error(address: str, done: int, total: int, exc: BaseException) -> InputError:
    """The error for a scheduler lost during a map, with the resume hint."""
    kind = type(exc).__name__
    return InputError(
        f"lost the Dask scheduler at {address} after {done} of {total} chunks ({kind}); the "
        "finished chunks are kept in the store: start the scheduler and its workers again "
        "and re-run the same command to resume"
    )


# --------------------------------------------------------------------------
# running the chunks on the cluster


def _scheduler_lost_errors() -> tuple[type[BaseException], ...]:
    """The exceptions a future's result raises when its scheduler is gone
    (looked up when a map runs on Dask: importing dask.distributed costs a
    third of a second, which local maps and their workers do not pay)."""
    # asyncio, concurrent.futures: loaded on first use (a local map needs neither)
    import asyncio
    import concurrent.futures

    errors: list[type[BaseException]] = [
        asyncio.CancelledError,
        concurrent.futures.CancelledError,
        OSError,
        TimeoutError,
    ]
    try:
        # optional: cdpm[maps]
        from distributed.comm.core import CommClosedError

        errors.append(CommClosedError)
    except ImportError:  # pragma: no cover - dask absent: run_dask says so
        pass
    return tuple(errors)


def run_dask(plan, job, todo, finished, scheduler, source, started) -> None:
    """Chunks ``todo`` as tasks on the Dask ``scheduler`` (an address, or a
    ``distributed.Client`` the caller keeps), at most two per worker thread
    queued; ``finished`` gets each chunk's arrays, ``started`` what runs
    where."""
    try:
        # optional: cdpm[maps]
        import distributed
    except ImportError as exc:
        raise MissingExtraError(
            "running a map on a Dask cluster needs dask.distributed: pip install 'cdpm[maps]'"
        ) from exc
    with _dask_logs_held() as logs:
        try:
            _run_on_cluster(distributed, plan, job, todo, finished, scheduler, source, started)
        except Exception as exc:
            # a lost (or unreachable) scheduler is said in one message; any
            # other failure comes with what Dask logged meanwhile
            if not isinstance(exc, InputError):
                logs.release()
            raise


#: the loggers whose messages a map on Dask holds back: those of
#: dask.distributed's modules (its client logs each attempt to reconnect to a
#: lost scheduler at ERROR level, with two tracebacks)
_DASK_LOGGERS = ("distributed",)


class _HeldLogs(logging.Filter):
    """A filter that keeps the records of the loggers it is added to
    instead of letting them through (:func:`_dask_logs_held`)."""

    def __init__(self) -> None:
        super().__init__()
        self.records: list[logging.LogRecord] = []

    def filter(self, record: logging.LogRecord) -> bool:
        self.records.append(record)
        return False

    def clear(self) -> None:
        self.records.clear()

    def release(self) -> None:
        """Pass the records held so far on, as they would have gone."""
        records, self.records = self.records, []
        for record in records:
            logging.getLogger(record.name).handle(record)


@contextlib.contextmanager
def _dask_logs_held() -> Iterator[_HeldLogs]:
    """Hold back, while the block runs, what dask.distributed's loggers
    log (each keeps its own level and handlers); the records held are
    dropped at the end unless the caller releases them, and the loggers
    are as before."""
    manager = logging.Logger.manager
    names = [
        name
        for name, logger in list(manager.loggerDict.items())
        if isinstance(logger, logging.Logger)
        and any(name == root or name.startswith(root + ".") for root in _DASK_LOGGERS)
    ]
    loggers = [logging.getLogger(name) for name in names]
    held = _HeldLogs()
    for logger in loggers:
        logger.addFilter(held)
    try:
        yield held
    finally:
        for logger in loggers:
            logger.removeFilter(held)
        held.clear()


def _run_on_cluster(distributed, plan, job, todo, finished, scheduler, source, started) -> None:
    """:func:`run_dask` with ``distributed`` imported."""
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
