"""Import CASPR models: bodies + cables XML -> URDF + cdpm cable spec.

CASPR (the MATLAB cable-robot platform) describes a robot in two XML files:
``<name>_bodies.xml`` (rigid links, their joints, inertias and parents) and
``<name>_cables.xml`` (cable sets; each cable an ordered list of attachment
points), plus an optional ``<name>_operational_spaces.xml``. This module
reads them with the standard library's XML parser (nothing is executed and no
external DTD or entity is fetched), writes a URDF through yourdfpy's object
model and a cable spec with ``yaml.safe_dump``, and checks that
:func:`cdpm.load_robot` loads the pair.

CASPR conventions reproduced here (CASPR ``SystemModelBodies.update``,
``JointBase``, ``CableAttachmentPoint``, ``BodyModelRigid``):

* Link k's frame sits at its joint point P. Its origin in the parent frame
  is ``r_Parent + r_rel(q)`` (``<parent><location>`` is given in the parent
  link's frame, relative to the parent's joint point, not its centre of mass;
  ``r_rel`` is the joint's translation along the parent's axes) and its
  orientation is ``R_pe(q)`` (vector_in_parent = R_pe @ vector_in_link).
* ``com_location`` and ``end_location`` are given in the link frame from P.
* ``<inertia ref="com">`` is about the centre of mass in link axes;
  ``ref="joint"`` is about P and is shifted to the centre of mass.
* Attachment ``location`` is in the link frame, from the centre of mass
  (``attachment_reference="com"``) or from P (``"joint"``); on link 0 (the
  ground) it is always a world position.
* Gravity is ``[0, 0, -9.81]`` m/s^2 in the world frame.

Every multi-DOF CASPR joint becomes a chain of 1-DOF URDF joints through
massless intermediate links, in the order of CASPR's rotation product, so
the cdpm coordinates are exactly CASPR's q (same values, same singularities;
only ``S_FIXED_XYZ`` lists its three angles in reverse order). See
``docs/caspr.md`` for the full mapping and what is refused or ignored.
"""

from __future__ import annotations

import html
import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import InputError, MissingExtraError, ModelError, UnsupportedError

__all__ = [
    "CasprImport",
    "CasprWarning",
    "import_caspr",
    "cable_sets",
    "JOINT_CHAINS",
    "GRAVITY",
]

#: CASPR's gravity vector [m/s^2] (``SystemModel.GRAVITY_CONSTANT`` along -z).
GRAVITY = (0.0, 0.0, -9.81)

# One 1-DOF URDF joint of a chain: (URDF type, axis, index into the CASPR
# joint's q, name suffix). Axis "axis" means the joint's ``axis`` attribute.
_PX = ("prismatic", "x")
_PY = ("prismatic", "y")
_PZ = ("prismatic", "z")
_RX = ("revolute", "x")
_RY = ("revolute", "y")
_RZ = ("revolute", "z")

#: CASPR joint type -> chain of (URDF type, axis, index in CASPR q). The
#: chain order is the order of CASPR's product ``R_pe`` (translations, which
#: CASPR adds along the parent's axes, come first).
JOINT_CHAINS: dict[str, tuple[tuple[str, str, int], ...]] = {
    "R_X": ((*_RX, 0),),
    "R_Y": ((*_RY, 0),),
    "R_Z": ((*_RZ, 0),),
    "R_AXIS": (("revolute", "axis", 0),),
    "P_X": ((*_PX, 0),),
    "P_AXIS": (("prismatic", "axis", 0),),
    "P_XY": ((*_PX, 0), (*_PY, 1)),
    "P_XZ": ((*_PX, 0), (*_PZ, 1)),
    "T_XYZ": ((*_PX, 0), (*_PY, 1), (*_PZ, 2)),
    "PLANAR_XY": ((*_PX, 0), (*_PY, 1), (*_RZ, 2)),
    "PLANAR_XZ": ((*_PX, 0), (*_PZ, 1), (*_RY, 2)),
    "PLANAR_YZ": ((*_PY, 0), (*_PZ, 1), (*_RX, 2)),
    "U_XY": ((*_RX, 0), (*_RY, 1)),
    "U_XZ": ((*_RX, 0), (*_RZ, 1)),
    "U_YZ": ((*_RY, 0), (*_RZ, 1)),
    "S_EULER_XYZ": ((*_RX, 0), (*_RY, 1), (*_RZ, 2)),
    # R = Rz(gamma) Ry(beta) Rx(alpha) with q = (alpha, beta, gamma)
    "S_FIXED_XYZ": ((*_RZ, 2), (*_RY, 1), (*_RX, 0)),
    "SPATIAL_EULER_XYZ": ((*_PX, 0), (*_PY, 1), (*_PZ, 2), (*_RX, 3), (*_RY, 4), (*_RZ, 5)),
}

# CASPR's default bounds (JointBase q_lb/q_ub) when a file gives none.
_DEFAULT_BOUND = {"revolute": math.pi, "prismatic": math.inf}
# URDF needs finite limits; an unbounded prismatic joint gets this [m].
_UNBOUNDED_PRISMATIC = 1e3

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}

#: Joint types CASPR itself marks unsupported; refused with this hint.
_QUATERNION_JOINTS = ("S_QUATERNION", "SPATIAL_QUATERNION")

