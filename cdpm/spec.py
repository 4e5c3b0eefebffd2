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

from cdpm.equilibrium import EQUILIBRIUM_METHODS
from cdpm.errors import SpecError, short_repr
from cdpm.expressions import parse_number
from cdpm.numerics import SPEC_COINCIDENT_POINT_ATOL
from cdpm.yaml_loading import MAX_YAML_CHARS, YamlLimitError, load_yaml

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
]

#: Position components of a point: its world coordinates [m].
POSITION_COMPONENTS = {"x": 0, "y": 1, "z": 2}

#: Orientation components of a frame: the world components of its rotation
#: vector, log3 of its world rotation [rad]; their rates are the frame's
#: angular velocity about the world axes (docs/outputs.md).
ROTATION_COMPONENTS = {"rx": 0, "ry": 1, "rz": 2}

#: Every ``component`` a frame output may ask for, -> its axis (0, 1, 2).
OUTPUT_COMPONENTS = {**POSITION_COMPONENTS, **ROTATION_COMPONENTS}

#: Kinds of output term: ``position`` and ``rotation`` of a frame, a
#: ``joint`` coordinate, a ``cable`` length.
OUTPUT_TERM_KINDS = ("position", "rotation", "joint", "cable")

#: Names that refer to the fixed world frame in a route.
WORLD_FRAME_NAMES = ("world", "universe")

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
_TERM_KEYS = ("frame", "component", "point", "joint", "cable", "weight")
_OUTPUT_KEYS = ("name", "unit", "sum", *_TERM_KEYS)
_OUTPUT_EXAMPLE = (
    "{name: tip_x, frame: tip, component: x}, {name: elbow, joint: joint2}, "
    "{name: c1_length, cable: c1} or {name: s, sum: [{weight: 0.5, frame: tip, "
    "component: x}, ...]}"
)
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
class OutputTerm:
    """One weighted component of an output.

    Attributes:
        kind: ``"position"`` (a world coordinate of a point fixed in
            ``frame`` [m]), ``"rotation"`` (a world component of ``frame``'s
            rotation vector [rad]), ``"joint"`` (the coordinate of a
            one-degree-of-freedom joint [rad or m]) or ``"cable"`` (a
            cable's length [m]).
        weight: the term's factor in its output's sum (1 for a plain output).
        frame: the frame (position, rotation), else "".
        component: ``x``, ``y``, ``z`` (position) or ``rx``, ``ry``, ``rz``
            (rotation), else "".
        point_in_frame: the point of a position term in ``frame`` [m],
            shape (3,) (the frame origin by default).
        joint: the joint name of a joint term, else "".
        cable: the cable name of a cable term, else "".
        unit: the component's unit: ``"m"`` or ``"rad"``.
    """

    kind: str
    weight: float = 1.0
    frame: str = ""
    component: str = ""
    point_in_frame: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint: str = ""
    cable: str = ""
    unit: str = "m"

    @property
    def axis(self) -> int:
        """World axis (0, 1, 2) of a position or rotation term."""
        return OUTPUT_COMPONENTS[self.component]

    def describe(self) -> str:
        """``tip.x``, ``tip.rz``, ``joint joint2``, ``cable c1``."""
        if self.kind in ("position", "rotation"):
            at = "" if not any(self.point_in_frame) else f"@{list(self.point_in_frame)}"
            return f"{self.frame}{at}.{self.component}"
        return f"{self.kind} {self.joint or self.cable}"


@dataclass(frozen=True)
class OutputDef:
    """One scalar output: a weighted sum of terms (:class:`OutputTerm`), most
    often a single term of weight 1.

    Attributes:
        name: the output's name.
        terms: its terms, at least one.
        unit: its unit: the terms' common unit (``"m"`` or ``"rad"``), the
            spec's ``unit:`` when given, else ``"mixed"``.
    """

    name: str
    terms: tuple[OutputTerm, ...]
    unit: str = "m"

    @property
    def frame(self) -> str:
        """The frame of the first position or rotation term ("" if none)."""
        term = self.marker_term
        return term.frame if term is not None else ""

    @property
    def component(self) -> str:
        """The component of a single frame term ("" otherwise)."""
        if len(self.terms) == 1 and self.terms[0].kind in ("position", "rotation"):
            return self.terms[0].component
        return ""

    @property
    def point_in_frame(self) -> tuple[float, float, float]:
        """The point of the first position or rotation term in its frame [m]."""
        term = self.marker_term
        return term.point_in_frame if term is not None else (0.0, 0.0, 0.0)

    @property
    def marker_term(self) -> OutputTerm | None:
        """The first position or rotation term: where the output is drawn."""
        return next((t for t in self.terms if t.kind in ("position", "rotation")), None)

    @property
    def has_rotation(self) -> bool:
        """Some term is an orientation component."""
        return any(t.kind == "rotation" for t in self.terms)

    def describe(self) -> str:
        """The output as a formula, e.g. ``0.5 link1.x + 0.5 tip.x``."""
        if len(self.terms) == 1 and self.terms[0].weight == 1.0:
            return self.terms[0].describe()
        parts = [f"{t.weight:g} {t.describe()}" for t in self.terms]
        return " + ".join(parts).replace("+ -", "- ")


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


