"""Cable spec: the YAML file that puts cables, outputs and poses on a URDF.

A spec lives beside its URDF and is read with ``yaml.safe_load`` only;
nothing in it is executed. Arithmetic in numbers (``pi/6``, ``-2*pi/3``) is
parsed by a small whitelist parser (:func:`cdpm.expressions.parse_number`,
re-exported here), not evaluated as Python.

Format (all lengths in metres, forces in newtons, angles in radians)::

    urdf: two_link_planar.urdf        # path relative to this file, or a file
                                      # of an installed data package:
                                      # {package: example-robot-data, path: robots/...urdf}
                                      # or package://example-robot-data/robots/...urdf
    gravity: [0, 0, 0]                # m/s^2, world frame (default [0, 0, -9.81])
    cables:
      - name: c1
        tension: [0, .inf]            # [min, max] in N (default [0, inf])
        route:                        # ordered attachment points, >= 2
          - {frame: base, point: [0, 0.5, 0]}
          - {frame: link1, point: [0.3, 0.1, 0], relative_to: com}
    outputs:                          # what the task controls (docs/outputs.md)
      - {name: tip_x, frame: tip, component: x}       # world position [m]
      - {name: end_z, frame: link2, component: z, point: [0, 0, 0.2]}
      - {name: tip_rz, frame: tip, component: rz}     # rotation about world z [rad]
      - {name: elbow, joint: joint2}                  # a joint coordinate [rad or m]
      - {name: c1_length, cable: c1}                  # a cable's length [m]
      - name: mid_x                                   # a weighted sum of components
        sum:
          - {weight: 0.5, frame: link1, component: x}
          - {weight: 0.5, frame: tip, component: x}
    poses:
      nominal: [pi/6, pi/3]           # configuration vector (nq values) or
      other: {joint2: 0.5}            # joint name -> value(s), others neutral
    equilibrium: {method: min_norm}   # optional: default tension method of
                                      # linearise() (zero, min_norm, pretension)
                                      # and pretension [N]; default min_norm
    external_wrench: [0, 0]           # optional generalised force w_ext (nv,)

``relative_to: com`` gives the point relative to the link's centre of mass
(in the link frame's orientation), as the seed paper's Table I and CASPR do;
the default ``frame`` gives it in the frame itself.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import SpecError
from cdpm.expressions import parse_number
from cdpm.model._spec_parts import (
    MAP_NAMES,
    WORLD_FRAME_NAMES,
    Problems,
    read_vector,
    unknown_keys,
    unprintable_name,
)
from cdpm.model._spec_urdf import (
    FrameTable,
    link_coms,
    load_urdf,
    package_share_directory,
    usable_path,
)
from cdpm.model.coordinates import (
    ConfigurationError,
    configuration_from_values,
    coordinate_names,
)
from cdpm.model.outputs import (
    OUTPUT_COMPONENTS,
    POSITION_COMPONENTS,
    ROTATION_COMPONENTS,
    OutputDef,
    OutputTerm,
    parse_outputs,
)
from cdpm.model.tension_methods import EQUILIBRIUM_METHODS
from cdpm.model.yaml_loading import MAX_YAML_CHARS, YamlLimitError, load_yaml
from cdpm.numerics import (
    MAX_EXTERNAL_LOAD,
    MAX_GRAVITY,
    MAX_TENSION,
    SPEC_COINCIDENT_POINT_ATOL,
)

__all__ = [
    "AttachmentPoint",
    "CableDef",
    "OutputDef",
    "OutputTerm",
    "CableSpec",
    "load_spec",
    "find_specs",
    "folder_error",
    "parse_number",
    "OUTPUT_COMPONENTS",
    "POSITION_COMPONENTS",
    "ROTATION_COMPONENTS",
    "WORLD_FRAME_NAMES",
    "package_share_directory",
    "usable_path",
]

_TOP_KEYS = (
    "urdf",
    "gravity",
    "cables",
    "outputs",
    "poses",
    "equilibrium",
    "external_wrench",
    "description",
    "source",
)
_CABLE_KEYS = ("name", "tension", "route", "description")
_POINT_KEYS = ("frame", "point", "relative_to")
_EQUILIBRIUM_KEYS = ("method", "pretension")
_DEFAULT_GRAVITY = (0.0, 0.0, -9.81)


@dataclass(frozen=True)
class AttachmentPoint:
    """One attachment point of a cable route.

    Attributes:
        frame: name of the URDF link or frame the point is fixed to.
        point_in_frame: position in ``frame`` [m], shape (3,); a point given
            ``relative_to: com`` has already been shifted by the link's
            centre of mass.
    """

    frame: str
    point_in_frame: tuple[float, float, float]


@dataclass(frozen=True)
class CableDef:
    """One cable: name, tension bounds [N] and route (>= 2 points)."""

    name: str
    tension_min: float
    tension_max: float
    route: tuple[AttachmentPoint, ...]


@dataclass(frozen=True)
class CableSpec:
    """A validated cable spec with its Pinocchio model.

    Attributes:
        path: absolute path of the YAML file.
        urdf_path: absolute path of the URDF it names.
        model: ``pinocchio.Model`` built from the URDF, gravity set from the spec.
        gravity: gravity vector in the world frame [m/s^2], shape (3,).
        cables: cable definitions, in spec order.
        outputs: output definitions, in spec order.
        poses: named configuration vectors, each shape (nq,).
        equilibrium_method: default equilibrium tension method.
        pretension: default pretension [N] for the ``pretension`` method.
        external_wrench: generalised external force w_ext, shape (nv,).
        sha256: hash of the spec file and the URDF bytes (provenance).
    """

    path: Path
    urdf_path: Path
    model: Any
    gravity: np.ndarray
    cables: tuple[CableDef, ...]
    outputs: tuple[OutputDef, ...]
    poses: dict[str, np.ndarray] = field(default_factory=dict)
    equilibrium_method: str = "min_norm"
    pretension: float = 0.0
    external_wrench: np.ndarray | None = None
    sha256: str = ""


# ---------------------------------------------------------------------------
# loading


def _file_hash(*paths: Path) -> str:
    digest = hashlib.sha256()
    for p in paths:
        digest.update(p.read_bytes())
    return digest.hexdigest()


#: a cable spec is a YAML file with a top-level "cables:" key
_SPEC_KEY = re.compile(r"^cables\s*:", re.MULTILINE)


def find_specs(folder: str | os.PathLike) -> list[Path]:
    """The cable specs in a folder and its subfolders (one level down; hidden
    ones skipped): YAML files with a top-level ``cables:`` key, sorted, each
    starting with ``folder`` as given (``models/two_link_planar/...yaml``)."""
    root = Path(folder).expanduser()
    files = [*root.glob("*.y*ml"), *root.glob("[!.]*/*.y*ml")]
    return sorted(f for f in files if f.suffix.lower() in (".yaml", ".yml") and _is_spec(f))


def _is_spec(path: Path) -> bool:
    try:
        with path.open(encoding="utf-8", errors="replace") as handle:
            return bool(_SPEC_KEY.search(handle.read(100_000)))
    except OSError:
        return False


def folder_error(folder: str | os.PathLike, specs: list[Path] | None = None) -> SpecError:
    """The error for a folder given where a spec file is needed: it lists
    the folder's specs (:func:`find_specs`) or says it has none."""
    specs = find_specs(folder) if specs is None else specs
    where = os.fspath(folder)
    if not specs:
        return SpecError(
            f"{where} is a folder with no cable spec in it or one folder down (a YAML "
            "file with a top-level cables: key): give the spec file"
        )
    # the advice first: a long listing is cut at the end of the line
    return SpecError(
        f"{where} is a folder; give one of the specs in it: {', '.join(map(str, specs))}"
    )


