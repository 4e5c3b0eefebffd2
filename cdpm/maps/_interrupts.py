"""Interrupts held while a block runs (:func:`interrupts_held`): the
map's set-up, its imports and kernels, and each write into zarr's event
loop finish before Ctrl-C (or SIGTERM) goes on."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = ["interrupts_held"]


#: the signals :func:`interrupts_held` holds: Ctrl-C, and SIGTERM, which
#: cdpm's command line reads as Ctrl-C
_HELD_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def interrupts_held() -> Iterator[None]:
    """Hold Ctrl-C (and SIGTERM where Python handles it) while the block
    runs, and let it go on once the block has ended.

    Raised inside an import, a Ctrl-C can leave an error of the import
    instead of itself ("initialization failed", "Error calling
    __set_name__"), or make Python end with a signal instead of the
    command's exit code (within an ``exec``), and raised in numba's
    callbacks while kernels load it is lost ("Exception ignored"): the
    block's imports and loading finish first (a few seconds at most; half
    a minute when numba compiles after an install, which it says). A
    second one goes through at once. Signals Python does not handle (the
    default SIGTERM) and threads other than the main one are left alone.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    held: list = []

    def hold(signum, frame) -> None:
        if held:  # a second one: at once
            _restore(previous)
            held.clear()
            previous[signum](signum, frame)
            return
        held.append((signum, frame))

    for signum in _HELD_SIGNALS:
        handler = signal.getsignal(signum)
        if callable(handler):
            previous[signum] = handler
            signal.signal(signum, hold)
    try:
        yield
    finally:
        _restore(previous)
        if held:
            signum, frame = held.pop()
            previous[signum](signum, frame)


def _restore(handlers: dict) -> None:
    for signum, handler in handlers.items():
        signal.signal(signum, handler)