#: Cable models whose extra parameters only describe the cable's elasticity
#: (the tension stays the input): imported as ideal cables with a warning.
_ELASTIC_CABLES = (
    "cable_linear_spring",
    "cable_vsd_flexure_linear",
    "cable_vsd_polynomial",
    "cable_vsd_torsion_spring",
)
#: Cable models that are not tension inputs at all: refused.
_PASSIVE_CABLES = ("cable_passive_linear_spring",)
#: Attachment elements that are pulleys or winches (not fixed points): refused.
_PULLEY_ATTACHMENTS = ("base_rotating_pulley", "screw_base_rotating_pulley")

_KNOWN_PROPERTIES = ("force_min", "force_max")

#: A cable segment shorter than this [m] at the named pose counts as degenerate.
_MIN_SEGMENT = 1e-6


class CasprWarning(UserWarning):
    """Something in a CASPR file was ignored or changed during import."""


@dataclass(frozen=True)
class CasprImport:
    """Result of :func:`import_caspr`.

    Attributes:
        name: model name (file stem of the URDF and spec).
        urdf_path: the URDF written.
        spec_path: the cable spec written (load it with :func:`cdpm.load_robot`).
        cable_set: id of the CASPR cable set imported.
        operational_set: id of the CASPR operational set turned into outputs,
            or None.
        n_links: number of CASPR links.
        cable_names: names of the cables, in spec order.
        output_names: names of the spec outputs.
        coordinates: for each cdpm coordinate (tangent-space order), the
            CASPR coordinate it is: ``"joint2_rx <- link 2 'Lower Arm' q[1]"``.
        caspr_coordinates: for each cdpm coordinate, (CASPR link number,
            index in that link's joint q), to translate poses either way.
        pose_name: name of the pose written to the spec.
        pose: that pose in cdpm coordinates, shape (nv,).
        warnings: what was ignored or changed, one line each.
    """

    name: str
    urdf_path: Path
    spec_path: Path
    cable_set: str
    operational_set: str | None
    n_links: int
    cable_names: tuple[str, ...]
    output_names: tuple[str, ...]
    coordinates: tuple[str, ...]
    caspr_coordinates: tuple[tuple[int, int], ...]
    pose_name: str
    pose: np.ndarray
    warnings: tuple[str, ...] = field(default=())

    def as_dict(self) -> dict:
        """JSON-serialisable content."""
        return {
            "name": self.name,
            "urdf": str(self.urdf_path),
            "spec": str(self.spec_path),
            "cable_set": self.cable_set,
            "operational_set": self.operational_set,
            "n_links": self.n_links,
            "cables": list(self.cable_names),
            "outputs": list(self.output_names),
            "coordinates": list(self.coordinates),
            "pose": {self.pose_name: self.pose.tolist()},
            "warnings": list(self.warnings),
        }

    def __str__(self) -> str:
        lines = [
            f"CASPR model {self.name!r}: {self.n_links} link(s), {len(self.coordinates)} "
            f"coordinate(s), {len(self.cable_names)} cable(s) (set {self.cable_set!r}), "
            f"{len(self.output_names)} output(s)"
            + (f" (operational set {self.operational_set!r})" if self.operational_set else ""),
            f"  URDF: {self.urdf_path}",
            f"  spec: {self.spec_path}",
            f"  pose {self.pose_name!r}: {np.round(self.pose, 6).tolist()}",
            "  coordinates:",
            *(f"    {c}" for c in self.coordinates),
        ]
        if self.warnings:
            lines.append(f"  {len(self.warnings)} warning(s):")
            lines.extend(f"    - {w}" for w in self.warnings)
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(str(self))}</pre>"


# ---------------------------------------------------------------------------
# reading the XML


@dataclass(frozen=True)
class _Link:
    num: int
    name: str
    joint_type: str
    q_initial: tuple[float, ...]
    q_min: tuple[float, ...]
    q_max: tuple[float, ...]
    axis: tuple[float, float, float] | None
    mass: float
    com: np.ndarray
    end: np.ndarray
    inertia_com: np.ndarray
    parent: int
    parent_location: np.ndarray


@dataclass(frozen=True)
class _Attachment:
    link: int
    location: np.ndarray


@dataclass(frozen=True)
class _Cable:
    name: str
    reference: str
    force_min: float
    force_max: float
    attachments: tuple[_Attachment, ...]


@dataclass(frozen=True)
class _OpPoint:
    name: str
    link: int
    offset: np.ndarray
    axes: str


def _parse_xml(path: Path, what: str) -> ET.Element:
    if not path.is_file():
        raise InputError(f"CASPR {what} file not found: {path}")
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise InputError(
            f"{path}: not well-formed XML ({exc}); expected a CASPR {what} file"
        ) from exc


def _describe(element: ET.Element) -> str:
    """``<tag a="b" ...>`` of an element, for messages."""
    attrs = " ".join(f'{k}="{v}"' for k, v in element.attrib.items())
    return f"<{element.tag}{' ' + attrs if attrs else ''}>"