def load_spec(path: str | os.PathLike) -> CableSpec:
    """Read and validate a cable spec and build its Pinocchio model.

    Every problem found is reported in one :class:`~cdpm.errors.SpecError`
    that names the file, the YAML path of each problem and what would be
    valid.

    Args:
        path: the YAML cable spec.

    Returns:
        The validated :class:`CableSpec`.

    Raises:
        SpecError: the file is missing or unreadable, is not valid YAML, or
            does not describe a valid cable robot.
    """
    # yaml: loaded on first use
    import yaml

    spec_path = usable_path(path)
    if spec_path.is_dir():
        raise folder_error(path)
    if not spec_path.is_file():
        raise SpecError(f"cable spec file not found: {spec_path}")
    try:
        size = spec_path.stat().st_size
        if size > MAX_YAML_CHARS * 4:  # UTF-8 has at most 4 bytes per character
            raise YamlLimitError(f"the file has {size:,} bytes; a cable spec is a few kilobytes")
        data, read_problems = load_yaml(spec_path.read_text(encoding="utf-8"))
    except YamlLimitError as exc:
        raise SpecError(f"refused: {exc}", path=str(spec_path)) from None
    except yaml.YAMLError as exc:
        raise SpecError(f"not valid YAML: {exc}", path=str(spec_path)) from exc
    except OSError as exc:
        raise SpecError(
            f"cannot read the file: {exc.strerror or exc}", path=str(spec_path)
        ) from None
    except UnicodeDecodeError as exc:
        raise SpecError(f"not a UTF-8 text file: {exc}", path=str(spec_path)) from exc
    if read_problems:
        raise SpecError(read_problems, path=str(spec_path))
    if not isinstance(data, dict):
        raise SpecError(
            "a cable spec is a YAML mapping with keys urdf, gravity, cables, outputs, poses",
            path=str(spec_path),
        )

    problems = Problems()
    unknown_keys(problems, "", data, _TOP_KEYS)

    model, urdf_path = load_urdf(problems, spec_path, data.get("urdf"))
    if model is not None:
        _check_coordinate_names(problems, model, urdf_path)

    gravity = np.array(_DEFAULT_GRAVITY)
    if "gravity" in data:
        g = read_vector(problems, "gravity", data["gravity"], 3)
        if g is not None:
            if not all(abs(x) <= MAX_GRAVITY for x in g):
                problems.add("gravity", f"values must be finite, at most {MAX_GRAVITY:g} m/s^2")
            gravity = np.array(g)

    frames = FrameTable(model, link_coms(urdf_path)) if model is not None else None
    cables = _parse_cables(problems, data.get("cables"), frames)
    outputs = parse_outputs(problems, data.get("outputs"), frames, model, cables)
    poses = _parse_poses(problems, data.get("poses"), model)
    method, pretension = _parse_equilibrium(problems, data.get("equilibrium"))

    external = None
    if data.get("external_wrench") is not None and model is not None:
        w = read_vector(problems, "external_wrench", data["external_wrench"], model.nv)
        if w is not None and not all(abs(x) <= MAX_EXTERNAL_LOAD for x in w):
            problems.add(
                "external_wrench",
                f"values must be finite, at most {MAX_EXTERNAL_LOAD:g} (N or N m)",
            )
        elif w is not None:
            external = np.array(w)

    if problems.items:
        raise SpecError(problems.items, path=str(spec_path))

    model.gravity.linear = gravity
    return CableSpec(
        path=spec_path,
        urdf_path=urdf_path,
        model=model,
        gravity=gravity,
        cables=tuple(cables),
        outputs=tuple(outputs),
        poses=poses,
        equilibrium_method=method,
        pretension=pretension,
        external_wrench=external,
        sha256=_file_hash(spec_path, urdf_path),
    )


