"""Plain file operations of map stores (no zarr): the bookkeeping markers,
and a new store's skeleton written by a thread of its own
(:class:`SkeletonFiles`, :class:`cdpm.maps._store.ZarrSink`).
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

__all__ = ["SkeletonFiles", "write_new_file", "touch"]


class SkeletonFiles:
    """Writes the files of a new store's skeleton, then its created
    marker, from a thread of its own: the run computes its first chunk
    meanwhile (the compiled kernels release the GIL, and so do file
    operations), which hides the two dozen file creations (each 0.05 to
    1 ms on a local disk, the more the more files were made or deleted
    there in the last seconds).

    The files are written in place (no temporary file and rename): a store
    is not a map until it is marked created, ``open_map`` refuses it before
    (its files may be half written), and a run that finds it unmarked
    makes it again.

    Args:
        root: the store directory.
        files: [(key, bytes)]: each file's path under ``root``, and content.
        created: the marker written after every file.
    """

    def __init__(self, root: Path, files: list[tuple[str, bytes]], created: Path):
        self._stop = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(
            target=self._write, args=(root, files, created), name="cdpm-new-store", daemon=True
        )
        self._thread.start()

    def _write(self, root: Path, files: list[tuple[str, bytes]], created: Path) -> None:
        try:
            for key, data in files:
                if self._stop.is_set():
                    return
                write_new_file(root / key, data)
            touch(created)
        except BaseException as exc:  # raised in the run's thread by wait()
            self._error = exc

    def wait(self, stop: bool = False) -> None:
        """Wait until every file is written; with ``stop``, stop after the
        file being written and raise nothing, else raise what writing
        raised."""
        if stop:
            self._stop.set()
        self._thread.join()
        if self._error is not None and not stop:
            raise self._error


def write_new_file(path: Path, data: bytes) -> None:
    """Write ``data`` to the file ``path`` of a store being created, in
    place, with its folder (:class:`SkeletonFiles`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)


def touch(path: Path) -> None:
    """Create an empty marker file atomically (rename of a temporary file)."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.flush()
    os.replace(tmp, path)
