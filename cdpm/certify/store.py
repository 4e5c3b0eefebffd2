"""Certified map stores: a certified map in a zarr store, written chunk by
chunk and resumable (:class:`CertifiedStore`), read back by
:func:`read_certified` (:func:`cdpm.open_certified` builds the map).

Layout of ``<store>`` (a zarr v3 group, readable with ``zarr`` or
``xarray.open_zarr``; ``K`` boxes, ``P`` direction patches, ``nv`` natural
coordinates, ``p`` outputs):

- group attributes: ``cdpm_kind`` = ``"certified_map"``, the settings a
  resumed run must match (``cdpm_certified_settings``, JSON), the
  provenance (``spec``, ``spec_sha256``, ``cdpm_version``, ``created``),
  the mapped ``coordinates`` with their ``units``, ``robot_coordinates``,
  ``wraps``, ``min_fraction``, and the reach-margin bound's ``horizon``
  [s], ``tension_budget`` [N] and ``margin_unit``;
- arrays, written once every chunk is done: ``lower``, ``upper`` (K, nv)
  [rad or m], ``verdict`` (K,) int8, ``reason_code`` (K,) int32 (an index
  into its attribute ``reasons``, the distinct reason lines),
  ``margin_lower`` (K,), ``patch_start`` (K + 1,), ``faces`` (P,),
  ``patches`` (P, p - 1, 2), ``columns`` (P,), ``separator`` (K, p),
  ``cell`` (K,), ``base`` (nv,) and ``edges_<coordinate>`` per mapped axis
  (:class:`cdpm.certify.box.CertifiedBoxes` and
  :class:`cdpm.certify.map.CertifiedMap` name what each holds).

Resumption bookkeeping lives in ``<store>/.cdpm/`` (zarr ignores it):
``created`` once the group and its settings are written; ``parts/<k>.npz``
(chunk k's boxes, written atomically) and then ``done/<k>``; ``complete``
once the arrays are written (the parts are then deleted). A run that
stopped leaves every chunk with a done marker complete, and the next run
with the same settings certifies only the others.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError
from cdpm.maps.runtime import (
    StoreSettingsError,
    file_store,
    settings_difference,
    zarr_warnings_silenced,
)
from cdpm.verdicts import MARGINAL, NO, YES

__all__ = ["CertifiedStore", "PartWriter", "read_certified", "KIND"]

#: the group attribute ``cdpm_kind`` of a certified map store
KIND = "certified_map"

_META = ".cdpm"

#: rows per zarr chunk of the box and patch arrays
ROWS_PER_ZARR_CHUNK = 65536


def _touch(path: Path) -> None:
    """Create an empty marker file atomically."""
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    tmp.write_bytes(b"")
    os.replace(tmp, path)


class PartWriter:
    """Writes a chunk's arrays into a store's ``.cdpm/parts`` (atomically:
    a temporary file renamed), then its done marker. Picklable: local
    worker processes write their own chunks.

    Args:
        path: the store directory.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = str(path)

    def write(self, index: int, data: dict) -> None:
        meta = Path(self.path) / _META
        part = meta / "parts" / f"{index}.npz"
        tmp = part.with_name(f"{index}.{os.getpid()}.tmp.npz")
        np.savez(tmp, **data)
        os.replace(tmp, part)
        _touch(meta / "done" / str(index))