_CASE = "; the file systems of macOS and Windows ignore case"


def _check_coordinate_names(problems: Problems, model, urdf_path: Path) -> None:
    """Record each natural coordinate whose name a workspace map could not
    use. A map has one dimension per coordinate, named after it, beside its
    own variables and dimensions (MAP_NAMES), and a map store keeps each in
    a folder of that name; so the names must differ from those and from each
    other (a joint ``j.x`` and the x of a planar joint ``j``), also when
    case is ignored (as the file systems of macOS and Windows do), and be
    names of folders (no ``/``, not hidden, not ``zarr.json``)."""
    names = coordinate_names(model)
    map_names = {name.casefold(): name for name in MAP_NAMES}
    joint_of: dict[str, tuple[str, str]] = {}  # casefolded -> (coordinate, joint)
    for j in range(1, model.njoints):
        start = model.joints[j].idx_v
        for name in names[start : start + model.joints[j].nv]:
            coordinate = f"coordinate {name!r}"
            if name != model.names[j]:
                coordinate += f" of joint {model.names[j]!r}"
            key = name.casefold()
            if key in map_names:
                taken = map_names[key]
                alike = "" if taken == name else f" but for case ({taken!r}{_CASE})"
                problems.add(
                    "urdf",
                    f"{coordinate} has the name of {MAP_NAMES[taken]}{alike}, and a map names "
                    f"a dimension after each coordinate; rename the joint in {urdf_path.name}",
                )
            elif key in joint_of:
                other, joint = joint_of[key]
                alike = "" if other == name else f" but for case ({other!r}{_CASE})"
                problems.add(
                    "urdf",
                    f"{coordinate} has the name of a coordinate of joint {joint!r}{alike}; "
                    f"rename one of the joints in {urdf_path.name}",
                )
            elif "/" in name or name.startswith(".") or name == "zarr.json":
                problems.add(
                    "urdf",
                    f"{coordinate} cannot name a folder of a map store (no '/', no leading "
                    f"'.', not zarr.json); rename the joint in {urdf_path.name}",
                )
            joint_of.setdefault(key, (name, model.names[j]))


