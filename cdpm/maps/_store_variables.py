"""A variable added to a finished map store: its POC regions
(``poc_region``), written by the run that made the map or by
:func:`cdpm.maps.regions.attach_regions` afterwards."""

from __future__ import annotations

from pathlib import Path

from cdpm.errors import InputError
from cdpm.maps._store import CHUNK_KEY_ENCODING
from cdpm.maps._zarr_calls import file_store, write_metadata

__all__ = ["write_variable"]


def write_variable(path: Path, values, group=None) -> None:
    """Write the named ``xarray.DataArray`` ``values`` (dims as ``poc``'s)
    as the store's array of that name (fill value 0), chunked like ``poc``, replacing
    any, and add it to the store's consolidated metadata: one call into
    zarr's event loop (the POC regions of a finished map, ``poc_region``).
    ``group``: the store's zarr AsyncGroup with its consolidated metadata,
    if at hand (the run that created the store, which has no such array
    yet), else the store is opened.

    Raises:
        InputError: ``path`` is not a map store.
    """
    write_metadata(lambda: _write_variable(path, values, group))


async def _write_variable(path: Path, values, group=None) -> None:
    # zarr: loaded on first use
    from zarr.api.asynchronous import consolidate_metadata, open_group

    if group is not None:
        await _add_variable(group, values)
        return
    store = file_store(path)
    try:
        if not (path / "zarr.json").is_file():  # opening would create the folder
            raise FileNotFoundError(f"no zarr group at {path}")
        group = await open_group(store, mode="r+")
    except (FileNotFoundError, ValueError, KeyError, TypeError, OSError) as exc:
        raise InputError(
            f"cannot write {values.name} into map store {path} ({type(exc).__name__}: "
            f"{exc}); give the store the map was written to"
        ) from exc
    if not await group.contains("poc"):
        raise InputError(f"{path} is not a cdpm map store (no 'poc' array)")
    poc = await group.getitem("poc")
    # overwrite: replaces the values of an earlier run, and the array a run
    # killed mid-write leaves without metadata
    array = await group.create_array(
        values.name, **_array_options(values, poc.chunks), overwrite=True
    )
    await array.setitem(..., values.values)
    consolidated = group.metadata.consolidated_metadata
    members = {p.name for p in path.iterdir() if (p / "zarr.json").is_file()}
    if consolidated is None or set(consolidated.metadata) | {values.name} != members:
        # metadata never consolidated, or arrays added or removed since
        await consolidate_metadata(store)
        return
    # add the array to the consolidated metadata of the group (as read when
    # it was opened, or as this run created it) and save the group's
    # metadata (update_attributes writes it, consolidated part included):
    # one file written, where consolidating again reads every array's
    # metadata back from disk
    consolidated.metadata[values.name] = array.metadata
    await group.update_attributes({})


async def _add_variable(group, values) -> None:
    """:func:`_write_variable` into the store this run created (``group``,
    its AsyncGroup with the consolidated metadata it was made with), which
    has no array of that name: the array's metadata made in memory, as
    zarr makes it (no look for an array to replace: 2 ms), its document
    and chunks written, then the group's document with the array added to
    its consolidated metadata."""
    # zarr: loaded on first use
    from zarr import AsyncArray
    from zarr.api.asynchronous import create_array
    from zarr.core.buffer import default_buffer_prototype
    from zarr.storage import MemoryStore, StorePath

    poc = group.metadata.consolidated_metadata.metadata["poc"]
    made = await create_array(MemoryStore(), **_array_options(values, poc.chunk_grid.chunk_shape))
    where = StorePath(group.store_path.store, values.name)
    document = made.metadata.to_buffer_dict(default_buffer_prototype())["zarr.json"]
    await (where / "zarr.json").set(document)
    await AsyncArray(made.metadata, where).setitem(..., values.values)
    group.metadata.consolidated_metadata.metadata[values.name] = made.metadata
    await group.update_attributes({})


def _array_options(values, chunks) -> dict:
    """zarr's options for the array of ``values`` (a named DataArray), in
    ``chunks`` (``poc``'s), fill value 0: one set for both ways of writing
    it."""
    return {
        "shape": values.shape,
        "chunks": chunks,
        "dtype": values.dtype,
        "fill_value": 0,
        "dimension_names": list(values.dims),
        "attributes": dict(values.attrs),
        "chunk_key_encoding": CHUNK_KEY_ENCODING,
    }
