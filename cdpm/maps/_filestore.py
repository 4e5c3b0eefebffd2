"""The zarr store every map store is read and written through.

zarr's ``LocalStore`` hands each whole-file read and write to a thread of
its own (``asyncio.to_thread``). A map store's files are small (a
metadata document of a few kB, a chunk of at most a few MB), so the hop to
and from the thread costs more than the file operation: a map writes two
dozen files per chunk and reads as many when it is opened. This store does
whole-file reads and writes directly in zarr's event loop, and looks for
a file before zarr's exclusive creation of it (which zarr asks for the
parent group's metadata of every array it creates, there already);
everything else (listing, deleting, byte-range reads) is zarr's own.
:func:`write_new_files` writes the files of a store being created.

Imported only where zarr is (maps to a store, ``open_map``).
"""

from __future__ import annotations

import os
from pathlib import Path

from zarr.core.buffer import Buffer, BufferPrototype, default_buffer_prototype
from zarr.storage import LocalStore

__all__ = ["MapFileStore", "write_new_files"]


class MapFileStore(LocalStore):
    """``zarr.storage.LocalStore`` with whole-file reads and writes done in
    the calling event loop instead of a worker thread each.

    A write goes to ``<file>.<pid>.partial`` and is renamed over the file,
    as ``LocalStore`` does: a reader never sees a half-written file, and
    processes writing different files of one store (map workers, each its
    own chunks) never share a temporary file. The files of a store being
    created are written apart (:func:`write_new_files`).

    Args:
        root: the store directory.
        read_only: refuse writes.
    """

    async def get(
        self,
        key: str,
        prototype: BufferPrototype | None = None,
        byte_range=None,
    ) -> Buffer | None:
        if byte_range is not None:
            return await super().get(key, prototype, byte_range)
        if not self._is_open:
            await self._open()
        try:
            data = (self.root / key).read_bytes()
        except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
            return None
        return (prototype or default_buffer_prototype()).buffer.from_bytes(data)

    async def set_if_not_exists(self, key: str, value: Buffer) -> None:
        # zarr calls this for each parent group of an array it creates,
        # whose metadata is there already: looked for first, without
        # LocalStore's temporary file and thread hop
        await self._open_writable()
        if not (self.root / key).exists():
            await super().set_if_not_exists(key, value)

    async def set(self, key: str, value: Buffer) -> None:
        path = await self._path_to_write(key, value)
        partial = path.with_name(f"{path.name}.{os.getpid()}.partial")
        try:
            with open(partial, "wb") as fh:
                fh.write(value.as_buffer_like())
            os.replace(partial, path)
        except BaseException:
            partial.unlink(missing_ok=True)
            raise

    async def _path_to_write(self, key: str, value: Buffer):
        """The file of ``key``, its folder made; refuses a read-only store
        and a value that is not a zarr Buffer."""
        await self._open_writable()
        if not isinstance(value, Buffer):
            raise TypeError(f"MapFileStore.set(): value must be a zarr Buffer, got {type(value)}")
        path = self.root / key
        path.parent.mkdir(parents=True, exist_ok=True)
        return path

    async def _open_writable(self) -> None:
        """Open the store if it is not yet; refuse a read-only one."""
        if not self._is_open:
            await self._open()
        self._check_writable()


def write_new_files(root: Path, files: dict[str, bytes]) -> None:
    """Write the files {key: bytes} of a zarr store being created at
    ``root`` (keys as zarr names them, e.g. ``poc/zarr.json``), each in
    place: no temporary file and rename, which cost 1-2 ms of a new map
    store's four dozen files. A store that is still being created is not a
    map yet: cdpm marks it created once every file is written, refuses to
    open it before (``open_map``), and a run that finds it unmarked makes
    it again."""
    folders = set()
    for key, data in files.items():
        path = root / key
        if path.parent not in folders:
            path.parent.mkdir(parents=True, exist_ok=True)
            folders.add(path.parent)
        write_new_file(path, data)


def write_new_file(path: Path, data: bytes) -> None:
    """Write one file of a store being created (:func:`write_new_files`)."""
    with open(path, "wb") as fh:
        fh.write(data)
