"""One run per map store: a lock file beside the store.

``<store>.lock`` holds an exclusive ``flock`` for as long as a run writes
the store, and names its owner (pid, host, start time). The operating
system releases the lock when its process dies, however it dies (Ctrl-C,
SIGTERM, SIGKILL), so a lock file left by a killed run is stale: the next
run takes it over. A second run while the first is alive refuses at once
and says who owns the store. The lock file sits beside the store's resolved
path, so two runs that name one store by different paths (a symbolic link
to it, or to a folder above it) take the same lock. Locks are advisory and
local: runs on other machines that share the store over a network file
system may not see them.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from pathlib import Path

from cdpm.errors import InputError

__all__ = ["StoreBusyError", "store_lock", "lock_path"]


class StoreBusyError(InputError):
    """Another live run owns the map store."""


def lock_path(store) -> Path:
    """The lock file of a store: ``<store>.lock`` beside it, with symbolic
    links resolved (a link to a store has the store's lock)."""
    path = Path(store).expanduser()
    try:
        path = path.resolve()
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python < 3.13)
        raise InputError(
            f"cannot use the map store path {path}: {exc}; choose another path (--out)"
        ) from None
    return path.with_name(path.name + ".lock")


@contextlib.contextmanager
def store_lock(store):
    """Own ``store`` for the duration of the block.

    Raises:
        StoreBusyError: another live process holds the lock (the message
            names its pid, host and start time).
    """
    try:
        # platform-specific, used here only
        import fcntl
    except ImportError:  # pragma: no cover - not a POSIX system: no locking
        yield
        return
    _check_writable_folder(Path(store).expanduser())
    path = lock_path(store)  # after the folder exists: resolved through it
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise InputError(
                f"cannot write the map store {Path(store).expanduser()}: "
                f"{exc.strerror or exc}; choose a folder you can write to (--out)"
            ) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            owner = _owner(fd)
            os.close(fd)
            raise StoreBusyError(
                f"map store {Path(store).expanduser()} is being written by another run "
                f"({owner}); wait for it to finish or stop it, then run again (finished "
                f"chunks are kept), or write this map to another --out"
            ) from None
        # the file may have been removed by its previous owner between our
        # open and our lock: then lock the file that is there now
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        record = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time()}
        os.write(fd, json.dumps(record).encode())
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        os.close(fd)


def _check_writable_folder(store: Path) -> None:
    """Create the store's folder if needed; refuse a path under a file or
    in a folder that cannot be written, naming it."""
    for parent in [store.parent, *store.parent.parents]:
        if parent.exists():
            if not parent.is_dir():
                raise InputError(
                    f"cannot write the map store {store}: {parent} is a file, not a folder; "
                    "choose another path (--out)"
                )
            break
    try:
        store.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"cannot create the folder {store.parent} for the map store: "
            f"{exc.strerror or exc}; choose a folder you can write to (--out)"
        ) from None


def _owner(fd: int) -> str:
    """'pid N on HOST since HH:MM:SS' from a lock file, or 'unknown owner'."""
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        record = json.loads(os.read(fd, 4096).decode() or "{}")
        since = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(record["started"]))
        return f"pid {record['pid']} on {record['host']} since {since}"
    except (OSError, ValueError, KeyError, TypeError):
        return "owner unknown"
