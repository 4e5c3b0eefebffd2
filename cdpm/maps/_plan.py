"""What a map covers: axes, the base pose, the chunk layout and settings.

A :class:`MapPlan` is plain data (picklable, JSON-able settings) built once
by the driver. It turns a chunk index into the region of the dataset the
chunk fills and the natural coordinates of its poses, so the driver, local
workers and Dask workers all agree on what chunk k is.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.errors import InputError
from cdpm.maps.criteria import CRITERIA
from cdpm.numerics import SPAN_TOL

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.robot import CableRobot

__all__ = ["SampledAxes", "MapPlan", "sample_axes", "make_plan", "coordinate_units"]

#: default number of poses per chunk
DEFAULT_CHUNK_SIZE = 16384


@dataclass(frozen=True)
class SampledAxes:
    """Random poses: one value per sample for each named coordinate.

    Build with :func:`sample_axes`. :func:`cdpm.workspace_map` maps these
    along a single ``sample`` dimension instead of a grid.

    Attributes:
        values: coordinate name -> values, each shape (n,).
        ranges: coordinate name -> (low, high) the values were drawn from.
        seed: the random seed used (None for explicit values).
    """

    values: dict[str, np.ndarray]
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    seed: int | None = None

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(next(iter(self.values.values()))) if self.values else 0


def sample_axes(
    ranges: Mapping[str, tuple[float, float]], n: int, seed: int | None = 0
) -> SampledAxes:
    """Draw ``n`` poses uniformly in a box of natural coordinates.

    Args:
        ranges: coordinate name -> (low, high) [rad or m].
        n: number of samples (>= 1).
        seed: seed of ``numpy.random.default_rng``; the same seed gives the
            same samples.

    Returns:
        :class:`SampledAxes` for :func:`cdpm.workspace_map`.
    """
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"samples must be a positive integer, got {n!r}")
    if not ranges:
        raise InputError("give at least one coordinate range to sample, e.g. {'q1': (-3.14, 3.14)}")
    rng = np.random.default_rng(seed)
    values, clean = {}, {}
    for name, bounds in ranges.items():
        try:
            lo, hi = (float(b) for b in bounds)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"sample range of {name!r} must be (low, high), got {bounds!r}"
            ) from exc
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise InputError(
                f"sample range of {name!r} must be finite with low <= high, got {bounds!r}"
            )
        clean[name] = (lo, hi)
        values[name] = rng.uniform(lo, hi, int(n))
    return SampledAxes(values=values, ranges=clean, seed=seed)


def coordinate_units(model) -> list[str]:
    """Unit of each natural coordinate: ``"m"`` for translations, ``"rad"`` for angles."""
    units: list[str] = []
    for j in range(1, model.njoints):
        name = model.joints[j].shortname()
        nv = model.joints[j].nv
        if name == "JointModelFreeFlyer":
            units += ["m"] * 3 + ["rad"] * 3
        elif name == "JointModelPlanar":
            units += ["m", "m", "rad"]
        elif name == "JointModelTranslation" or name.startswith("JointModelP"):
            units += ["m"] * nv
        else:
            units += ["rad"] * nv
    return units


def _digest(values: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(values, dtype="<f8").tobytes()).hexdigest()[:16]


@dataclass(frozen=True)
class MapPlan:
    """The poses of a map and how they are cut into chunks.

    Attributes:
        mode: ``"grid"`` or ``"sample"``.
        names: axis (coordinate) names, in dimension order.
        values: values of each axis: grid coordinates (n_k,) or per-sample
            values (n,).
        columns: index of each axis in the natural coordinates.
        base: natural coordinates of the base pose, shape (nv,).
        shape: dataset shape of the pose dimensions.
        chunks: chunk shape (same rank as ``shape``).
        settings: JSON-able settings that determine the result (compared
            when resuming).
    """

    mode: str
    names: tuple[str, ...]
    values: tuple[np.ndarray, ...]
    columns: tuple[int, ...]
    base: np.ndarray
    shape: tuple[int, ...]
    chunks: tuple[int, ...]
    settings: dict

    @property
    def dims(self) -> tuple[str, ...]:
        """Names of the pose dimensions of the dataset."""
        return self.names if self.mode == "grid" else ("sample",)

    @property
    def n_poses(self) -> int:
        return int(np.prod(self.shape))

    @property
    def chunk_grid(self) -> tuple[int, ...]:
        return tuple(-(-s // c) for s, c in zip(self.shape, self.chunks, strict=True))

    @property
    def n_chunks(self) -> int:
        return int(np.prod(self.chunk_grid))

    def region(self, index: int) -> tuple[slice, ...]:
        """Index slices of chunk ``index`` in the pose dimensions."""
        pos = np.unravel_index(index, self.chunk_grid)
        return tuple(
            slice(int(k) * c, min((int(k) + 1) * c, s))
            for k, c, s in zip(pos, self.chunks, self.shape, strict=True)
        )

    def chunk_size(self, index: int) -> int:
        return int(np.prod([s.stop - s.start for s in self.region(index)]))

    def natural(self, index: int) -> np.ndarray:
        """Natural coordinates of the poses of chunk ``index``, shape (k, nv),
        in C order of the chunk's region."""
        region = self.region(index)
        if self.mode == "grid":
            parts = [v[s] for v, s in zip(self.values, region, strict=True)]
            mesh = np.meshgrid(*parts, indexing="ij")
            n = mesh[0].size
            out = np.tile(self.base, (n, 1))
            for col, grid in zip(self.columns, mesh, strict=True):
                out[:, col] = grid.reshape(-1)
            return out
        s = region[0]
        out = np.tile(self.base, (s.stop - s.start, 1))
        for col, v in zip(self.columns, self.values, strict=True):
            out[:, col] = v[s]
        return out


