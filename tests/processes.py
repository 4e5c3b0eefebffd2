"""Processes a test started: found by a mark in their environment (a test
sets ``CDPM_TEST_MARK=<marker>`` on the command it runs; children inherit
it) and checked afterwards that none is left, whether one is alive, and
whether another process finds a map store locked."""

from __future__ import annotations

import os
import time
from pathlib import Path

__all__ = ["alive", "lock_held_elsewhere", "marked", "wait_gone"]


def marked(marker: str) -> list[int]:
    """Live processes (not zombies) whose environment holds
    ``CDPM_TEST_MARK=marker``: a command and every process it started."""
    needle = f"CDPM_TEST_MARK={marker}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            environ = (entry / "environ").read_bytes()
            state = (entry / "stat").read_bytes().rsplit(b")", 1)[1].split()[0]
        except OSError:
            continue
        if needle in environ.split(b"\0") and state not in (b"Z", b"X"):
            found.append(int(entry.name))
    return found


def wait_gone(marker: str, seconds: float = 10.0) -> list[int]:
    """The marked processes still alive after waiting up to ``seconds``."""
    end = time.monotonic() + seconds
    while marked(marker) and time.monotonic() < end:
        time.sleep(0.1)
    return marked(marker)


def alive(pid: int) -> bool:
    """True while a process runs (a zombie is gone for this purpose)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def lock_held_elsewhere(store: Path) -> bool:
    """Whether a forked process finds the map store ``store`` locked (a
    lock is per open file, so this process's own lock counts)."""
    from cdpm.maps._lock import StoreBusyError, store_lock

    pid = os.fork()
    if pid == 0:  # child: try to take the lock
        try:
            with store_lock(store):
                os._exit(0)
        except StoreBusyError:
            os._exit(7)
        except BaseException:
            os._exit(9)
    _, status = os.waitpid(pid, 0)
    assert os.WEXITSTATUS(status) in (0, 7)
    return os.WEXITSTATUS(status) == 7
