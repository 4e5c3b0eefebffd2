"""Where map chunks go: a zarr store on disk (resumable) or memory.

Zarr layout (readable with ``xarray.open_zarr``): one array per data
variable, chunked like the map's chunks, so each map chunk is written by a
region write into its own zarr chunks; coordinates and provenance attributes
are written when the store is created. Resumption bookkeeping lives beside
the arrays, in ``<store>/.cdpm/`` (zarr ignores it):

- ``created``: written once the skeleton (every array and attribute) exists
  (its files are written in a thread of their own while the first chunk is
  computed, :class:`ZarrSink`);
- ``done/<k>``: written after chunk k's data is in the store. Files appear
  in that order, so after a crash (Ctrl-C, SIGKILL) every chunk with a
  marker is complete and the others are recomputed from scratch.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import threading
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cdpm.errors import InputError
from cdpm.maps._zarr_calls import (
    INTERRUPT_SETTLE_SECONDS,
    file_store,
    sync,
    write_metadata,
    zarr_warnings_silenced,
)
from cdpm.maps.plan import MapPlan, settings_difference
from cdpm.model.coordinates import coordinate_units
from cdpm.pipeline.criteria import CRITERIA, CRITERION_DIMS, bytes_per_pose, extra_size

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = [
    "IMAGE_SUFFIXES",
    "DATA_SUFFIXES",
    "store_path_problem",
    "ZarrSink",
    "MemorySink",
    "ChunkWriter",
    "open_map",
    "variable_specs",
]

# ------------------------------------------------------------ store names
#
# A store is a zarr directory: not a name that reads as an image or another
# data file (which would become a directory of that name).

#: extensions of image and document files: a store named so is a mistake
#: (a store is a zarr directory; images are drawn from it)
IMAGE_SUFFIXES = frozenset(
    {".png", ".jpg", ".jpeg", ".gif", ".bmp", ".tif", ".tiff", ".webp", ".avif"}
    | {".svg", ".svgz", ".pdf", ".eps", ".ps", ".pgf", ".raw", ".rgba"}
)

#: extensions of other data files -> their format's name
DATA_SUFFIXES = {
    ".nc": "netCDF",
    ".h5": "HDF5",
    ".hdf5": "HDF5",
    ".csv": "CSV",
    ".json": "JSON",
    ".npy": "NumPy",
    ".npz": "NumPy",
    ".parquet": "Parquet",
    ".pkl": "pickle",
    ".txt": "text",
    ".yaml": "YAML",
    ".yml": "YAML",
}


def store_path_problem(path) -> str | None:
    """What is wrong with ``path`` as the name of a map store, or None.

    A store is a zarr directory; a path ending like an image (``m.png``) or
    another file format (``m.nc``) would become a directory of that name.

    Returns:
        e.g. ``"an image (.png)"`` or ``"a netCDF file (.nc)"``; None for a
        name without such an extension (``m.zarr`` by convention).
    """
    suffix = Path(path).suffix.lower()
    if suffix in IMAGE_SUFFIXES:
        return f"an image ({suffix})"
    if suffix in DATA_SUFFIXES:
        return f"a {DATA_SUFFIXES[suffix]} file ({suffix})"
    return None


_META = ".cdpm"

#: chunk files side by side (c.3.0), not nested folders (c/3/0): a chunk
#: then creates no folder (each coordinate, data variable and the regions)
CHUNK_KEY_ENCODING = {"name": "default", "separator": "."}

#: largest map [bytes of its variables] that the run writing it also keeps
#: in memory and returns from there (:meth:`ZarrSink.dataset`), when it
#: computed every chunk itself: reading a store back costs about 6 ms
#: whatever its size, a third of a 2048-pose map under load
RESULT_IN_MEMORY_MAX = 64 * 1024**2


def variable_specs(robot: CableRobot, plan: MapPlan) -> dict[str, tuple]:
    """name -> (extra dims, dtype, fill value, attrs) of every data variable
    (one per registered criterion, :data:`cdpm.pipeline.criteria.CRITERIA`)."""
    return {name: (c.dims, c.dtype, c.fill, c.attrs(robot)) for name, c in CRITERIA.items()}


def _attrs(robot: CableRobot, plan: MapPlan) -> dict:
    s = plan.settings
    bounds = {
        name: [float(lo), float(hi)]
        for name, lo, hi in zip(
            robot.cable_names, robot.tension_min, robot.tension_max, strict=True
        )
    }
    return {
        "title": f"cdpm workspace map of {robot.spec.path.name}",
        "cdpm_version": s["cdpm_version"],
        "spec": str(robot.spec.path),
        "spec_sha256": s["spec_sha256"],
        "axes": list(plan.names),
        "mode": plan.mode,
        "base": s["base"],
        "robot_coordinates": s["coordinates"],
        "tension": json.dumps(s["tension"]),
        "chunk_size": s["chunk_size"],
        **{k: s[k] for k in ("reach_horizon", "tension_budget") if k in s},
        # the robot as mapped: gravity [m/s^2], bounds [N], pretension [N],
        # and what of them differs from the spec file
        "gravity": [float(x) for x in robot.gravity],
        "cable_tension_bounds": json.dumps(bounds),
        "pretension": float(robot.spec.pretension or 0.0),
        "overrides": json.dumps(s.get("overrides", {}), sort_keys=True),
        "cdpm_settings": json.dumps(s, sort_keys=True),
    }


def _coords(robot: CableRobot, plan: MapPlan) -> dict:
    units = dict(zip(robot.coordinate_names, coordinate_units(robot.model), strict=True))
    coords: dict = {}
    if plan.mode == "grid":
        for name, v in zip(plan.names, plan.values, strict=True):
            coords[name] = (name, v, {"units": units[name], "long_name": name})
    else:
        coords["sample"] = ("sample", np.arange(plan.shape[0]))
        for name, v in zip(plan.names, plan.values, strict=True):
            coords[name] = ("sample", v, {"units": units[name], "long_name": name})
    labels = {"output": robot.output_names, "xyz": ["x", "y", "z"], "cable": robot.cable_names}
    for dim in CRITERION_DIMS:  # the order _in_map_order lists them in
        if any(dim in c.dims for c in CRITERIA.values()):
            coords[dim] = (dim, np.array(labels[dim], dtype=str))
    return coords


class MemorySink:
    """Chunks written into numpy arrays; :meth:`dataset` wraps them."""

    def __init__(self, robot: CableRobot, plan: MapPlan):
        self.robot, self.plan = robot, plan
        self.specs = variable_specs(robot, plan)
        self.arrays = {
            name: np.full(
                plan.shape + tuple(extra_size(robot, d) for d in extra), fill, dtype=dtype
            )
            for name, (extra, dtype, fill, _) in self.specs.items()
        }

    def done(self) -> set[int]:
        return set()

    def write(self, index: int, data: dict) -> None:
        region = self.plan.region(index)
        shape = tuple(s.stop - s.start for s in region)
        for name, arr in self.arrays.items():
            value = data[name]
            arr[region] = value.reshape(shape + value.shape[1:])

    #: no zarr group (see ZarrSink.group), nor a writer for workers
    #: (they return their chunks to this process)
    group = writer = None

    def close(self) -> None:
        """Nothing to wait for (see :meth:`ZarrSink.close`)."""

    def dataset(self):
        # xarray: loaded on first use
        import xarray as xr

        dims = self.plan.dims
        data_vars = {
            name: (dims + extra, self.arrays[name], attrs)
            for name, (extra, _, _, attrs) in self.specs.items()
        }
        return xr.Dataset(
            data_vars, coords=_coords(self.robot, self.plan), attrs=_attrs(self.robot, self.plan)
        )


class StoreSettingsError(InputError):
    """A map store holds a map made with other settings, so it cannot be
    resumed.

    Attributes:
        path: the store.
        differences: one line per differing setting (stored vs asked for).
    """

    def __init__(self, path, differences: list[str]):
        self.path, self.differences = Path(path), list(differences)
        super().__init__(
            self.explain("call again with the stored settings", "pass overwrite=True", "store=")
        )

    def explain(self, resume: str, replace: str, other: str) -> str:
        """The message, with the ways to resume, replace or go elsewhere
        worded for the caller (Python arguments or command-line options)."""
        lines = "\n".join(f"  - {d}" for d in self.differences)
        return (
            f"{self.path} holds a map made with different settings, so it cannot be "
            f"resumed:\n{lines}\nto resume it, {resume}; to replace it, {replace}; or give "
            f"another {other}"
        )


class ZarrSink:
    """A resumable zarr store on the local file system.

    Args:
        path: directory of the store (``*.zarr`` by convention).
        robot, plan: what is mapped.
        overwrite: delete an existing store at ``path`` first.

    Raises:
        InputError: ``path`` holds a store made with other settings (or
            something that is not a cdpm map) and ``overwrite`` is False.
    """

    def __init__(self, path, robot, plan: MapPlan, overwrite: bool = False):
        self.path = Path(path).expanduser()
        self.robot, self.plan = robot, plan
        self.specs = variable_specs(robot, plan)
        created = self.path / _META / "created"
        if self.path.is_dir() and not any(self.path.iterdir()):
            pass  # an empty folder (made for the map, or a run killed at once)
        elif self.path.exists():
            is_map = created.is_file()
            self._refuse_a_folder_of_other_files()
            if overwrite or (not is_map and (self.path / _META).is_dir()):
                # a map killed while its skeleton was written is remade
                self._remove()
            elif not is_map:
                raise InputError(
                    f"{self.path} exists and is not a cdpm map store; choose another output "
                    "path (--out) or pass overwrite=True (--overwrite) to replace it"
                )
            else:
                self._check_settings()
        self._writer: ChunkWriter | None = None
        #: keep the chunks this process writes in memory, for the map this
        #: run returns (:meth:`dataset`): set when this run creates the store
        #: and the map is at most RESULT_IN_MEMORY_MAX bytes; the caller
        #: clears it when worker processes will write chunks too
        self.keep = False
        self._written: set[int] = set()  # the chunks this process wrote
        self._memory: MemorySink | None = None  # their values, when kept
        #: the store's zarr AsyncGroup, with its consolidated metadata, when
        #: this run created the store (else None: it is opened when needed)
        self.group = None
        #: the thread writing the files of the store this run creates,
        #: until a write, the map or close() has waited for it
        self._creating: _Background | None = None
        self._done_dir = self.path / _META / "done"
        if not created.is_file():
            self._create()  # last: it starts that thread

    def _refuse_a_folder_of_other_files(self) -> None:
        """Refuse a non-empty folder that is not a zarr store: neither
        written into nor deleted, even with overwrite."""
        if (
            self.path.is_dir()
            and not ((self.path / "zarr.json").is_file() or (self.path / _META).is_dir())
            and any(self.path.iterdir())
        ):
            raise InputError(
                f"{self.path} is a folder of other files, not a zarr store; cdpm neither writes "
                "into it nor deletes it (not even with --overwrite): choose another output "
                "path (--out)"
            )

    def _remove(self) -> None:
        self._refuse_a_folder_of_other_files()
        if self.path.is_dir():
            shutil.rmtree(self.path)
        else:
            self.path.unlink()

    def _check_settings(self) -> None:
        # zarr: loaded on first use
        import zarr

        group = zarr.open_group(file_store(self.path, read_only=True), mode="r")
        stored = json.loads(group.attrs.get("cdpm_settings", "{}"))
        diff = settings_difference(stored, self.plan.settings)
        if diff:
            raise StoreSettingsError(self.path, diff)

    def _create(self) -> None:
        # the bookkeeping folder first: a run stopped while writing the
        # skeleton leaves a store without its created marker, which the
        # next run makes again
        (self.path / _META / "done").mkdir(parents=True, exist_ok=True)
        self.group, arrays, files = write_metadata(self._create_skeleton)
        # this process's chunks go straight into the arrays just made
        self._writer = ChunkWriter(str(self.path), self.plan, tuple(self.specs), arrays)
        self.keep = bytes_per_pose(self.robot) * self.plan.n_poses <= RESULT_IN_MEMORY_MAX
        # the files go out while the first chunk is computed: they are
        # mostly waits on the file system (0.05-0.5 ms a file; 27 files in
        # 21 folders on a two-link model), in which the thread holds no GIL
        self._creating = _Background(lambda: _write_skeleton(self.path, files))

    def _created(self) -> None:
        """Wait until the store's files are written and it is marked
        created (when this run creates it); raises the error that stopped
        the writing (a full disk). Interrupted while it waits, it leaves
        the wait to :meth:`close`."""
        if self._creating is not None:
            self._creating.wait()
            creating, self._creating = self._creating, None
            creating.raise_error()

    def close(self) -> None:
        """Wait for the store's files to be written, if this run creates
        the store and nothing has waited for them to the end (a run
        stopped before its first chunk was written, or while it waited):
        through interrupts too, for at most INTERRUPT_SETTLE_SECONDS, so
        that no write outlives the run and its lock on the store; an
        interrupt is raised once they are written. Their errors are not
        raised here: the run is failing already."""
        creating, interrupted = self._creating, None
        if creating is None:
            return
        deadline = time.monotonic() + INTERRUPT_SETTLE_SECONDS
        while not creating.finished and time.monotonic() < deadline:
            try:
                creating.wait(deadline - time.monotonic())
            except KeyboardInterrupt as exc:
                interrupted = exc
        self._creating = None
        if interrupted is not None:
            raise interrupted

    async def _create_skeleton(self) -> tuple:
        """Build the store's skeleton in memory (:meth:`_create_arrays`);
        returns the group and the data variables' arrays {name: zarr
        AsyncArray}, in the store on disk, and the files to write there
        {key: bytes}.

        Zarr creates an array in a local store through several file-system
        round trips one after another (checks, parents, metadata), about
        1 ms an array; in memory they cost little, and the files then go
        out in one pass, from a thread of their own (:meth:`_create`).

        The group's consolidated metadata is made from the metadata of the
        arrays just created, as ``zarr.consolidate_metadata`` makes it from
        the same metadata read back from the store (the same document,
        without parsing two dozen documents again: 3-5 ms)."""
        # asyncio: loaded on first use
        import asyncio

        # zarr: loaded on first use
        from zarr import AsyncArray, AsyncGroup
        from zarr.core.group import ConsolidatedMetadata
        from zarr.storage import MemoryStore, StorePath

        memory = MemoryStore()
        group, arrays = await self._create_arrays(memory)
        consolidated = ConsolidatedMetadata(
            metadata={name: array.metadata for name, array in arrays.items()}
        )
        metadata = dataclasses.replace(group.metadata, consolidated_metadata=consolidated)
        await AsyncGroup(metadata, group.store_path)._save_metadata()
        keys = sorted([key async for key in memory.list()])
        files = await asyncio.gather(*(memory.get(key) for key in keys))
        local = file_store(self.path)
        return (
            AsyncGroup(metadata, StorePath(local, "")),
            {
                name: AsyncArray(arrays[name].metadata, StorePath(local, name))
                for name in self.specs
            },
            {key: file.to_bytes() for key, file in zip(keys, files, strict=True)},
        )

    async def _create_arrays(self, store) -> tuple:
        """Create, in the zarr ``store``, the group with the map's
        attributes, every coordinate (with its values) and every data
        variable's array, all at once.

        The layout is the one ``xarray.Dataset.to_zarr`` writes: a
        coordinate is an array named after its dimension, or, for the axes
        of a sampled map, an array along ``sample`` listed in the group's
        ``coordinates`` attribute.

        zarr creates the first data variable of each kind (dtype, extra
        dimensions' sizes, fill value); the others of that kind take its
        metadata with their own attributes and dimension names, which is
        what zarr makes for them (tested) at a sixth of the cost: a map has
        16 data variables of 4 to 6 kinds, and zarr's creation of an array
        costs about 0.2 ms of Python.

        Returns:
            (the group, every array {name: zarr AsyncArray}).
        """
        # asyncio: loaded on first use
        import asyncio

        # zarr: loaded on first use
        from zarr import AsyncArray
        from zarr.api.asynchronous import create_group
        from zarr.core.buffer import default_buffer_prototype
        from zarr.storage import StorePath

        plan = self.plan
        coords = _coords(self.robot, plan)
        attrs = _attrs(self.robot, plan)
        others = [name for name, (dim, *_) in coords.items() if dim != name]
        if others:
            attrs["coordinates"] = " ".join(others)
        group = await create_group(store=store, attributes=attrs, zarr_format=3, overwrite=True)
        creating = []
        for name, (dim, values, *rest) in coords.items():
            values = np.asarray(values)
            creating.append(
                group.create_array(
                    name,
                    data=values,
                    fill_value=np.nan if values.dtype.kind == "f" else None,
                    compressors=None,  # a few values: read without a codec's thread hop
                    dimension_names=[dim],
                    attributes=rest[0] if rest else {},
                    chunk_key_encoding=CHUNK_KEY_ENCODING,
                )
            )
        names = list(coords)
        kinds: dict[tuple, str] = {}  # (dtype, extra sizes, fill) -> its first variable
        alike: dict[str, tuple] = {}  # variable -> (first of its kind, dims, attrs)
        for name, (extra, dtype, fill, var_attrs) in self.specs.items():
            extra_shape = tuple(extra_size(self.robot, d) for d in extra)
            kind = (np.dtype(dtype).str, extra_shape, repr(fill))
            if kind in kinds:
                alike[name] = (kinds[kind], tuple(plan.dims + extra), var_attrs)
                continue
            kinds[kind] = name
            names.append(name)
            creating.append(
                group.create_array(
                    name,
                    shape=plan.shape + extra_shape,
                    chunks=plan.chunks + extra_shape,
                    dtype=dtype,
                    fill_value=fill,
                    dimension_names=list(plan.dims + extra),
                    attributes=var_attrs,
                    chunk_key_encoding=CHUNK_KEY_ENCODING,
                )
            )
        created = dict(zip(names, await asyncio.gather(*creating), strict=True))
        prototype = default_buffer_prototype()
        for name, (first, dims, var_attrs) in alike.items():
            metadata = dataclasses.replace(
                created[first].metadata, attributes=var_attrs, dimension_names=dims
            )
            document = metadata.to_buffer_dict(prototype)["zarr.json"]
            await store.set(f"{name}/zarr.json", document)
            created[name] = AsyncArray(metadata, StorePath(store, name))
        return group, {name: created[name] for name in [*coords, *self.specs]}

    def done(self) -> set[int]:
        """Indices of the chunks whose data is complete in the store."""
        if not self._done_dir.is_dir():
            return set()
        return {int(p.name) for p in self._done_dir.iterdir() if p.name.isdigit()}

    @property
    def writer(self) -> ChunkWriter:
        """A picklable writer of this store's chunks, for worker processes
        that see the same file system (once the store's files are written)."""
        self._created()
        return ChunkWriter(str(self.path), self.plan, tuple(self.specs))

    def write(self, index: int, data: dict) -> None:
        """Write chunk ``index`` (region write), then its done marker."""
        self._created()
        if self._writer is None:
            self._writer = self.writer
        self._writer.write(index, data)
        if self.keep:
            if self._memory is None:
                self._memory = MemorySink(self.robot, self.plan)
            self._memory.write(index, data)
        self._written.add(index)

    def dataset(self):
        """The map: from memory when this run created the store, computed
        every chunk in this process and kept them (a map of at most
        RESULT_IN_MEMORY_MAX bytes), else read from the store (lazily).
        Either is the dataset :func:`open_map` reads: the same values,
        coordinates and attributes, with ``encoding["source"]``."""
        self._created()
        done_here = len(self._written) == self.plan.n_chunks
        if self.keep and self._memory is not None and done_here:
            ds = self._memory.dataset()
            ds.encoding["source"] = os.path.abspath(self.path)
            return ds
        if self.group is None:  # a store this run did not create: read as it is
            return open_map(self.path)
        # the dimension coordinates as this run wrote them: xarray indexes
        # these values instead of reading each array back
        coords = _coords(self.robot, self.plan)
        return _open_map(self.path, {name: c[1] for name, c in coords.items() if c[0] == name})


def _write_skeleton(path: Path, files: dict[str, bytes]) -> None:
    """Write a new store's files {key: bytes} at ``path``, then mark it
    created."""
    # zarr: loaded on first use
    from cdpm.maps._filestore import write_new_files

    write_new_files(path, files)
    _touch(path / _META / "created")


class _Background:
    """``run()`` in a thread of its own, from construction. Its end is
    waited for on an event, not by joining the thread: a join that an
    interrupt stops marks the thread as ended in Python 3.11 while it still
    runs, and no later join waits for it."""

    def __init__(self, run):
        self._error: BaseException | None = None
        self._ended = threading.Event()

        def target() -> None:
            try:
                run()
            except BaseException as exc:  # raised in the waiting thread
                self._error = exc
            finally:
                self._ended.set()

        threading.Thread(target=target, name="cdpm-store-files").start()

    @property
    def finished(self) -> bool:
        return self._ended.is_set()

    def wait(self, timeout: float | None = None) -> None:
        """Wait for ``run()`` to end (at most ``timeout`` seconds)."""
        self._ended.wait(timeout)

    def raise_error(self) -> None:
        """Raise what stopped ``run()``, if anything did."""
        if self._error is not None:
            raise self._error


class ChunkWriter:
    """Writes map chunks into an existing store: the region of each data
    variable, then the chunk's done marker (so a marker always means the
    chunk is complete). Chunks are whole zarr chunks, so processes writing
    different chunks never touch the same file. Picklable: a worker opens
    the store on its first write.

    Args:
        path: the store directory.
        plan: the map's :class:`~cdpm.maps.plan.MapPlan`.
        names: the data variables to write.
        arrays: their zarr AsyncArrays {name: array}, if open already
            (not pickled: a worker opens its own).
    """

    def __init__(
        self, path: str, plan: MapPlan, names: tuple[str, ...], arrays: dict | None = None
    ):
        self.path, self.plan, self.names = path, plan, names
        self._arrays = arrays

    def __getstate__(self) -> dict:
        return {"path": self.path, "plan": self.plan, "names": self.names}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["path"], state["plan"], state["names"])

    def write(self, index: int, data: dict) -> None:
        # One call into zarr's event loop writes every variable's chunk
        # concurrently: a chunk's cost is mostly a fixed overhead per array
        # (a file each, and a round trip to zarr's loop thread), which a
        # write per array in turn paid serially.
        region = self.plan.region(index)
        shape = tuple(s.stop - s.start for s in region)
        values = {}
        for name in self.names:
            value = data[name]
            values[name] = value.reshape(shape + value.shape[1:])
        sync(lambda: self._write_regions(region, values))
        _touch(Path(self.path) / _META / "done" / str(index))

    async def _write_regions(self, region: tuple[slice, ...], values: dict) -> None:
        """Write ``values`` (name -> array of the region's shape) into the
        region of each variable, all at once (opening the store first)."""
        # asyncio: loaded on first use
        import asyncio

        if self._arrays is None:
            # zarr: loaded on first use
            from zarr.api.asynchronous import open_group

            group = await open_group(file_store(Path(self.path)), mode="r+")
            arrays = await asyncio.gather(*(group.getitem(name) for name in self.names))
            self._arrays = dict(zip(self.names, arrays, strict=True))
        await asyncio.gather(
            *(self._arrays[name].setitem(region, value) for name, value in values.items())
        )


def _touch(path: Path) -> None:
    """Create an empty marker file atomically (rename of a temporary file)."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.flush()
    os.replace(tmp, path)


def open_map(path):
    """Open a map store written by :func:`cdpm.workspace_map` as an
    ``xarray.Dataset`` (lazily loaded; no Dask needed).

    Raises:
        InputError: ``path`` is missing, not a zarr store, a zarr store that
            cdpm did not write (or cannot read), or a map whose run stopped
            while creating it; the message names the fix.
    """
    return _open_map(path)


def _open_map(path, index_values: dict | None = None):
    """:func:`open_map`; ``index_values`` (the map that just wrote the
    store) gives the values of every dimension coordinate {name: values},
    which xarray then indexes without reading them from the store (it reads
    each coordinate array in a call of its own into zarr's event loop,
    about 0.7 ms each). The dataset is the same as without them."""
    # xarray: loaded on first use
    import xarray as xr

    p = Path(path).expanduser()
    make = f"make it with `cdpm map SPEC ... --out {p}` (or cdpm.workspace_map(..., store=))"
    if not p.exists():
        raise InputError(f"map store {p} not found; {make}")
    fix = "give a store written by `cdpm map SPEC ... --out STORE` (or cdpm.workspace_map)"

    def incomplete(why: str = "") -> InputError:
        return InputError(
            f"map store {p} is an incomplete cdpm map (its run stopped while creating it{why}); "
            f"run the same `cdpm map SPEC ... --out {p}` again to remake it"
        )

    if (p / _META).is_dir() and not (p / _META / "created").is_file():
        # its files are written in place (write_new_files): maybe not all, or
        # half, or not yet its group's document
        raise incomplete()
    if not (p / "zarr.json").is_file() and not (p / ".zgroup").is_file():
        raise InputError(f"map store {p} is not a zarr store; {fix}")
    try:
        with zarr_warnings_silenced():
            # a store without consolidated metadata reads as well, only slower
            warnings.filterwarnings("ignore", "Failed to open Zarr", RuntimeWarning)
            ds = xr.open_zarr(
                file_store(p, read_only=True),
                chunks=None,
                create_default_indexes=index_values is None,
            )
        # as xarray records a store opened by its path (opened through a
        # store object, it records nothing)
        ds.encoding["source"] = os.path.abspath(p)
    except (ValueError, KeyError, TypeError, OSError) as exc:
        # zarr's and json's errors on a damaged store or on a zarr array (not a group)
        reason = (str(exc).splitlines() or [""])[0]
        raise InputError(
            f"map store {p} cannot be read as a zarr group ({type(exc).__name__}: {reason}); {fix}"
        ) from exc
    if ds.attrs.get("cdpm_kind") == "certified_map":
        raise InputError(
            f"{p} is a certified map (made by `cdpm certify`), not a sampled one: open it with "
            "cdpm.open_certified; `cdpm path` takes either"
        )
    if "cdpm_settings" not in ds.attrs:
        raise InputError(
            f"map store {p} is a zarr store but not a cdpm map (no cdpm_settings); {fix}"
        )
    if "poc" not in ds.data_vars:
        raise incomplete(": no 'poc' variable")
    if index_values is not None:
        # the indexes xarray makes when it reads the coordinates itself:
        # the lazily read variables (attributes, encoding) with these values
        ds = ds.assign_coords(
            xr.Coordinates(
                {
                    name: ds[name].variable.copy(data=np.asarray(values))
                    for name, values in index_values.items()
                }
            )
        )
    return _in_map_order(ds)


def _in_map_order(ds):
    """``ds`` with its coordinates listed in the order the map lists them
    (:func:`_coords`: ``sample`` of a sampled map, the axes, then
    ``output``, ``xyz``, ``cable``), not by name as zarr lists a store's
    arrays; the same variables (lazily loaded), indexes and attributes."""
    # xarray: loaded on first use
    import xarray as xr

    axes = ds.attrs.get("axes", [])
    axes = [axes] if isinstance(axes, str) else list(axes)
    first = ["sample", *axes, *CRITERION_DIMS]
    order = [c for c in first if c in ds.coords] + [c for c in ds.coords if c not in first]
    if list(ds.coords) == order:
        return ds
    coords = xr.Coordinates(
        {name: ds.coords[name].variable for name in order},
        indexes={name: ds.xindexes[name] for name in order if name in ds.xindexes},
    )
    data_vars = {name: value.variable for name, value in ds.data_vars.items()}
    out = xr.Dataset(data_vars, coords=coords, attrs=ds.attrs)
    out.encoding = dict(ds.encoding)
    return out