def _text(parent: ET.Element, tag: str, path: Path, where: str) -> str:
    child = parent.find(tag)
    if child is None or child.text is None or not child.text.strip():
        raise InputError(f"{path}: {where} has no <{tag}>; CASPR requires it")
    return child.text.strip()


def _numbers(text: str, path: Path, where: str, size: int | None = None) -> tuple[float, ...]:
    try:
        values = tuple(float(x) for x in text.split())
    except ValueError as exc:
        raise InputError(f"{path}: {where}: {text!r} is not a list of numbers") from exc
    if size is not None and len(values) != size:
        raise InputError(f"{path}: {where}: expected {size} numbers, got {len(values)}: {text!r}")
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{path}: {where}: values must be finite, got {text!r}")
    return values


def _read_bodies(path: Path) -> tuple[list[_Link], dict[str, str]]:
    root = _parse_xml(path, "bodies")
    links_el = root.find("links")
    if root.tag != "bodies_system" or links_el is None:
        raise InputError(
            f"{path}: expected <bodies_system><links>...</links></bodies_system> "
            f"(a CASPR *_bodies.xml file), found <{root.tag}>"
        )
    meta = {k: v for k, v in links_el.attrib.items() if k in ("display_range", "view_angle")}
    links: list[_Link] = []
    for child in links_el:
        if child.tag != "link_rigid":
            raise UnsupportedError(
                f"{path}: {_describe(child)} is not supported; only <link_rigid> bodies are"
            )
        links.append(_read_link(path, child, len(links) + 1))
    if not links:
        raise InputError(f"{path}: <links> holds no <link_rigid>; nothing to import")
    return links, meta


def _read_link(path: Path, el: ET.Element, expected_num: int) -> _Link:
    where = _describe(el)
    try:
        num = int(el.get("num", ""))
    except ValueError as exc:
        raise InputError(f"{path}: {where} needs an integer num attribute") from exc
    if num != expected_num:
        raise InputError(
            f"{path}: {where} is link number {expected_num} in file order; CASPR numbers "
            "links 1, 2, ... in the order they appear"
        )
    name = el.get("name", f"link {num}")
    joint = el.find("joint")
    if joint is None:
        raise InputError(f"{path}: {where} has no <joint>")
    jtype = joint.get("type", "")
    jwhere = f"{_describe(joint)} of {where}"
    if joint.get("actuated", "false").strip().lower() == "true":
        raise UnsupportedError(
            f"{path}: {jwhere} is an actuated joint (a hybrid cable/joint-actuated robot); "
            'cdpm models cable-driven joints only. Remove actuated="true" to import the '
            "mechanism with that joint passive"
        )
    if jtype in _QUATERNION_JOINTS:
        raise UnsupportedError(
            f"{path}: {jwhere}: quaternion joints are marked unsupported in CASPR itself and "
            "have no URDF equivalent; use S_EULER_XYZ or SPATIAL_EULER_XYZ"
        )
    if jtype not in JOINT_CHAINS:
        raise UnsupportedError(
            f"{path}: {jwhere}: joint type {jtype!r} is not supported; supported: "
            f"{', '.join(JOINT_CHAINS)}"
        )
    chain = JOINT_CHAINS[jtype]
    n = len(chain)
    q_initial = _numbers(joint.get("q_initial", ""), path, f"{jwhere} q_initial", n)
    bounds = []
    for attr, sign in (("q_min", -1.0), ("q_max", 1.0)):
        if joint.get(attr) is None:
            bounds.append(tuple(sign * _DEFAULT_BOUND[kind] for kind, _a, _i in _sorted(chain)))
        else:
            bounds.append(_numbers(joint.get(attr), path, f"{jwhere} {attr}", n))
    axis = None
    if any(a == "axis" for _k, a, _i in chain):
        if joint.get("axis") is None:
            raise InputError(f"{path}: {jwhere} needs an axis attribute (3 numbers)")
        vec = np.array(_numbers(joint.get("axis"), path, f"{jwhere} axis", 3))
        norm = float(np.linalg.norm(vec))
        if norm == 0:
            raise InputError(f"{path}: {jwhere}: axis must not be the zero vector")
        axis = tuple(float(x) for x in vec / norm)  # CASPR normalises it too
    elif joint.get("axis") is not None:
        raise InputError(f"{path}: {jwhere}: an axis is only allowed on R_AXIS/P_AXIS joints")

    physical = el.find("physical")
    if physical is None:
        raise InputError(f"{path}: {where} has no <physical>")
    mass = _numbers(_text(physical, "mass", path, where), path, f"{where} mass", 1)[0]
    if mass < 0:
        raise InputError(f"{path}: {where}: mass {mass} must be >= 0")
    com = np.array(
        _numbers(_text(physical, "com_location", path, where), path, f"{where} com_location", 3)
    )
    end = np.array(
        _numbers(_text(physical, "end_location", path, where), path, f"{where} end_location", 3)
    )
    inertia_el = physical.find("inertia")
    if inertia_el is None:
        raise InputError(f"{path}: {where} has no <inertia>")
    entries = {
        k: _numbers(_text(inertia_el, k, path, where), path, f"{where} {k}", 1)[0]
        for k in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
    }
    inertia = np.array(
        [
            [entries["Ixx"], entries["Ixy"], entries["Ixz"]],
            [entries["Ixy"], entries["Iyy"], entries["Iyz"]],
            [entries["Ixz"], entries["Iyz"], entries["Izz"]],
        ]
    )
    ref = inertia_el.get("ref")
    if ref == "joint":
        inertia = inertia - mass * (float(com @ com) * np.eye(3) - np.outer(com, com))
    elif ref != "com":
        raise UnsupportedError(
            f"{path}: {_describe(inertia_el)} of {where}: inertia reference {ref!r} is not "
            'supported; use ref="com" or ref="joint"'
        )
    parent_el = el.find("parent")
    if parent_el is None:
        raise InputError(f"{path}: {where} has no <parent>")
    try:
        parent = int(_text(parent_el, "num", path, where))
    except ValueError as exc:
        raise InputError(f"{path}: {where}: <parent><num> must be an integer") from exc
    if not 0 <= parent < num:
        raise InputError(
            f"{path}: {where}: parent {parent} must be 0 (ground) or an earlier link (< {num})"
        )
    location = np.array(
        _numbers(_text(parent_el, "location", path, where), path, f"{where} parent location", 3)
    )
    return _Link(
        num=num,
        name=name,
        joint_type=jtype,
        q_initial=q_initial,
        q_min=bounds[0],
        q_max=bounds[1],
        axis=axis,
        mass=mass,
        com=com,
        end=end,
        inertia_com=inertia,
        parent=parent,
        parent_location=location,
    )


