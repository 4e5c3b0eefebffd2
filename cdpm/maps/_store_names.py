"""What a map store may be named: a zarr directory, so not a name that
reads as an image or another data file (which would become a directory of
that name)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["IMAGE_SUFFIXES", "DATA_SUFFIXES", "store_path_problem"]

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