class _Problems:
    """Collects problems with their YAML path so all are reported at once."""

    def __init__(self) -> None:
        self.items: list[str] = []

    def add(self, where: str, what: str) -> None:
        self.items.append(f"{where}: {what}" if where else what)


def _vector(
    problems: _Problems, where: str, value: Any, size: int | None, infinite: bool = False
) -> list[float] | None:
    """``value`` as a list of ``size`` floats, or None after recording a
    problem. NaN is never a value; +-inf only with ``infinite``."""
    if not isinstance(value, (list, tuple)):
        problems.add(where, f"expected a list of {size or 'some'} numbers, got {short_repr(value)}")
        return None
    if size is not None and len(value) != size:
        problems.add(where, f"expected {size} numbers, got {len(value)}: {short_repr(value)}")
        return None
    out = []
    for k, item in enumerate(value):
        try:
            number = parse_number(item)
        except ValueError as exc:
            problems.add(f"{where}[{k}]", f"{exc}; expected a number")
            return None
        if math.isnan(number) or (math.isinf(number) and not infinite):
            problems.add(f"{where}[{k}]", f"{short_repr(item)} is not a finite number")
            return None
        out.append(number)
    return out


def _unknown_keys(problems: _Problems, where: str, mapping: dict, allowed: tuple) -> None:
    for key in mapping:
        if key not in allowed:
            problems.add(where, f"unknown key {key!r}; valid keys: {', '.join(allowed)}")


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
    return SpecError(
        f"{where} is a folder; specs in it: {', '.join(map(str, specs))}; give one of them"
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
        data, duplicates = load_yaml(spec_path.read_text(encoding="utf-8"))
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
    if duplicates:
        raise SpecError(duplicates, path=str(spec_path))
    if not isinstance(data, dict):
        raise SpecError(
            "a cable spec is a YAML mapping with keys urdf, gravity, cables, outputs, poses",
            path=str(spec_path),
        )

    problems = _Problems()
    _unknown_keys(problems, "", data, _TOP_KEYS)

    model, urdf_path = _load_urdf(problems, spec_path, data.get("urdf"))

    gravity = np.array(_DEFAULT_GRAVITY)
    if "gravity" in data:
        g = _vector(problems, "gravity", data["gravity"], 3)
        if g is not None:
            if not all(math.isfinite(x) for x in g):
                problems.add("gravity", "values must be finite")
            gravity = np.array(g)

    frames = _FrameTable(model, _link_coms(urdf_path)) if model is not None else None
    cables = _parse_cables(problems, data.get("cables"), frames)
    outputs = _parse_outputs(problems, data.get("outputs"), frames, model, cables)
    poses = _parse_poses(problems, data.get("poses"), model)
    method, pretension = _parse_equilibrium(problems, data.get("equilibrium"))

    external = None
    if data.get("external_wrench") is not None and model is not None:
        w = _vector(problems, "external_wrench", data["external_wrench"], model.nv)
        if w is not None:
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


#: pip distribution that installs a ROS-style package's files, where the
#: names differ (used in the install hint when a package is missing).
_PACKAGE_PIP_NAMES = {"example-robot-data": "example-robot-data (or: pip install 'cdpm[robots]')"}


def usable_path(path: str | os.PathLike) -> Path:
    """``path`` expanded and resolved, checked to be one the system can
    look up (no NUL character, not too long).

    Raises:
        SpecError: the path cannot name a file, with the reason.
    """
    text = os.fspath(path)
    if "\0" in str(text):
        raise SpecError(f"the path {short_repr(text)} contains a NUL character; no file has it")
    try:
        resolved = Path(text).expanduser().resolve()
        resolved.is_dir()  # a name too long for the system fails here
    except (OSError, ValueError, RuntimeError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise SpecError(f"cannot use the path {short_repr(text)}: {reason}") from None
    return resolved


def package_share_directory(package: str) -> Path | None:
    """Directory of an installed ROS-style data package, or None.

    Looks in the Python distribution of that name (cmeel layout, e.g.
    ``example-robot-data`` installs ``<site-packages>/cmeel.prefix/share/
    example-robot-data``), then in ``$ROS_PACKAGE_PATH`` and
    ``$AMENT_PREFIX_PATH``.
    """
    from importlib import metadata

    try:
        dist = metadata.distribution(package)
    except metadata.PackageNotFoundError:
        dist = None
    if dist is not None:
        candidate = Path(str(dist.locate_file(f"cmeel.prefix/share/{package}")))
        if candidate.is_dir():
            return candidate
    for var in ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH"):
        for root in filter(None, os.environ.get(var, "").split(os.pathsep)):
            for candidate in (Path(root) / package, Path(root) / "share" / package):
                if candidate.is_dir():
                    return candidate
    return None


def _package_urdf(problems: _Problems, urdf: Any) -> Path | None:
    """Resolve ``{package: NAME, path: REL}`` or ``package://NAME/REL``."""
    if isinstance(urdf, str):
        package, _, rel = urdf[len("package://") :].partition("/")
    else:
        _unknown_keys(problems, "urdf", urdf, ("package", "path"))
        package, rel = urdf.get("package"), urdf.get("path")
        if not isinstance(package, str) or not isinstance(rel, str):
            problems.add(
                "urdf",
                "a packaged URDF needs {package: NAME, path: PATH/IN/PACKAGE.urdf}, got "
                f"{urdf!r}",
            )
            return None
    if not package or not rel:
        problems.add("urdf", f"{urdf!r}: expected package://PACKAGE/PATH/TO/FILE.urdf")
        return None
    root = package_share_directory(package)
    if root is None:
        pip_name = _PACKAGE_PIP_NAMES.get(package, package)
        problems.add(
            "urdf",
            f"package {package!r} is not installed (it provides the URDF {rel!r}); "
            f"install it with: pip install {pip_name}",
        )
        return None
    urdf_path = (root / rel).resolve()
    if not urdf_path.is_file():
        problems.add("urdf", f"{rel!r} not found in package {package!r} (looked for {urdf_path})")
        return None
    return urdf_path


def _load_urdf(problems: _Problems, spec_path: Path, urdf: Any):
    if urdf is None:
        problems.add("urdf", "missing; give the URDF file's path relative to the spec")
        return None, None
    if isinstance(urdf, dict) or (isinstance(urdf, str) and urdf.startswith("package://")):
        urdf_path = _package_urdf(problems, urdf)
        if urdf_path is None:
            return None, None
        return build_model(problems, urdf_path), urdf_path
    if not isinstance(urdf, str):
        problems.add("urdf", f"expected a file path or {{package, path}}, got {urdf!r}")
        return None, None
    urdf_path = (spec_path.parent / urdf).resolve()
    if not urdf_path.is_file():
        nearby = sorted(p.name for p in spec_path.parent.glob("*.urdf"))
        hint = f"; URDF files beside the spec: {', '.join(nearby)}" if nearby else ""
        problems.add("urdf", f"file {urdf!r} not found (looked for {urdf_path}){hint}")
        return None, None
    return build_model(problems, urdf_path), urdf_path


def build_model(problems: _Problems, urdf_path: Path):
    """Build a Pinocchio model from a URDF, recording a problem on failure
    (the file is checked by :func:`cdpm.urdf_check.read_urdf` first)."""
    import pinocchio as pin

    from cdpm.urdf_check import read_urdf

    _, urdf_problems = read_urdf(urdf_path)
    if urdf_problems:
        for problem in urdf_problems:
            problems.add("urdf", problem)
        return None
    try:
        return pin.buildModelFromUrdf(str(urdf_path))
    except (ValueError, RuntimeError) as exc:
        problems.add("urdf", f"Pinocchio could not read {urdf_path}: {exc}")
        return None


class _FrameTable:
    """Names a route may use, and each link's centre of mass."""

    def __init__(self, model, link_coms: dict[str, np.ndarray]) -> None:
        self.model = model
        self.names: dict[str, int] = {}
        for fid, frame in enumerate(model.frames):
            if frame.name == "universe":
                continue
            self.names.setdefault(frame.name, fid)
        self.link_coms = link_coms

    def listing(self) -> str:
        names = ["world", *sorted(self.names)]
        more = f", ... ({len(names) - 30} more)" if len(names) > 30 else ""
        return ", ".join(names[:30]) + more

    def exists(self, name: str) -> bool:
        return name in WORLD_FRAME_NAMES or name in self.names

    def com_in_frame(self, name: str) -> np.ndarray | None:
        """Centre of mass of the link ``name`` in that link's frame [m], or
        None when ``name`` is not a link with a positive mass."""
        return self.link_coms.get(name)


def _link_coms(urdf_path: Path) -> dict[str, np.ndarray]:
    """Centre of mass of every URDF link with a positive mass, in its frame.

    Pinocchio merges link inertias into their joint's and keeps no per-link
    record, so the ``<inertial>`` origins are read from the URDF here.
    """
    from cdpm.urdf_check import read_urdf

    coms: dict[str, np.ndarray] = {}
    root, _ = read_urdf(urdf_path)  # checked before the model was built
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        mass = inertial.find("mass")
        if mass is None or not float(mass.get("value", "0")) > 0:
            continue
        origin = inertial.find("origin")
        xyz = origin.get("xyz", "0 0 0") if origin is not None else "0 0 0"
        coms[link.get("name")] = np.array([float(x) for x in xyz.split()])
    return coms


def tension_bound_problems(fmin: float, fmax: float, number=str) -> list[str]:
    """What is wrong with a cable's tension bounds [N] (none: an empty list):
    the minimum must be finite and >= 0, the maximum >= the minimum and > 0.

    Args:
        fmin, fmax: the bounds [N].
        number: how a value is written in the messages (e.g. ``"{:g} N".format``).
    """
    problems = []
    if not (math.isfinite(fmin) and fmin >= 0):
        problems.append(f"minimum {number(fmin)} must be finite and >= 0 (cables only pull)")
    if not fmax >= fmin:
        problems.append(f"maximum {number(fmax)} must be >= minimum {number(fmin)}")
    if fmax == 0:
        problems.append(f"maximum {number(0)} leaves the cable no tension")
    return problems


def _parse_cables(problems: _Problems, raw: Any, frames: _FrameTable | None) -> list[CableDef]:
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
        _unknown_keys(problems, where, item, _CABLE_KEYS)
        name = item.get("name", f"cable{i + 1}")
        if not isinstance(name, str) or not name:
            problems.add(f"{where}.name", f"expected a non-empty string, got {name!r}")
            name = f"cable{i + 1}"
        if name in seen:
            problems.add(f"{where}.name", f"duplicate cable name {name!r}; names must be unique")
        seen.add(name)
        where = f"cables[{i}] ({name})"
        fmin, fmax = 0.0, math.inf
        if "tension" in item:
            bounds = _vector(problems, f"{where}.tension", item["tension"], 2, infinite=True)
            if bounds is not None:
                fmin, fmax = bounds
                for problem in tension_bound_problems(fmin, fmax):
                    problems.add(f"{where}.tension", problem)
        route = _parse_route(problems, where, item.get("route"), frames)
        cables.append(CableDef(name=name, tension_min=fmin, tension_max=fmax, route=route))
    return cables


def _parse_route(
    problems: _Problems, where: str, raw: Any, frames: _FrameTable | None
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
        _unknown_keys(problems, pw, item, _POINT_KEYS)
        frame = item.get("frame")
        ok = True
        if not isinstance(frame, str):
            problems.add(f"{pw}.frame", f"expected a frame name, got {frame!r}")
            ok = False
        elif frames is not None and not frames.exists(frame):
            problems.add(f"{pw}.frame", f"frame {frame!r} not in URDF; frames: {frames.listing()}")
            ok = False
        xyz = _vector(problems, f"{pw}.point", item.get("point"), 3)
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


def _parse_outputs(
    problems: _Problems,
    raw: Any,
    frames: _FrameTable | None,
    model: Any,
    cables: list[CableDef],
) -> list[OutputDef]:
    if raw is None or raw == []:
        problems.add("outputs", f"missing; give at least one output, e.g. - {_OUTPUT_EXAMPLE}")
        return []
    if not isinstance(raw, list):
        problems.add("outputs", f"expected a list of outputs, e.g. {_OUTPUT_EXAMPLE}")
        return []
    outputs: list[OutputDef] = []
    seen: set[str] = set()
    for i, item in enumerate(raw):
        where = f"outputs[{i}]"
        if not isinstance(item, dict):
            problems.add(where, f"expected a mapping such as {_OUTPUT_EXAMPLE}; got {item!r}")
            continue
        _unknown_keys(problems, where, item, _OUTPUT_KEYS)
        if "sum" in item:
            extra = [k for k in _TERM_KEYS if k in item]
            if extra:
                problems.add(
                    where,
                    f"give either sum or {', '.join(extra)}, not both; put each component "
                    "of the sum in its list",
                )
                continue
            terms = _parse_sum(problems, f"{where}.sum", item["sum"], frames, model, cables)
        else:
            term = _parse_term(problems, where, item, frames, model, cables)
            terms = None if term is None else [term]
        if not terms:
            continue
        unit = _output_unit(problems, where, item.get("unit"), terms)
        if unit is None:
            continue
        name = item.get("name", _default_output_name(terms) if "sum" not in item else None)
        if not isinstance(name, str) or not name:
            problems.add(f"{where}.name", f"expected a non-empty string, got {name!r}")
            continue
        if name in seen:
            problems.add(f"{where}.name", f"duplicate output name {name!r}")
        seen.add(name)
        outputs.append(OutputDef(name=name, terms=tuple(terms), unit=unit))
    return outputs


def _default_output_name(terms: list[OutputTerm]) -> str:
    term = terms[0]
    if term.kind in ("position", "rotation"):
        return f"{term.frame}_{term.component}"
    return f"{term.joint or term.cable}_{'length' if term.kind == 'cable' else 'q'}"


def _output_unit(problems: _Problems, where: str, raw: Any, terms: list[OutputTerm]) -> str | None:
    units = {t.unit for t in terms}
    derived = units.pop() if len(units) == 1 else "mixed"
    if raw is None:
        return derived
    if not isinstance(raw, str) or not raw.strip():
        problems.add(f"{where}.unit", f"expected a unit such as m or rad, got {raw!r}")
        return None
    return raw.strip()


def _parse_sum(
    problems: _Problems,
    where: str,
    raw: Any,
    frames: _FrameTable | None,
    model: Any,
    cables: list[CableDef],
) -> list[OutputTerm] | None:
    if not isinstance(raw, list) or not raw:
        problems.add(
            where,
            "expected a non-empty list of weighted components, e.g. "
            "[{weight: 0.5, frame: tip, component: x}, {weight: 2, joint: joint2}]",
        )
        return None
    terms = []
    for k, item in enumerate(raw):
        at = f"{where}[{k}]"
        if not isinstance(item, dict):
            problems.add(
                at,
                f"expected {{weight, frame, component}}, {{weight, joint}} or "
                f"{{weight, cable}}; got {item!r}",
            )
            return None
        _unknown_keys(problems, at, item, _TERM_KEYS)
        term = _parse_term(problems, at, item, frames, model, cables)
        if term is None:
            return None
        terms.append(term)
    return terms


def _parse_term(
    problems: _Problems,
    where: str,
    item: dict,
    frames: _FrameTable | None,
    model: Any,
    cables: list[CableDef],
) -> OutputTerm | None:
    """One output term from its mapping, or None after recording a problem."""
    weight = 1.0
    if "weight" in item:
        try:
            weight = parse_number(item["weight"])
        except ValueError as exc:
            problems.add(f"{where}.weight", f"{exc}; expected a number")
            return None
        if not math.isfinite(weight) or weight == 0:
            problems.add(f"{where}.weight", f"must be finite and nonzero, got {weight!r}")
            return None
    kinds = [k for k in ("frame", "joint", "cable") if k in item]
    if len(kinds) != 1:
        said = f"got {' and '.join(kinds)}" if kinds else "got none"
        problems.add(
            where,
            f"name exactly one of frame (with component), joint or cable; {said}",
        )
        return None
    kind = kinds[0]
    if kind != "frame":
        extra = [k for k in ("component", "point") if k in item]
        if extra:
            problems.add(
                where,
                f"{' and '.join(extra)} apply to frame outputs only; leave "
                f"{'them' if len(extra) > 1 else 'it'} out of a {kind} output",
            )
            return None
    if kind == "joint":
        return _joint_term(problems, f"{where}.joint", item["joint"], model, weight)
    if kind == "cable":
        name = item["cable"]
        names = [c.name for c in cables]
        if not isinstance(name, str) or name not in names:
            problems.add(
                f"{where}.cable",
                f"{name!r} is not a cable of this spec; cables: {', '.join(names) or '(none)'}",
            )
            return None
        return OutputTerm(kind="cable", weight=weight, cable=name, unit="m")
    frame = item["frame"]
    component = item.get("component")
    if not isinstance(frame, str):
        problems.add(f"{where}.frame", f"expected a frame name, got {frame!r}")
        return None
    if frames is not None and not frames.exists(frame):
        problems.add(f"{where}.frame", f"frame {frame!r} not in URDF; frames: {frames.listing()}")
        return None
    if component not in OUTPUT_COMPONENTS:
        problems.add(
            f"{where}.component",
            f"{component!r} is not valid; use one of {', '.join(OUTPUT_COMPONENTS)} "
            "(x, y, z: world position [m]; rx, ry, rz: rotation about the world axes [rad])",
        )
        return None
    rotation = component in ROTATION_COMPONENTS
    point = (0.0, 0.0, 0.0)
    if item.get("point") is not None:
        if rotation:
            problems.add(
                f"{where}.point",
                f"a frame's orientation ({component}) is the same at every point of it; "
                "leave point out",
            )
            return None
        xyz = _vector(problems, f"{where}.point", item["point"], 3)
        if xyz is None:
            return None
        if not all(math.isfinite(x) for x in xyz):
            problems.add(f"{where}.point", f"values must be finite, got {xyz}")
            return None
        point = tuple(xyz)
    return OutputTerm(
        kind="rotation" if rotation else "position",
        weight=weight,
        frame=frame,
        component=component,
        point_in_frame=point,
        unit="rad" if rotation else "m",
    )


def _joint_term(problems: _Problems, where: str, name: Any, model: Any, weight: float):
    """A joint term: one-degree-of-freedom joints only (their coordinate
    is the natural one, and its rate is the tangent direction)."""
    if model is None:
        return None
    joints = [model.names[j] for j in range(1, model.njoints)]
    if not isinstance(name, str) or name not in joints:
        problems.add(where, f"{name!r} is not a joint of the URDF; joints: {', '.join(joints)}")
        return None
    joint = model.joints[model.getJointId(name)]
    short = joint.shortname()
    if joint.nv != 1 or not short.startswith(("JointModelR", "JointModelP")):
        problems.add(
            where,
            f"joint {name!r} ({short.removeprefix('JointModel')}, {joint.nv} degrees of "
            "freedom) is not revolute or prismatic; use frame outputs (x, y, z, rx, ry, rz) "
            "of the link it moves",
        )
        return None
    unit = "rad" if short.startswith("JointModelR") else "m"
    return OutputTerm(kind="joint", weight=weight, joint=name, unit=unit)


def _parse_poses(problems: _Problems, raw: Any, model) -> dict[str, np.ndarray]:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        problems.add("poses", "expected a mapping from pose name to configuration")
        return {}
    if model is None:
        return {}
    from cdpm.configuration import ConfigurationError, configuration_from_values

    poses: dict[str, np.ndarray] = {}
    for name, value in raw.items():
        try:
            poses[str(name)] = configuration_from_values(model, value)
        except ConfigurationError as exc:
            problems.add(f"poses.{name}", str(exc))
    return poses


def _parse_equilibrium(problems: _Problems, raw: Any) -> tuple[str, float]:
    if raw is None:
        return "min_norm", 0.0
    if not isinstance(raw, dict):
        problems.add("equilibrium", "expected {method: NAME, pretension: N}")
        return "min_norm", 0.0
    _unknown_keys(problems, "equilibrium", raw, _EQUILIBRIUM_KEYS)
    method = raw.get("method", "min_norm")
    if method not in EQUILIBRIUM_METHODS:
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
        else:
            if not (math.isfinite(pretension) and pretension >= 0):
                problems.add("equilibrium.pretension", "must be finite and >= 0 N")
    if method == "pretension" and pretension == 0:
        problems.add(
            "equilibrium",
            "method 'pretension' needs pretension: N > 0 (every cable at least N newtons); "
            "with 0 it is the min_norm method, so give the pretension or use method: min_norm",
        )
    return method, pretension