def _chunk_shape(shape: tuple[int, ...], chunk_size: int) -> tuple[int, ...]:
    """Chunks of about ``chunk_size`` poses: trailing dimensions whole, one
    dimension cut, leading dimensions in steps of one."""
    chunks = [1] * len(shape)
    total = 1
    for k in range(len(shape) - 1, -1, -1):
        if total * shape[k] <= chunk_size:
            chunks[k] = shape[k]
            total *= shape[k]
        else:
            chunks[k] = max(1, chunk_size // total)
            break
    return tuple(chunks)


def _as_axis(name: str, values: Any) -> np.ndarray:
    try:
        arr = np.array(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"axis {name!r}: values must be numbers, got {values!r}") from exc
    if arr.size == 0:
        raise InputError(f"axis {name!r} has no values")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"axis {name!r} has non-finite values")
    return arr


def _base_natural(robot: CableRobot, base: Any) -> np.ndarray:
    if base is None:
        if robot.poses:
            return robot.to_natural(next(iter(robot.poses.values())))
        return robot.to_natural(robot.neutral())
    if isinstance(base, str):
        return robot.to_natural(robot.configuration(base))
    if isinstance(base, Mapping):
        return robot.to_natural(robot.configuration(dict(base)))
    return robot.to_natural(robot.as_q(base))


def make_plan(
    robot,
    axes: Mapping[str, Any] | SampledAxes,
    base: Any,
    tension_setting,
    chunk_size: int,
    version: str,
    margin: bool = True,
    tol: float | None = None,
    reach=None,
) -> MapPlan:
    """Validate the axes and the base pose and lay out the chunks."""
    if not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise InputError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    coords = list(robot.coordinate_names)
    if isinstance(axes, SampledAxes):
        mode, items = "sample", list(axes.values.items())
    elif isinstance(axes, Mapping):
        mode, items = "grid", list(axes.items())
    else:
        raise InputError(
            "axes must be a mapping coordinate -> values (a grid) or cdpm.sample_axes(...), "
            f"got {type(axes).__name__}"
        )
    if not items:
        raise InputError(f"give at least one axis; coordinates: {', '.join(coords)}")
    names, values, columns = [], [], []
    for name, vals in items:
        if name not in coords:
            raise InputError(
                f"axis {name!r} is not a coordinate of the robot; coordinates: {', '.join(coords)}"
            )
        if name in names:
            raise InputError(f"axis {name!r} given twice")
        names.append(name)
        values.append(_as_axis(name, vals))
        columns.append(coords.index(name))
        if mode != "sample":
            if np.ndim(vals) > 1:
                raise InputError(
                    f"axis {name!r}: a grid axis is a 1-D list of values, got shape "
                    f"{np.shape(vals)}; for scattered poses use samples= or cdpm.sample_axes"
                )
            if np.unique(values[-1]).size != values[-1].size:
                raise InputError(
                    f"axis {name!r} repeats a value (a map could not select it); give each "
                    "value once"
                )
    if mode == "sample":
        sizes = {v.size for v in values}
        if len(sizes) != 1:
            raise InputError("sampled axes must all have the same number of values")
        shape = (values[0].size,)
    else:
        shape = tuple(v.size for v in values)
    base_nat = _base_natural(robot, base)
    chunks = _chunk_shape(shape, int(chunk_size))
    axes_info = {
        n: {"size": int(v.size), "min": float(v.min()), "max": float(v.max()), "sha256": _digest(v)}
        for n, v in zip(names, values, strict=True)
    }
    settings = {
        "cdpm_version": version,
        "spec_sha256": robot.spec.sha256,
        "coordinates": coords,
        "mode": mode,
        "axes": axes_info,
        "base": [float(x) for x in base_nat],
        "tension": tension_setting,
        "chunk_size": int(chunk_size),
        "margin": bool(margin),
        "variables": list(CRITERIA),
        "tol": float(SPAN_TOL if tol is None else tol),
    }
    if margin and reach is not None:
        settings["reach_horizon"] = float(reach.horizon)
        settings["tension_budget"] = float(reach.tension_budget)
    if mode == "sample":
        settings["seed"] = axes.seed
    return MapPlan(
        mode=mode,
        names=tuple(names),
        values=tuple(values),
        columns=tuple(columns),
        base=base_nat,
        shape=shape,
        chunks=chunks,
        settings=json.loads(json.dumps(settings)),
    )


def settings_difference(stored: dict, current: dict) -> list[str]:
    """Readable lines naming each setting that differs."""
    lines = []
    for key in sorted(set(stored) | set(current)):
        a, b = stored.get(key), current.get(key)
        if a == b:
            continue
        if key == "axes" and isinstance(a, dict) and isinstance(b, dict):
            for name in sorted(set(a) | set(b)):
                if a.get(name) != b.get(name):
                    lines.append(
                        f"axis {name!r}: stored {_axis_text(a.get(name))}, "
                        f"now {_axis_text(b.get(name))}"
                    )
        elif key == "spec_sha256":
            lines.append("the cable spec or its URDF changed (file hash differs)")
        elif key not in stored:
            lines.append(
                f"{key}: not recorded in the store (made by an earlier cdpm), now {b!r}; "
                "this store cannot be resumed, only replaced"
            )
        else:
            lines.append(f"{key}: stored {a!r}, now {b!r}")
    return lines


def _axis_text(info) -> str:
    if info is None:
        return "absent"
    return f"{info['size']} values in [{info['min']:.6g}, {info['max']:.6g}] (#{info['sha256']})"