def tension_bound_problems(fmin: float, fmax: float, number=str) -> list[str]:
    """What is wrong with a cable's tension bounds [N] (none: an empty list):
    the minimum must be finite and >= 0, the maximum >= the minimum and > 0,
    and neither above MAX_TENSION (a maximum of inf: no upper bound).

    Args:
        fmin, fmax: the bounds [N].
        number: how a value is written in the messages (e.g. ``"{:g} N".format``).
    """
    problems = []
    if not (math.isfinite(fmin) and fmin >= 0):
        problems.append(f"minimum {number(fmin)} must be finite and >= 0 (cables only pull)")
    elif fmin > MAX_TENSION:
        problems.append(f"minimum {number(fmin)} is above {MAX_TENSION:g} N")
    if math.isfinite(fmax) and fmax > MAX_TENSION:
        problems.append(
            f"maximum {number(fmax)} is above {MAX_TENSION:g} N; give inf for no upper bound"
        )
    if not fmax >= fmin:
        problems.append(f"maximum {number(fmax)} must be >= minimum {number(fmin)}")
    if fmax == 0:
        problems.append(f"maximum {number(0)} leaves the cable no tension")
    return problems


def _parse_cables(problems: Problems, raw: Any, frames: FrameTable | None) -> list[CableDef]:
    if raw is None:
        problems.add("cables", "missing; a cable robot needs at least one cable")
        return []
    if not isinstance(raw, list) or not raw:
        problems.add("cables", "expected a non-empty list of cables")
        return []
    cables: list[CableDef] = []
    seen: set[str] = set()
    for i, item in enumerate(raw):
        where = f"cables[{i}]"
        if not isinstance(item, dict):
            problems.add(where, f"expected a mapping with name, tension, route; got {item!r}")
            continue
        unknown_keys(problems, where, item, _CABLE_KEYS)
        name = item.get("name", f"cable{i + 1}")
        if not isinstance(name, str) or not name:
            problems.add(f"{where}.name", f"expected a non-empty string, got {name!r}")
            name = f"cable{i + 1}"
        elif (unprintable := unprintable_name(name)) is not None:
            problems.add(f"{where}.name", f"the cable name {unprintable}: rename the cable")
            name = f"cable{i + 1}"  # never printed again, even in later messages
        if name in seen:
            problems.add(f"{where}.name", f"duplicate cable name {name!r}; names must be unique")
        seen.add(name)
        where = f"cables[{i}] ({name})"
        fmin, fmax = 0.0, math.inf
        if "tension" in item:
            bounds = read_vector(problems, f"{where}.tension", item["tension"], 2, infinite=True)
            if bounds is not None:
                fmin, fmax = (b + 0.0 for b in bounds)  # -0 N is 0 N
                for problem in tension_bound_problems(fmin, fmax):
                    problems.add(f"{where}.tension", problem)
        route = _parse_route(problems, where, item.get("route"), frames)
        cables.append(CableDef(name=name, tension_min=fmin, tension_max=fmax, route=route))
    return cables


