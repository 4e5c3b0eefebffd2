"""What a map covers: axes, the base pose, the chunk layout and settings.

A :class:`MapPlan` is plain data (picklable, JSON-able settings) built once
by the driver. It turns a chunk index into the region of the dataset the
chunk fills and the natural coordinates of its poses, so the driver, local
workers and Dask workers all agree on what chunk k is.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cdpm.dynamics.equilibrium import checked_pretension
from cdpm.errors import (
    InputError,
    checked_seed,
    float_array,
    float_scalar,
    is_integer,
    short_repr,
)
from cdpm.model.coordinates import MAX_COORDINATE
from cdpm.model.robot import CableRobot
from cdpm.model.spec import tension_bound_problems
from cdpm.numerics import MAX_EXTERNAL_LOAD, MAX_GRAVITY, SPAN_TOL
from cdpm.pipeline.criteria import CRITERIA

__all__ = [
    "SampledAxes",
    "MapPlan",
    "sample_axes",
    "make_plan",
    "override_robot",
    "robot_overrides",
    "describe_overrides",
]

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


#: largest map kept in memory (without ``store=``) [bytes]
IN_MEMORY_MAX = 2 * 1024**3

#: most poses one map may have (a grid's product or samples): about a day
#: of work for a 32-core machine at the cheapest models' speed
MAX_MAP_POSES = 10**10


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
    if not is_integer(n) or n < 1:
        raise InputError(f"samples must be a positive integer, got {n!r}")
    need = int(n) * max(len(ranges) if isinstance(ranges, Mapping) else 1, 1) * 8
    if int(n) > MAX_MAP_POSES or need > IN_MEMORY_MAX:
        # before drawing them
        raise InputError(
            f"{int(n):,} samples need {need / 1024**3:,.1f} GiB for their coordinates alone "
            f"(at most {IN_MEMORY_MAX / 1024**3:g} GiB and {MAX_MAP_POSES:.0e} poses); sample "
            "fewer poses, or map several sample sets with different seeds"
        )
    if seed is not None:
        seed = checked_seed(seed)
    if not ranges:
        raise InputError("give at least one coordinate range to sample, e.g. {'q1': (-3.14, 3.14)}")
    rng = np.random.default_rng(seed)
    values, clean = {}, {}
    for name, bounds in ranges.items():
        try:
            lo, hi = (float_scalar(b) for b in bounds)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"sample range of {name!r} must be (low, high), got {bounds!r}"
            ) from exc
        if not (abs(lo) <= MAX_COORDINATE and abs(hi) <= MAX_COORDINATE and lo <= hi):
            raise InputError(
                f"sample range of {name!r} must be finite, within +-{MAX_COORDINATE:g} (rad or "
                f"m), with low <= high, got {bounds!r}"
            )
        clean[name] = (lo, hi)
        values[name] = rng.uniform(lo, hi, int(n))
    return SampledAxes(values=values, ranges=clean, seed=seed)


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
        arr = float_array(values, copy=True).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"axis {name!r}: values must be numbers or arithmetic such as 'pi/4', got "
            f"{short_repr(values)}: {exc}"
        ) from exc
    if arr.size == 0:
        raise InputError(f"axis {name!r} has no values")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"axis {name!r} has non-finite values")
    if not np.all(np.abs(arr) <= MAX_COORDINATE):
        raise InputError(
            f"axis {name!r} has values of magnitude above {MAX_COORDINATE:g} (rad or m); "
            "give coordinates within it"
        )
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
    overrides: Mapping[str, Any] | None = None,
    tension_search: Mapping[str, Any] | None = None,
) -> MapPlan:
    """Validate the axes and the base pose and lay out the chunks.

    ``overrides`` (:func:`robot_overrides`) are the robot's departures from
    its spec file; they enter the settings (compared when resuming) only
    when there are any, so maps of the spec as it is keep their settings.
    ``tension_search`` (the search's settings as plain data, with ``tension="best"``)
    enters them likewise only when the map asks for the search.
    """
    if not is_integer(chunk_size) or chunk_size < 1:
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
    if overrides:
        settings["overrides"] = dict(overrides)
    if tension_search:
        settings["tension_search"] = dict(tension_search)
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


def settings_difference(stored: dict, current: dict, *, cells: bool = False) -> list[str]:
    """Readable lines naming each setting that differs.

    Args:
        stored, current: the settings.
        cells: the axes hold cell edges (a certified map's), not poses: they
            are counted in cells, and a different grid leaves out the chunk
            size (its default follows the grid)."""
    lines = []
    grid_changed = stored.get("axes") != current.get("axes")
    for key in sorted(set(stored) | set(current)):
        a, b = stored.get(key), current.get(key)
        if a == b or (cells and grid_changed and key == "chunk_size"):
            continue
        if key == "axes" and isinstance(a, dict) and isinstance(b, dict):
            for name in sorted(set(a) | set(b)):
                if a.get(name) != b.get(name):
                    was, now = _axis_text(a.get(name), cells), _axis_text(b.get(name), cells)
                    if was == now:  # the same count and span: other values between
                        was, now = _axis_text(a.get(name)), _axis_text(b.get(name))
                    lines.append(f"axis {name!r}: stored {was}, now {now}")
        elif key == "spec_sha256":
            lines.append("the cable spec or its URDF changed (file hash differs)")
        elif key == "overrides":
            lines += _overrides_difference(a or {}, b or {})
        elif key == "tension_search":
            lines.append(
                f"tension search (tension 'best'): stored {_search_text(a)}, now {_search_text(b)}"
            )
        elif key not in stored:
            lines.append(
                f"{key}: not recorded in the store (made by an earlier cdpm), now {b!r}; "
                "this store cannot be resumed, only replaced"
            )
        else:
            lines.append(f"{key}: stored {a!r}, now {b!r}")
    return lines


def _search_text(info) -> str:
    if not info:
        return "none"
    return ", ".join(f"{k} {v}" for k, v in info.items())


def _axis_text(info, cells: bool = False) -> str:
    if info is None:
        return "absent"
    span = f"[{info['min']:.6g}, {info['max']:.6g}]"
    if cells:
        return f"{info['size'] - 1} cells over {span}"
    return f"{info['size']} values in {span} (#{info['sha256']})"


# --------------------------------------------------------------------------
# the robot as a map sees it: the spec file with overrides


#: what an override changes, in the order they are described
_OVERRIDE_KEYS = ("gravity", "tension_bounds", "pretension", "external_wrench")


def _finite_vector(what: str, value: Any, size: int, largest: float) -> np.ndarray:
    try:
        arr = float_array(value, copy=True).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what} must be {size} numbers, got {value!r}") from exc
    if arr.shape != (size,) or not np.all(np.abs(arr) <= largest):
        raise InputError(f"{what} must be {size} numbers of at most {largest:g}, got {value!r}")
    return arr


def _bound_pair(cable: str, value: Any) -> tuple[float, float]:
    """(min, max) [N] of one cable, checked as the spec loader checks
    ``tension: [min, max]``."""
    try:
        low, high = float_array(value).reshape(-1) + 0.0  # -0 N is 0 N
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"tension bounds of cable {cable!r} must be (min, max) in N, got {short_repr(value)}"
        ) from exc

    problems = tension_bound_problems(low, high, "{:g} N".format)
    if problems:
        raise InputError(f"tension bounds of cable {cable!r}: {problems[0]}")
    return float(low), float(high)


def _bounds_by_cable(robot: CableRobot, tension_bounds: Any) -> dict[str, tuple[float, float]]:
    """{cable: (min, max)} from one pair for every cable or a mapping
    cable name -> pair."""
    names = list(robot.cable_names)
    if isinstance(tension_bounds, Mapping):
        unknown = [k for k in tension_bounds if k not in names]
        if unknown:
            raise InputError(
                f"no cable named {unknown[0]!r} in {robot.spec.path.name}; cables: "
                f"{', '.join(names)}"
            )
        return {k: _bound_pair(k, v) for k, v in tension_bounds.items()}
    return {name: _bound_pair(name, tension_bounds) for name in names}


def override_robot(
    robot: CableRobot,
    *,
    gravity: Any = None,
    tension_bounds: Any = None,
    pretension: float | None = None,
    external_wrench: Any = None,
) -> CableRobot:
    """The robot with other gravity, tension bounds, pretension or load.

    Builds a new :class:`~cdpm.model.robot.CableRobot` from a copy of the spec
    (``dataclasses.replace``; the Pinocchio model is copied when gravity
    changes): no file is written, and ``robot`` is left as it is. Maps
    record such departures from the spec file in their settings
    (:func:`robot_overrides`), and their worker processes rebuild the same
    robot.

    Args:
        robot: the robot.
        gravity: gravity in the world frame [m/s^2], shape (3,); None keeps it.
        tension_bounds: (min, max) [N] for every cable, or a mapping cable
            name -> (min, max); max may be ``inf``; None keeps the bounds.
        pretension: least tension [N] of the ``pretension`` equilibrium
            method (the spec's ``equilibrium.pretension``); None keeps it.
        external_wrench: generalised external force w_ext, shape (nv,)
            [N or N m]; None keeps it.

    Returns:
        A new robot, or ``robot`` itself when nothing is overridden.

    Raises:
        InputError: a value of the wrong shape, a bound a cable cannot have
            (negative, max < min, max 0) or an unknown cable name.
    """

    spec = robot.spec
    changes: dict[str, Any] = {}
    if gravity is not None:
        g = _finite_vector("gravity [m/s^2]", gravity, 3, MAX_GRAVITY)
        model = spec.model.copy()
        model.gravity.linear = g
        changes.update(gravity=g, model=model)
    if tension_bounds is not None:
        bounds = _bounds_by_cable(robot, tension_bounds)
        changes["cables"] = tuple(
            dataclasses.replace(c, tension_min=bounds[c.name][0], tension_max=bounds[c.name][1])
            if c.name in bounds
            else c
            for c in spec.cables
        )
    if pretension is not None:
        changes["pretension"] = checked_pretension(pretension)
    if external_wrench is not None:
        changes["external_wrench"] = _finite_vector(
            f"external wrench (nv={robot.nv} values)", external_wrench, robot.nv, MAX_EXTERNAL_LOAD
        )
    if not changes:
        return robot
    return CableRobot(dataclasses.replace(spec, **changes))


def robot_overrides(robot: CableRobot, reference: CableRobot) -> dict[str, Any]:
    """What ``robot`` changes of ``reference`` (the robot of its spec file),
    as JSON-able data that :func:`override_robot` takes back.

    Returns:
        ``{"gravity": [3 floats], "tension_bounds": {cable: [min, max]},
        "pretension": float, "external_wrench": [nv floats]}`` with only
        the items that differ (the cables whose bounds differ); ``{}`` when
        ``robot`` is its spec file's.
    """
    out: dict[str, Any] = {}
    if not np.array_equal(robot.gravity, reference.gravity):
        out["gravity"] = [float(x) for x in robot.gravity]
    bounds = {
        name: [float(lo), float(hi)]
        for name, lo, hi, lo0, hi0 in zip(
            robot.cable_names,
            robot.tension_min,
            robot.tension_max,
            reference.tension_min,
            reference.tension_max,
            strict=True,
        )
        if (lo, hi) != (lo0, hi0)
    }
    if bounds:
        out["tension_bounds"] = bounds
    if float(robot.spec.pretension or 0.0) != float(reference.spec.pretension or 0.0):
        out["pretension"] = float(robot.spec.pretension or 0.0)
    if not np.array_equal(robot.external_wrench, reference.external_wrench):
        out["external_wrench"] = [float(x) for x in robot.external_wrench]
    return out


def _numbers(values) -> str:
    return "[" + ", ".join(f"{float(v):g}" for v in values) + "]"


def _override_text(key: str, value: Any, reference: CableRobot | None = None) -> str:
    """The value of one override in words, with the spec's value when
    ``reference`` (the robot of the spec file) is given."""
    if key == "gravity":
        was = f" (spec {_numbers(reference.gravity)})" if reference is not None else ""
        return f"{_numbers(value)} m/s^2{was}"
    if key == "tension_bounds":
        items = []
        for name, pair in value.items():
            was = ""
            if reference is not None and name in reference.cable_names:
                i = reference.cable_names.index(name)
                was = f" (spec {_numbers((reference.tension_min[i], reference.tension_max[i]))})"
            items.append(f"{name} {_numbers(pair)}{was}")
        return "[N] " + ", ".join(items)
    if key == "pretension":
        was = f" (spec {reference.spec.pretension:g} N)" if reference is not None else ""
        return f"{float(value):g} N{was}"
    return _numbers(value)


def describe_overrides(overrides: Mapping[str, Any], reference: CableRobot | None = None) -> str:
    """One line naming each override (``gravity [0, 0, 0] m/s^2; tension
    bounds [N] c1 [0, 50]; ...``), with the spec's value when ``reference``
    (the robot of the spec file) is given."""
    return "; ".join(
        f"{key.replace('_', ' ')} {_override_text(key, overrides[key], reference)}"
        for key in _OVERRIDE_KEYS
        if key in overrides
    )


def _overrides_difference(stored: Mapping[str, Any], current: Mapping[str, Any]) -> list[str]:
    """One line per override that differs between a store and a request."""
    lines = []
    for key in _OVERRIDE_KEYS:
        a, b = stored.get(key), current.get(key)
        if a != b:
            a_text = "the spec's" if a is None else _override_text(key, a)
            b_text = "the spec's" if b is None else _override_text(key, b)
            lines.append(f"{key.replace('_', ' ')}: stored {a_text}, now {b_text}")
    return lines