def _sorted(chain):
    """Chain entries in CASPR q order."""
    return sorted(chain, key=lambda item: item[2])


def cable_sets(cables_xml: str | os.PathLike) -> tuple[tuple[str, ...], str | None]:
    """Ids of the cable sets in a CASPR cables file and its default set.

    Returns:
        (ids in file order, the ``default_cable_set`` attribute or None).
    """
    path = Path(cables_xml)
    root = _parse_xml(path, "cables")
    ids = tuple(s.get("id", "") for s in root.findall("cable_set"))
    return ids, root.get("default_cable_set")


def _read_cables(path: Path, cable_set: str | None, n_links: int, warn) -> tuple[str, list[_Cable]]:
    root = _parse_xml(path, "cables")
    if root.tag != "cables":
        raise InputError(f"{path}: expected a <cables> root (a CASPR *_cables.xml file)")
    sets = {s.get("id", ""): s for s in root.findall("cable_set")}
    chosen = cable_set if cable_set is not None else root.get("default_cable_set")
    if chosen is None:
        if len(sets) != 1:
            raise InputError(
                f"{path}: no default_cable_set; choose one with cable_set= / --cable-set "
                f"(sets: {', '.join(sets) or 'none'})"
            )
        chosen = next(iter(sets))
    if chosen not in sets:
        raise InputError(
            f"{path}: cable set {chosen!r} not found; sets in this file: "
            f"{', '.join(sets) or 'none'}"
        )
    set_el = sets[chosen]
    set_where = _describe(set_el)
    cables: list[_Cable] = []
    names: set[str] = set()
    for cable_el in set_el:
        where = f"{_describe(cable_el)} in {set_where}"
        tag = cable_el.tag
        if tag in _PASSIVE_CABLES:
            raise UnsupportedError(
                f"{path}: {where}: a passive spring's force is set by its length, not an "
                "input; cdpm has no passive elastic elements. Choose a cable set without "
                "passive springs"
            )
        if tag != "cable_ideal" and tag not in _ELASTIC_CABLES:
            raise UnsupportedError(
                f"{path}: {where}: cable model <{tag}> is not supported; supported: "
                f"cable_ideal, {', '.join(_ELASTIC_CABLES)}"
            )
        name = cable_el.get("name") or f"cable {len(cables) + 1}"
        if name in names:
            new = f"{name} ({len(cables) + 1})"
            warn(f"{path}: {where}: duplicate cable name {name!r} renamed {new!r}")
            name = new
        names.add(name)
        reference = cable_el.get("attachment_reference")
        if reference not in ("com", "joint"):
            raise InputError(
                f"{path}: {where}: attachment_reference must be 'com' or 'joint', got {reference!r}"
            )
        props = cable_el.find("properties")
        bounds = {"force_min": 0.0, "force_max": math.inf}
        ignored: list[str] = []
        if props is not None:
            for prop in props:
                if prop.tag in _KNOWN_PROPERTIES:
                    bounds[prop.tag] = _numbers(prop.text or "", path, f"{where} <{prop.tag}>", 1)[
                        0
                    ]
                else:
                    ignored.append(prop.tag)
        missing = [k for k in _KNOWN_PROPERTIES if props is None or props.find(k) is None]
        if missing:
            warn(f"{path}: {where}: no {' or '.join(missing)}; using [0, inf] N defaults")
        if tag in _ELASTIC_CABLES:
            warn(
                f"{path}: {where}: elastic cable imported as an ideal cable; its stiffness "
                f"parameters ({', '.join(ignored) or 'none'}) are ignored because cdpm's input "
                "is the cable tension, which they do not change"
            )
        elif ignored:
            warn(f"{path}: {where}: properties {', '.join(ignored)} ignored (not used by cdpm)")
        fmin, fmax = bounds["force_min"], bounds["force_max"]
        if fmin < 0:
            raise UnsupportedError(
                f"{path}: {where}: force_min {fmin} < 0 (a pushing cable); cdpm cables only pull"
            )
        if not fmax > 0 or fmax < fmin:
            raise InputError(
                f"{path}: {where}: force bounds [{fmin}, {fmax}] are empty or zero; "
                "need 0 <= force_min <= force_max, force_max > 0"
            )
        attachments_el = cable_el.find("attachments")
        if attachments_el is None:
            raise InputError(f"{path}: {where} has no <attachments>")
        attachments: list[_Attachment] = []
        for att in attachments_el:
            if att.tag in _PULLEY_ATTACHMENTS:
                raise UnsupportedError(
                    f"{path}: {_describe(att)} of {where}: pulley attachments are not "
                    "supported (cdpm routes are straight segments between fixed points); "
                    "choose a cable set with point attachments"
                )
            if att.tag != "attachment":
                raise UnsupportedError(
                    f"{path}: {_describe(att)} of {where}: attachment type <{att.tag}> is not "
                    "supported; only <attachment> points are"
                )
            try:
                link = int(_text(att, "link", path, where))
            except ValueError as exc:
                raise InputError(f"{path}: {where}: <link> must be an integer") from exc
            if not 0 <= link <= n_links:
                raise InputError(
                    f"{path}: {where}: attachment on link {link}, but the bodies file has links "
                    f"0 (ground) to {n_links}"
                )
            loc = np.array(_numbers(_text(att, "location", path, where), path, where, 3))
            attachments.append(_Attachment(link=link, location=loc))
        if len(attachments) < 2:
            raise InputError(
                f"{path}: {where} has {len(attachments)} attachment point(s); a cable needs >= 2"
            )
        cables.append(
            _Cable(
                name=name,
                reference=reference,
                force_min=fmin,
                force_max=fmax,
                attachments=tuple(attachments),
            )
        )
    if not cables:
        raise InputError(
            f"{path}: {set_where} has no cables; choose another set "
            f"(sets: {', '.join(k for k, v in sets.items() if len(v))})"
        )
    return chosen, cables


