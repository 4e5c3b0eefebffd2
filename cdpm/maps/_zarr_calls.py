"""Calls into zarr's event loop, for the map stores: interrupt-safe
(:func:`sync`), metadata written compactly with zarr's warnings about the
stores' layout silenced (:func:`write_metadata`), and the store object of a
map store's folder (:func:`file_store`)."""

from __future__ import annotations

import contextlib
import threading
import time
import warnings
from pathlib import Path

from cdpm.maps._interrupts import interrupts_held

__all__ = [
    "INTERRUPT_SETTLE_SECONDS",
    "file_store",
    "sync",
    "write_metadata",
    "zarr_warnings_silenced",
]

#: longest wait [s], after an interrupt (Ctrl-C, SIGTERM), for a store write
#: under way in zarr's event loop to stop (:func:`sync`)
INTERRUPT_SETTLE_SECONDS = 10.0


def write_metadata(make):
    """Run the coroutine that writes zarr metadata (``make()``, or
    ``make``: :func:`sync`) in zarr's event loop; its result.

    Metadata documents are written without indentation: zarr indents them
    by default, and Python encodes indented JSON in pure Python, several
    times slower (a map store's root document, with the consolidated
    metadata of every array, is 15-30 kB). zarr's warnings about them are
    silenced (:func:`zarr_warnings_silenced`)."""
    # zarr: loaded on first use
    import zarr

    with zarr_warnings_silenced(), zarr.config.set({"json_indent": None}):
        return sync(make)


@contextlib.contextmanager
def zarr_warnings_silenced():
    """Silence, while the context lasts, zarr's warnings that a map
    store's string coordinates and consolidated metadata are not in the
    zarr v3 specification yet (xarray and zarr-python read both): only
    warnings raised in zarr's modules, since other threads of the process
    may warn meanwhile."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=UserWarning, module=r"zarr\.")
        warnings.filterwarnings("ignore", category=FutureWarning, module=r"zarr\.")
        yield


def sync(make):
    """Run a coroutine in zarr's event loop (``zarr.core.sync.sync``) and
    return its result: the one ``make()`` returns (made in the loop), or
    ``make`` itself.

    An interrupt (Ctrl-C, or SIGTERM, which cdpm reads as Ctrl-C) waits
    for the work to end (:func:`~cdpm.maps._interrupts.interrupts_held`).
    A second one while it runs cancels it and waits for it (at most
    INTERRUPT_SETTLE_SECONDS) before the interrupt goes on: zarr's exit
    handler closes its loop, and printed a traceback ("Cannot close a
    running event loop") when a write was still running in it 0.2 s after
    the interrupt, as on a loaded machine. A cancelled write leaves no
    partial file, and its chunk no done marker. Interrupted before it
    started (zarr's loop starting, an import), it never starts, and no
    "coroutine ... was never awaited" warning follows: hence ``make``, which
    makes the coroutine only once it runs."""
    # asyncio: loaded on first use
    import asyncio

    # zarr: loaded on first use
    from zarr.core import sync as zarr_sync

    # the loop's start of the work and the caller's giving up on it are
    # decided under one lock: either the work started (and is cancelled and
    # waited for) or it never will (and is closed unstarted)
    lock = threading.Lock()
    state: dict = {"task": None, "abandoned": False}

    async def tracked():
        with lock:
            if state["abandoned"]:  # the caller was interrupted before this started
                return None
            state["task"] = asyncio.current_task()
        return await (make() if callable(make) else make)

    outer = tracked()
    try:
        # an interrupt waits for the write (milliseconds): cancelled mid-way,
        # zarr's gathered chunk writes could outlive its loop at exit
        with interrupts_held():
            return zarr_sync.sync(outer)
    except KeyboardInterrupt:  # a second interrupt, which goes through at once
        with lock:
            task = state["task"]
            state["abandoned"] = task is None
        if task is not None:
            task.get_loop().call_soon_threadsafe(task.cancel)
            deadline = time.monotonic() + INTERRUPT_SETTLE_SECONDS
            while not task.done() and time.monotonic() < deadline:
                time.sleep(0.005)
        else:  # never started, and never will: closed, no "never awaited" warning
            # (the loop may be running its first step, which now returns:
            # closing it then raises ValueError, and is not needed)
            with contextlib.suppress(ValueError, RuntimeError):
                outer.close()
            if not callable(make):
                make.close()
        raise


def file_store(path: Path, read_only: bool = False):
    """The zarr store of the map store at ``path``
    (:class:`cdpm.maps._filestore.MapFileStore`)."""
    # zarr: loaded on first use
    from cdpm.maps._filestore import MapFileStore

    return MapFileStore(path, read_only=read_only)
