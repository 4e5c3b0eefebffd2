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
finished chunks stay in the store.
"""

from __future__ import annotations

import socket

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