class CertifiedStore:
    """A resumable certified map store on the local file system.

    Args:
        path: the store directory (``*.zarr`` by convention).
        settings: what the map is made with (a resumed store must match).
        overwrite: replace an existing store at ``path``.

    Raises:
        InputError: ``path`` is a folder of other files, or a store of
            another kind (a sampled map) without ``overwrite``.
        StoreSettingsError: ``path`` holds a certified map made with other
            settings, and ``overwrite`` is False.
    """

    def __init__(self, path: str | os.PathLike, settings: dict, overwrite: bool = False):
        self.path = Path(path).expanduser()
        self.settings = settings
        meta = self.path / _META
        if self.path.is_dir() and not any(self.path.iterdir()):
            pass  # an empty folder
        elif self.path.exists():
            if not self.path.is_dir() or not ((self.path / "zarr.json").is_file() or meta.is_dir()):
                raise InputError(
                    f"{self.path} exists and is not a zarr store; cdpm neither writes into it "
                    "nor deletes it: choose another output path (--out)"
                )
            if overwrite or not (meta / "created").is_file():
                # replaced, or a run stopped while creating it: made again
                shutil.rmtree(self.path)
            else:
                self._check(self._attrs())
        if not (meta / "created").is_file():
            self._create()

    def _attrs(self) -> dict:
        # zarr: loaded on first use
        import zarr

        group = zarr.open_group(file_store(self.path, read_only=True), mode="r")
        return dict(group.attrs)

    def _check(self, attrs: dict) -> None:
        if attrs.get("cdpm_kind") != KIND:
            what = "a sampled map (cdpm map)" if "cdpm_settings" in attrs else "not a cdpm store"
            raise InputError(
                f"{self.path} holds {what}, not a certified map; choose another output path "
                "(--out, store=) or pass --overwrite (overwrite=True) to replace it"
            )
        stored = json.loads(attrs.get("cdpm_certified_settings", "{}"))
        diff = settings_difference(stored, self.settings, cells=True)
        if diff:
            raise StoreSettingsError(self.path, diff)

    def _create(self) -> None:
        # zarr: loaded on first use
        import zarr

        meta = self.path / _META
        attrs = {
            "title": "cdpm certified map",
            "cdpm_kind": KIND,
            "cdpm_certified_settings": json.dumps(self.settings, sort_keys=True),
        }
        zarr.create_group(
            store=file_store(self.path), attributes=attrs, zarr_format=3, overwrite=True
        )
        # after the group (zarr empties the folder it creates a group in)
        (meta / "parts").mkdir(parents=True, exist_ok=True)
        (meta / "done").mkdir(parents=True, exist_ok=True)
        _touch(meta / "created")

    @property
    def complete(self) -> bool:
        """Whether every chunk is done and the arrays are written."""
        return (self.path / _META / "complete").is_file()

    def done(self) -> set[int]:
        """Indices of the chunks whose boxes are in the store."""
        folder = self.path / _META / "done"
        if not folder.is_dir():
            return set()
        return {int(p.name) for p in folder.iterdir() if p.name.isdigit()}

    @property
    def writer(self) -> PartWriter:
        """A picklable writer of this store's chunks, for worker processes."""
        return PartWriter(self.path)

    def write(self, index: int, data: dict) -> None:
        """Write chunk ``index``'s arrays, then its done marker."""
        self.writer.write(index, data)

    def read(self, index: int) -> dict:
        """Chunk ``index``'s arrays, as written."""
        with np.load(self.path / _META / "parts" / f"{index}.npz", allow_pickle=False) as f:
            return {name: f[name] for name in f.files}

    def finish(self, cmap: Any, provenance: dict) -> None:
        """Write the whole map's arrays and attributes, mark the store
        complete and delete the chunks' parts."""
        # zarr: loaded on first use
        import zarr

        boxes = cmap.boxes
        reasons, codes = np.unique(np.asarray(boxes.reason).astype(str), return_inverse=True)
        group = zarr.open_group(file_store(self.path), mode="r+")
        attrs = {
            **dict(group.attrs),
            "spec": provenance["spec"],
            "spec_sha256": provenance["spec_sha256"],
            "cdpm_version": provenance["cdpm_version"],
            "created": provenance["created"],
            "coordinates": list(cmap.coordinates),
            "units": list(cmap.units),
            "robot_coordinates": list(self.settings["coordinates"]),
            "wraps": [bool(w) for w in cmap.wraps],
            "min_fraction": float(cmap.min_fraction),
            "horizon": float(boxes.horizon),
            "tension_budget": float(boxes.tension_budget),
            "margin_unit": str(boxes.margin_unit),
        }
        arrays = {
            "lower": (boxes.lower, ["box", "coordinate"], {}),
            "upper": (boxes.upper, ["box", "coordinate"], {}),
            "verdict": (
                boxes.verdict,
                ["box"],
                {"codes": f"{YES} YES (proven), {NO} NO (proven), {MARGINAL} undecided"},
            ),
            "reason_code": (
                codes.reshape(-1).astype(np.int32),
                ["box"],
                {"reasons": [str(r) for r in reasons]},
            ),
            "margin_lower": (boxes.margin_lower, ["box"], {"units": str(boxes.margin_unit)}),
            "patch_start": (boxes.patch_start, ["box_edge"], {}),
            "faces": (boxes.faces, ["patch"], {}),
            "patches": (boxes.patches, ["patch", "direction", "bound"], {}),
            "columns": (boxes.columns, ["patch"], {}),
            "separator": (boxes.separator, ["box", "output"], {}),
            "cell": (cmap.cell, ["box"], {}),
            "base": (cmap.base, ["coordinate"], {}),
        }
        for name, values in zip(cmap.coordinates, cmap.edges, strict=True):
            unit = dict(zip(cmap.coordinates, cmap.units, strict=False)).get(name)
            arrays[f"edges_{name}"] = (values, [f"edge_{name}"], {"units": unit} if unit else {})
        for name, (values, dims, array_attrs) in arrays.items():
            values = np.asarray(values)
            chunks = (max(1, min(values.shape[0], ROWS_PER_ZARR_CHUNK)),) + tuple(
                max(1, s) for s in values.shape[1:]
            )
            group.create_array(
                name,
                data=values,
                chunks=chunks,
                dimension_names=dims,
                attributes=array_attrs,
                overwrite=True,
            )
        group.attrs.update(attrs)
        _touch(self.path / _META / "complete")
        shutil.rmtree(self.path / _META / "parts", ignore_errors=True)

    def close(self) -> None:
        """Nothing is written in the background."""