def _parse_route(
    problems: Problems, where: str, raw: Any, frames: FrameTable | None
) -> tuple[AttachmentPoint, ...]:
    where = f"{where}.route"
    if not isinstance(raw, list):
        problems.add(where, "missing or not a list; give >= 2 attachment points {frame, point}")
        return ()
    if len(raw) < 2:
        problems.add(
            where,
            f"has {len(raw)} point(s); a cable needs at least 2 attachment points "
            "(e.g. one on the base and one on a link)",
        )
    points: list[AttachmentPoint] = []
    for k, item in enumerate(raw):
        pw = f"{where}[{k}]"
        if not isinstance(item, dict):
            problems.add(pw, f"expected {{frame: NAME, point: [x, y, z]}}, got {item!r}")
            continue
        unknown_keys(problems, pw, item, _POINT_KEYS)
        frame = item.get("frame")
        ok = True
        if not isinstance(frame, str):
            problems.add(f"{pw}.frame", f"expected a frame name, got {frame!r}")
            ok = False
        elif frames is not None and not frames.exists(frame):
            problems.add(f"{pw}.frame", f"frame {frame!r} not in URDF; frames: {frames.listing()}")
            ok = False
        xyz = read_vector(problems, f"{pw}.point", item.get("point"), 3)
        if xyz is not None and not all(math.isfinite(x) for x in xyz):
            problems.add(f"{pw}.point", "coordinates must be finite")
            xyz = None
        relative = item.get("relative_to", "frame")
        if relative not in ("frame", "com"):
            problems.add(f"{pw}.relative_to", f"{relative!r} is not valid; use 'frame' or 'com'")
            ok = False
        if not ok or xyz is None:
            continue
        point = np.array(xyz)
        if relative == "com" and frames is not None:
            com = frames.com_in_frame(frame)
            if com is None:
                problems.add(
                    f"{pw}.relative_to",
                    f"'com' needs a URDF link with an inertia; {frame!r} is not one",
                )
                continue
            point = point + com
        points.append(AttachmentPoint(frame=frame, point_in_frame=tuple(float(x) for x in point)))
    for k in range(len(points) - 1):
        a, b = points[k], points[k + 1]
        same_frame = a.frame == b.frame or (
            a.frame in WORLD_FRAME_NAMES and b.frame in WORLD_FRAME_NAMES
        )
        if same_frame and np.allclose(
            a.point_in_frame, b.point_in_frame, atol=SPEC_COINCIDENT_POINT_ATOL
        ):
            problems.add(
                where,
                f"points {k} and {k + 1} coincide (both at {list(a.point_in_frame)} on "
                f"{a.frame!r}); a cable segment needs two distinct attachment points",
            )
    return tuple(points)


def _parse_poses(problems: Problems, raw: Any, model) -> dict[str, np.ndarray]:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        problems.add("poses", "expected a mapping from pose name to configuration")
        return {}

    poses: dict[str, np.ndarray] = {}
    keys: dict[str, Any] = {}  # pose name -> the YAML key it was written as
    for key, value in raw.items():
        name = str(key)  # a YAML key may be a number: 1: [...] is the pose "1"
        if not name:
            problems.add("poses", "a pose has an empty name; give it a name")
            continue
        if (unprintable := unprintable_name(name)) is not None:
            problems.add("poses", f"the pose name {unprintable}: rename the pose")
            continue
        if name in keys:
            problems.add(
                f"poses.{name}",
                f"the pose name {name!r} is given twice (as {keys[name]!r} and {key!r}); "
                "rename one of them",
            )
            continue
        keys[name] = key
        if model is None:
            continue
        try:
            poses[name] = configuration_from_values(model, value)
        except ConfigurationError as exc:
            problems.add(f"poses.{name}", str(exc))
    return poses


def _parse_equilibrium(problems: Problems, raw: Any) -> tuple[str, float]:
    if raw is None:
        return "min_norm", 0.0
    if not isinstance(raw, dict):
        problems.add("equilibrium", "expected {method: NAME, pretension: N}")
        return "min_norm", 0.0
    unknown_keys(problems, "equilibrium", raw, _EQUILIBRIUM_KEYS)
    method = raw.get("method", "min_norm")
    if not isinstance(method, str) or method not in EQUILIBRIUM_METHODS:
        problems.add(
            "equilibrium.method",
            f"{method!r} is not valid; use one of {', '.join(EQUILIBRIUM_METHODS)}",
        )
        method = "min_norm"
    pretension = 0.0
    if "pretension" in raw:
        try:
            pretension = parse_number(raw["pretension"])
        except ValueError as exc:
            problems.add("equilibrium.pretension", f"{exc}; expected tension in N")
            pretension = math.nan  # reported: not also as a missing one below
        else:
            if not (math.isfinite(pretension) and 0 <= pretension <= MAX_TENSION):
                problems.add(
                    "equilibrium.pretension", f"must be finite, >= 0 and <= {MAX_TENSION:g} N"
                )
    if method == "pretension" and pretension == 0:
        problems.add(
            "equilibrium",
            "method 'pretension' needs pretension: N > 0 (every cable at least N newtons); "
            "with 0 it is the min_norm method, so give the pretension or use method: min_norm",
        )
    return method, pretension