def _read_operational_spaces(
    path: Path, operational_set: str | None, n_links: int, warn
) -> tuple[str | None, list[_OpPoint]]:
    root = _parse_xml(path, "operational spaces")
    sets = {s.get("id", ""): s for s in root.findall("operational_set")}
    chosen = operational_set
    if chosen is None:
        chosen = root.get("default_operational_set") or (next(iter(sets)) if sets else None)
    if chosen is None:
        return None, []
    if chosen not in sets:
        raise InputError(
            f"{path}: operational set {chosen!r} not found; sets: {', '.join(sets) or 'none'}"
        )
    points: list[_OpPoint] = []
    for el in sets[chosen]:
        where = f"{_describe(el)} in operational set {chosen!r}"
        axes = (
            el.find("axes").get("active_axes", "") if el.find("axes") is not None else ""
        ).lower()
        if el.tag == "orientation_euler_xyz":
            warn(f"{path}: {where}: orientation outputs are not supported by cdpm; ignored")
            continue
        if el.tag not in ("position", "pose_euler_xyz"):
            warn(f"{path}: {where}: operational space <{el.tag}> not supported; ignored")
            continue
        position_axes = "".join(a for a in axes if a in "xyz")
        if len(position_axes) != len(axes):
            warn(
                f"{path}: {where}: orientation components "
                f"{''.join(a for a in axes if a not in 'xyz')!r} ignored; "
                f"position components {position_axes!r} kept"
            )
        if not position_axes:
            continue
        try:
            link = int(_text(el, "link", path, where))
        except ValueError as exc:
            raise InputError(f"{path}: {where}: <link> must be an integer") from exc
        if not 1 <= link <= n_links:
            raise InputError(f"{path}: {where}: link {link} not in 1..{n_links}")
        offset_el = el.find("offset")
        offset = (
            np.array(_numbers(offset_el.text or "", path, where, 3))
            if offset_el is not None
            else np.zeros(3)
        )
        points.append(
            _OpPoint(
                name=el.get("name") or f"op{len(points) + 1}",
                link=link,
                offset=offset,
                axes=position_axes,
            )
        )
    return chosen, points


# ---------------------------------------------------------------------------
# writing


def _slug(text: str) -> str:
    slug = re.sub(r"[^0-9A-Za-z]+", "_", text).strip("_").lower()
    return slug or "op"


@dataclass
class _Dof:
    joint_name: str
    link: _Link
    index: int  # in the CASPR joint's q
    kind: str


