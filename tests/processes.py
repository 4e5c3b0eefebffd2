"""Processes a test started, found by a mark in their environment: a test
sets ``CDPM_TEST_MARK=<marker>`` on the command it runs (children inherit
it) and checks afterwards that none is left."""

from __future__ import annotations

import time
from pathlib import Path

__all__ = ["marked", "wait_gone"]


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