def read_certified(path: str | os.PathLike) -> tuple[dict, dict]:
    """The arrays and attributes of a certified map store.

    Returns:
        ({name: array} of every array in the store (module docstring), and
        ``reason`` (K,) str, the reason line of each box; the group's
        attributes).

    Raises:
        InputError: ``path`` is missing, not a zarr store, a store of
            another kind (a sampled map), or a certified map whose run has
            not finished (the message says how to finish it).
    """
    # zarr: loaded on first use
    import zarr

    p = Path(path).expanduser()
    make = "make one with `cdpm certify SPEC --axis ... --out STORE` (or cdpm.certify_map(store=))"
    if not p.exists():
        raise InputError(f"certified map store {p} not found; {make}")
    if not (p / "zarr.json").is_file():
        raise InputError(f"{p} is not a zarr store; {make}")
    try:
        group = zarr.open_group(file_store(p, read_only=True), mode="r")
        attrs = dict(group.attrs)
    except (ValueError, KeyError, TypeError, OSError) as exc:
        reason = (str(exc).splitlines() or [""])[0]
        raise InputError(f"{p} cannot be read as a zarr group ({reason}); {make}") from None
    if attrs.get("cdpm_kind") != KIND:
        if "cdpm_settings" in attrs:
            raise InputError(
                f"{p} is a sampled map (made by `cdpm map`), not a certified map: open it with "
                "cdpm.open_map, or make a certified map with `cdpm certify`"
            )
        raise InputError(f"{p} is a zarr store but not a cdpm certified map; {make}")
    if not (p / _META / "complete").is_file():
        done = p / _META / "done"
        n_done = sum(x.name.isdigit() for x in done.iterdir()) if done.is_dir() else 0
        raise InputError(
            f"certified map store {p} is not finished ({n_done} chunk(s) done): run the same "
            f"`cdpm certify SPEC ... --out {p}` (or certify_map(..., store=)) again to finish it"
        )
    try:
        with zarr_warnings_silenced():  # .cdpm/ is not a zarr node
            arrays = {name: np.asarray(array[...]) for name, array in group.arrays()}
        reasons = np.array(group["reason_code"].attrs["reasons"], dtype=str)
        arrays["reason"] = reasons[arrays["reason_code"]]
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise InputError(
            f"certified map store {p} is damaged ({type(exc).__name__}: {exc}); make it again "
            "with --overwrite (overwrite=True)"
        ) from None
    return arrays, attrs