def _build_urdf(name: str, links: list[_Link], op_points: list[_OpPoint]):
    """yourdfpy Robot and the 1-DOF joints in chain order."""
    try:
        import yourdfpy
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingExtraError(
            "importing CASPR models writes the URDF with yourdfpy; install it with "
            "pip install 'cdpm[caspr]'"
        ) from exc

    def transform(xyz) -> np.ndarray:
        t = np.eye(4)
        t[:3, 3] = xyz
        return t

    urdf_links = [yourdfpy.Link(name="base")]
    urdf_joints = []
    dofs: list[_Dof] = []
    for link in links:
        parent = "base" if link.parent == 0 else f"link{link.parent}"
        chain = JOINT_CHAINS[link.joint_type]
        for k, (kind, axis_name, index) in enumerate(chain):
            last = k == len(chain) - 1
            child = f"link{link.num}" if last else f"link{link.num}_{k + 1}"
            suffix = (
                "" if len(chain) == 1 else "_" + ("r" if kind == "revolute" else "") + axis_name
            )
            joint_name = f"joint{link.num}{suffix}"
            axis = link.axis if axis_name == "axis" else _AXES[axis_name]
            lower, upper = link.q_min[index], link.q_max[index]
            if kind == "prismatic":
                lower = max(lower, -_UNBOUNDED_PRISMATIC)
                upper = min(upper, _UNBOUNDED_PRISMATIC)
            urdf_joints.append(
                yourdfpy.Joint(
                    name=joint_name,
                    type=kind,
                    parent=parent,
                    child=child,
                    origin=transform(link.parent_location if k == 0 else np.zeros(3)),
                    axis=np.array(axis, dtype=float),
                    limit=yourdfpy.Limit(effort=0.0, velocity=0.0, lower=lower, upper=upper),
                )
            )
            if last:
                urdf_links.append(
                    yourdfpy.Link(
                        name=child,
                        inertial=yourdfpy.Inertial(
                            origin=transform(link.com),
                            mass=float(link.mass),
                            inertia=link.inertia_com.copy(),
                        ),
                    )
                )
            else:
                urdf_links.append(yourdfpy.Link(name=child))
            dofs.append(_Dof(joint_name=joint_name, link=link, index=index, kind=kind))
            parent = child
        urdf_links.append(yourdfpy.Link(name=f"link{link.num}_end"))
        urdf_joints.append(
            yourdfpy.Joint(
                name=f"link{link.num}_end_joint",
                type="fixed",
                parent=f"link{link.num}",
                child=f"link{link.num}_end",
                origin=transform(link.end),
            )
        )
    for op, frame in zip(op_points, _op_frames(op_points), strict=True):
        urdf_links.append(yourdfpy.Link(name=frame))
        urdf_joints.append(
            yourdfpy.Joint(
                name=f"{frame}_joint",
                type="fixed",
                parent=f"link{op.link}",
                child=frame,
                origin=transform(op.offset),
            )
        )
    robot = yourdfpy.Robot(name=name, links=urdf_links, joints=urdf_joints)
    return yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False), dofs


def _op_frames(op_points: list[_OpPoint]) -> list[str]:
    frames, used = [], set()
    for op in op_points:
        frame = f"op_{_slug(op.name)}"
        while frame in used:
            frame += "_"
        used.add(frame)
        frames.append(frame)
    return frames


def _point_entry(links_by_num: dict[int, _Link], cable: _Cable, att: _Attachment) -> dict:
    loc = [float(x) for x in att.location]
    if att.link == 0:
        return {"frame": "base", "point": loc}
    frame = f"link{att.link}"
    if cable.reference == "com":
        if links_by_num[att.link].mass > 0:
            return {"frame": frame, "point": loc, "relative_to": "com"}
        # cdpm's relative_to: com needs a link with mass; shift by hand
        loc = [float(x) for x in att.location + links_by_num[att.link].com]
    return {"frame": frame, "point": loc}


def import_caspr(
    bodies_xml: str | os.PathLike,
    cables_xml: str | os.PathLike,
    out_dir: str | os.PathLike,
    cable_set: str | None = None,
    *,
    operational_spaces_xml: str | os.PathLike | None = None,
    operational_set: str | None = None,
    name: str | None = None,
    seed: int = 0,
) -> CasprImport:
    """Convert a CASPR model into a URDF and a cdpm cable spec.

    Args:
        bodies_xml: CASPR ``<name>_bodies.xml``.
        cables_xml: CASPR ``<name>_cables.xml``.
        out_dir: folder to write ``<name>.urdf`` and ``<name>.yaml`` into
            (created if missing; existing files of that name are replaced).
        cable_set: id of the cable set to import; default the file's
            ``default_cable_set``.
        operational_spaces_xml: CASPR operational spaces file; default
            ``<name>_operational_spaces.xml`` beside the bodies file, if any.
        operational_set: id of the operational set whose position components
            become outputs; default the file's default set, else its first.
            With no position outputs, the outputs are the world coordinates
            of the last link's end point that the joints can move.
        name: model name for the files; default the bodies file name without
            ``_bodies.xml``.
        seed: seed of the search for a pose when CASPR's ``q_initial`` has a
            zero-length cable segment or lies outside the joint limits.

    Returns:
        A :class:`CasprImport` with the paths written and the warnings.

    Raises:
        UnsupportedError: the model uses something cdpm cannot represent
            (pulleys, passive springs, actuated joints, quaternion joints,
            unknown joint or cable types); the message names the element and
            the file.
        InputError: a file is missing, malformed or inconsistent.
        MissingExtraError: yourdfpy is not installed.
    """
    import yaml

    bodies_path = Path(bodies_xml).expanduser().resolve()
    cables_path = Path(cables_xml).expanduser().resolve()
    out = Path(out_dir).expanduser().resolve()
    stem = bodies_path.name
    stem = stem[: -len("_bodies.xml")] if stem.endswith("_bodies.xml") else bodies_path.stem
    model_name = name or stem
    if not re.fullmatch(r"[A-Za-z0-9_.\-]+", model_name):
        raise InputError(
            f"model name {model_name!r} must be letters, digits, '_', '-' or '.'; pass name="
        )

    collected: list[str] = []

    def warn(message: str) -> None:
        collected.append(message)
        warnings.warn(message, CasprWarning, stacklevel=3)

    links, meta = _read_bodies(bodies_path)
    links_by_num = {link.num: link for link in links}
    chosen_set, cables = _read_cables(cables_path, cable_set, len(links), warn)

    if operational_spaces_xml is None:
        candidate = bodies_path.with_name(f"{stem}_operational_spaces.xml")
        ops_path = candidate if candidate.is_file() else None
    else:
        ops_path = Path(operational_spaces_xml).expanduser().resolve()
    op_set, op_points = (None, [])
    if ops_path is not None:
        op_set, op_points = _read_operational_spaces(ops_path, operational_set, len(links), warn)
    elif operational_set is not None:
        raise InputError(
            f"operational set {operational_set!r} asked for, but no operational spaces file "
            f"(looked for {bodies_path.with_name(f'{stem}_operational_spaces.xml')})"
        )

    urdf, dofs = _build_urdf(model_name, links, op_points)
    out.mkdir(parents=True, exist_ok=True)
    urdf_path = out / f"{model_name}.urdf"
    spec_path = out / f"{model_name}.yaml"
    urdf.write_xml_file(str(urdf_path))

    outputs = []
    for op, frame in zip(op_points, _op_frames(op_points), strict=True):
        for axis in op.axes:
            outputs.append({"name": f"{_slug(op.name)}_{axis}", "frame": frame, "component": axis})
    default_outputs = not outputs
    if default_outputs:
        tip = f"link{links[-1].num}_end"
        outputs = [{"name": f"{tip}_{a}", "frame": tip, "component": a} for a in "xyz"]

    description = (
        f"CASPR model {stem}: {len(links)} link(s) "
        f"({', '.join(f'{k.num}: {k.name} [{k.joint_type}]' for k in links)}); "
        f"cable set {chosen_set!r}"
        + (f"; operational set {op_set!r}" if op_set else "")
        + "".join(f"; CASPR {k.replace('_', ' ')}: [{v}]" for k, v in meta.items())
    )
    spec: dict[str, Any] = {
        "description": description,
        "source": (
            f"CASPR model library (darwinlau/CASPR, BSD-3-Clause): {bodies_path.name}, "
            f"{cables_path.name}" + (f", {ops_path.name}" if ops_path else "")
        ),
        "urdf": urdf_path.name,
        "gravity": list(GRAVITY),
        "cables": [
            {
                "name": cable.name,
                "tension": [cable.force_min, cable.force_max],
                "route": [_point_entry(links_by_num, cable, a) for a in cable.attachments],
            }
            for cable in cables
        ],
        "outputs": outputs,
    }

    def write_spec() -> None:
        spec_path.write_text(
            "# Imported from CASPR by cdpm import-caspr; see docs/caspr.md for the mapping.\n"
            + yaml.safe_dump(spec, sort_keys=False, default_flow_style=None, width=100),
            encoding="utf-8",
        )

    write_spec()
    from cdpm.robot import load_robot

    robot = load_robot(spec_path)
    dof_of_joint = {d.joint_name: d for d in dofs}
    # cdpm coordinates (tangent order) <- CASPR coordinates
    order = [dof_of_joint[n] for n in robot.coordinate_names]
    lower = np.array([d.link.q_min[d.index] for d in order])
    upper = np.array([d.link.q_max[d.index] for d in order])
    initial = np.array([d.link.q_initial[d.index] for d in order])
    pose_name, natural = _choose_pose(robot, initial, lower, upper, seed, warn)

    if default_outputs:
        keep = _moving_components(robot, lower, upper, seed)
        spec["outputs"] = [o for o, k in zip(outputs, keep, strict=True) if k]
        warn(
            f"{bodies_path}: no position operational space; outputs are the world "
            f"{''.join(o['component'] for o in spec['outputs']) or '(none)'} coordinates of "
            f"the end point of link {links[-1].num} ({links[-1].name!r})"
        )
    spec["poses"] = {
        pose_name: {d.joint_name: float(v) for d, v in zip(order, natural, strict=True)}
    }
    write_spec()
    robot = load_robot(spec_path)
    deficit = _output_rank_deficit(robot, natural, lower, upper, seed, links)
    if deficit:
        warn(f"{spec_path}: {deficit}")

    coordinates = tuple(
        f"{d.joint_name} <- link {d.link.num} {d.link.name!r} ({d.link.joint_type}) q[{d.index}]"
        for d in order
    )
    return CasprImport(
        name=model_name,
        urdf_path=urdf_path,
        spec_path=spec_path,
        cable_set=chosen_set,
        operational_set=op_set,
        n_links=len(links),
        cable_names=robot.cable_names,
        output_names=robot.output_names,
        coordinates=coordinates,
        caspr_coordinates=tuple((d.link.num, d.index) for d in order),
        pose_name=pose_name,
        pose=natural,
        warnings=tuple(collected),
    )


def _outside_limits(robot, natural: np.ndarray, lower, upper) -> list[str]:
    tol = 1e-9
    return [
        f"{n}={v:g} not in [{lo:g}, {hi:g}]"
        for n, v, lo, hi in zip(robot.coordinate_names, natural, lower, upper, strict=True)
        if not lo - tol <= v <= hi + tol
    ]


def _pose_problem(robot, natural: np.ndarray) -> str | None:
    """Why a pose has degenerate cables (a zero-length segment), or None."""
    try:
        kin = robot.kinematics(robot.from_natural(natural))
    except ModelError as exc:
        return str(exc)
    if kin.segment_lengths.size and kin.segment_lengths.min() < _MIN_SEGMENT:
        k = int(np.argmin(kin.segment_lengths))
        return (
            f"cable {robot.cable_names[kin.segment_cable[k]]!r} has a segment of length "
            f"{kin.segment_lengths[k]:.3g} m"
        )
    return None


def _sample(rng, lower, upper) -> np.ndarray:
    lo = np.where(np.isfinite(lower), lower, -1.0)
    hi = np.where(np.isfinite(upper), upper, 1.0)
    return rng.uniform(lo, hi)


def _choose_pose(robot, initial, lower, upper, seed, warn) -> tuple[str, np.ndarray]:
    """CASPR's q_initial when its cables are non-degenerate, else a sampled pose."""
    problem = _pose_problem(robot, initial)
    if problem is None:
        outside = _outside_limits(robot, initial, lower, upper)
        if outside:
            warn(
                f"CASPR q_initial lies outside the joint limits ({'; '.join(outside)}); "
                "kept as pose 'initial' as CASPR uses it"
            )
        return "initial", initial
    rng = np.random.default_rng(seed)
    for _ in range(500):
        candidate = _sample(rng, lower, upper)
        if _pose_problem(robot, candidate) is None:
            warn(
                f"CASPR q_initial {initial.tolist()} is not usable ({problem}); wrote pose "
                f"'sampled' (seed {seed}) instead"
            )
            return "sampled", candidate
    raise ModelError(
        f"CASPR q_initial is not usable ({problem}) and no pose within the joint limits "
        "with non-degenerate cables was found in 500 samples; check the model"
    )


def _output_jacobians(robot, lower, upper, seed, extra=()) -> list[np.ndarray]:
    """Output Jacobians (p, nv) at a few poses sampled within the limits
    (and at the natural coordinates ``extra``)."""
    rng = np.random.default_rng(seed)
    poses = [_sample(rng, lower, upper) for _ in range(5)] + list(extra)
    jacobians = []
    for natural in poses:
        try:
            jacobians.append(robot.output_jacobian(robot.from_natural(natural)))
        except ModelError:
            continue
    return jacobians


def _moving_components(robot, lower, upper, seed) -> list[bool]:
    """Which outputs have a nonzero Jacobian row at some of a few sampled poses."""
    moving = np.zeros(robot.n_outputs, dtype=bool)
    for jac in _output_jacobians(robot, lower, upper, seed):
        moving |= np.linalg.norm(jac, axis=1) > 1e-9
    return moving.tolist()


def _rank(matrix: np.ndarray) -> int:
    s = np.linalg.svd(matrix, compute_uv=False)
    return int(np.count_nonzero(s > 1e-9 * max(1.0, float(s[0]) if s.size else 0.0)))


#: CASPR joints that turn a link about a fixed point (three rotations).
_SPHERICAL_JOINTS = ("S_EULER_XYZ", "S_FIXED_XYZ")


def _output_rank_deficit(robot, natural, lower, upper, seed, links) -> str | None:
    """Why the outputs can never be output controllable, or None.

    With fewer independent output directions than outputs at every pose
    (rank of the output Jacobian < p), rank C [B AB ...] < p everywhere, so
    output controllability and POC are NO at every pose whatever the cables.
    """
    p = robot.n_outputs
    jacobians = _output_jacobians(robot, lower, upper, seed, extra=[natural])
    if not jacobians or p == 0:
        return None
    rank = max(_rank(jac) for jac in jacobians)
    if rank >= p:
        return None
    # a subset of `rank` outputs that the joints do move independently
    best = max(jacobians, key=_rank)
    keep: list[int] = []
    for i in range(p):
        if _rank(best[keep + [i]]) > len(keep):
            keep.append(i)
    names = robot.output_names
    why = "the joints cannot move them independently"
    spherical = [k.name for k in links if k.joint_type in _SPHERICAL_JOINTS]
    if spherical:
        why += (
            f" (link {spherical[0]!r} turns about a spherical joint: a point on it moves on a "
            "sphere and never along its radius)"
        )
    return (
        f"the {p} outputs ({', '.join(names)}) span only {rank} direction(s) at every sampled "
        f"pose: {why}. So output controllability fails and positive output controllability "
        f"is NO at every pose. Keep {rank} output(s) that move independently in the spec's "
        f"outputs (e.g. {', '.join(names[i] for i in keep)}), or give an operational space "
        f"(<name>_operational_spaces.xml) with at most {rank} independent position components"
    )
