"""Reading and validating CASPR XML: bodies, cable sets, operational spaces.

The files are read with the standard library's XML parser (nothing is
executed and no external DTD or entity is fetched) into plain records
(:class:`_Link`, :class:`_Cable`, :class:`_OpSpace`). Everything cdpm cannot
represent is refused here with an error naming the element and the file;
what is ignored is passed to ``warn``.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from defusedxml import DefusedXmlException
from defusedxml.ElementTree import fromstring

from cdpm.errors import InputError, UnsupportedError
from cdpm.model.robot import MODEL_INERTIA_NEGATIVE_RTOL

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
class _OpSpace:
    """One CASPR operational space, as the cdpm output components it becomes.

    Attributes:
        name: CASPR's ``name`` attribute (or ``op<k>``).
        tag: the CASPR element (``position``, ``orientation_euler_xyz``,
            ``pose_euler_xyz``).
        link: CASPR link number (>= 1).
        offset: the operational point from the link's joint point P, in link
            axes [m], shape (3,) (zeros for an orientation).
        components: cdpm components in CASPR's order (``x``, ``y``, ``z`` of
            the point; ``rx``, ``ry``, ``rz`` of the link frame).
        letters: CASPR's axis letter of each component (``x``, ``y``, ``z``,
            ``a``, ``b``, ``g``).
    """

    name: str
    tag: str
    link: int
    offset: np.ndarray
    components: tuple[str, ...]
    letters: tuple[str, ...]

    @property
    def has_position(self) -> bool:
        """Some component is a coordinate of the operational point."""
        return any(c in ("x", "y", "z") for c in self.components)


#: largest CASPR XML file read [bytes]
MAX_CASPR_XML_BYTES = 20_000_000


def _parse_xml(path: Path, what: str) -> ET.Element:
    """Parse a CASPR file with defusedxml: entity declarations and external
    references are refused (they can expand without bound or read files);
    the ``<!DOCTYPE ... SYSTEM "...dtd">`` line CASPR's files carry is
    allowed and not followed."""

    try:
        if not path.is_file():
            raise InputError(f"CASPR {what} file not found: {path}")
        size = path.stat().st_size
        if size > MAX_CASPR_XML_BYTES:
            raise InputError(
                f"{path}: {size:,} bytes, more than the {MAX_CASPR_XML_BYTES:,} read for a "
                f"CASPR {what} file"
            )
        text = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        return fromstring(text)
    except DefusedXmlException:
        raise InputError(
            f"{path}: declares entities or external references, which cdpm does not read "
            "because they can expand without bound or read other files; write the values out"
        ) from None
    except (ET.ParseError, LookupError, ValueError) as exc:
        # LookupError: an encoding Python does not know
        raise InputError(
            f"{path}: not well-formed XML ({exc}); expected a CASPR {what} file"
        ) from None


def _describe(element: ET.Element) -> str:
    """``<tag a="b" ...>`` of an element, for messages."""

    def short(value: str) -> str:
        return value if len(value) <= 60 else value[:57] + "..."

    attrs = " ".join(f'{short(k)}="{short(v)}"' for k, v in list(element.attrib.items())[:6])
    return f"<{short(element.tag)}{' ' + attrs if attrs else ''}>"


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
    crossed = [
        f"q_min[{i}] = {lo:g} > q_max[{i}] = {hi:g}"
        for i, (lo, hi) in enumerate(zip(bounds[0], bounds[1], strict=True))
        if lo > hi
    ]
    if crossed:
        unset = [a for a in ("q_min", "q_max") if joint.get(a) is None]
        default = f" ({unset[0]} not given: CASPR's default)" if unset else ""
        raise InputError(
            f"{path}: {jwhere}: {'; '.join(crossed)}{default}: each lower joint limit must "
            "be at most its upper one; swap or correct them"
        )
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
    moments = np.linalg.eigvalsh(inertia)
    if moments.min() < -MODEL_INERTIA_NEGATIVE_RTOL * np.abs(moments).max():
        about = " about the COM (the one given about the joint, less the mass at the COM)"
        raise InputError(
            f"{path}: {where}: its inertia{about if ref == 'joint' else ''} has a negative "
            f"principal moment ({np.array2string(moments, precision=3)} kg m^2), which no "
            "body has: check Ixx..Iyz, the mass and com_location"
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


#: CASPR's axis letters -> cdpm output components (``OperationalPosition``,
#: ``OperationalOrientationEulerXYZ``, ``OperationalPoseEulerXYZ``): a, b, g
#: select rows 4-6 of a link's world twist, the world angular velocity.
_POSITION_LETTERS = {"x": "x", "y": "y", "z": "z"}
_ORIENTATION_LETTERS = {"a": "rx", "b": "ry", "g": "rz"}
#: CASPR operational space element -> the axis letters it accepts.
OPERATIONAL_SPACE_TYPES: dict[str, dict[str, str]] = {
    "position": _POSITION_LETTERS,
    "orientation_euler_xyz": _ORIENTATION_LETTERS,
    "pose_euler_xyz": {**_POSITION_LETTERS, **_ORIENTATION_LETTERS},
}
#: ``<selection_matrix>`` children (older CASPR files), in CASPR's row order.
_SELECTION_TAGS = (("sx", "x"), ("sy", "y"), ("sz", "z"), ("sa", "a"), ("sb", "b"), ("sg", "g"))


def _selected_letters(el: ET.Element, path: Path, where: str, warn) -> str | None:
    """Axis letters of an operational space, in CASPR's order, or None when
    it names none (then ``warn`` was told why)."""
    axes_el = el.find("axes")
    axes = axes_el.get("active_axes") if axes_el is not None else None
    selection_el = el.find("selection_matrix")
    if selection_el is None:
        if axes is None:
            warn(
                f"{path}: {where}: no <axes active_axes=...> (CASPR requires it); "
                "no outputs from it"
            )
            return None
        return axes.strip().lower()
    # Older CASPR files: a diagonal <selection_matrix> of 0/1 entries that
    # selects rows of [x y z a b g] (CASPR kept the rows whose entry is nonzero).
    letters = ""
    for tag, letter in _SELECTION_TAGS:
        child = selection_el.find(tag)
        if child is None:
            continue
        value = _numbers(child.text or "", path, f"{where} <selection_matrix><{tag}>", 1)[0]
        if value not in (0.0, 1.0):
            warn(
                f"{path}: {where}: <selection_matrix><{tag}> is {value:g}; CASPR only uses "
                f"it to select the component, so {letter!r} is "
                f"{'kept with weight 1' if value else 'left out'}"
            )
        if value != 0.0:
            letters += letter
    if axes is not None and sorted(axes.strip().lower()) != sorted(letters):
        warn(
            f"{path}: {where}: active_axes {axes!r} and <selection_matrix> ({letters!r}) "
            "disagree; the selection matrix is used, as CASPR did when it read both"
        )
    return letters


def _read_operational_spaces(
    path: Path, operational_set: str | None, n_links: int, warn
) -> tuple[str | None, list[_OpSpace]]:
    """The operational spaces of one set, each with the components it keeps.

    Position letters ``x y z`` become world coordinates of the operational
    point; orientation letters ``a b g`` become the world components ``rx ry
    rz`` of the link frame's rotation vector (see docs/caspr.md for how they
    relate to CASPR's Euler angles). What cannot be kept is passed to
    ``warn`` with what was done.
    """
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
    spaces: list[_OpSpace] = []
    for el in sets[chosen]:
        if not isinstance(el.tag, str):  # comments, processing instructions
            continue
        where = f"{_describe(el)} in operational set {chosen!r}"
        accepted = OPERATIONAL_SPACE_TYPES.get(el.tag)
        if accepted is None:
            warn(
                f"{path}: {where}: operational space <{el.tag}> is not a CASPR type cdpm "
                f"can represent (known: {', '.join(OPERATIONAL_SPACE_TYPES)}); it gives no "
                "outputs. Replace it with one of those, e.g. <pose_euler_xyz> with "
                'active_axes="xyzabg" for the full pose'
            )
            continue
        letters = _selected_letters(el, path, where, warn)
        if letters is None:
            continue
        kept: list[str] = []
        for letter in letters:
            if letter not in accepted:
                warn(
                    f"{path}: {where}: axis {letter!r} is not one of <{el.tag}>'s axes "
                    f"({', '.join(accepted)}); left out"
                )
            elif letter in kept:
                warn(f"{path}: {where}: axis {letter!r} repeated; kept once")
            else:
                kept.append(letter)
        if not kept:
            warn(f"{path}: {where}: no valid axis selected; it gives no outputs")
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
            if offset_el is not None and el.tag != "orientation_euler_xyz"
            else np.zeros(3)
        )
        spaces.append(
            _OpSpace(
                name=el.get("name") or f"op{len(spaces) + 1}",
                tag=el.tag,
                link=link,
                offset=offset,
                components=tuple(accepted[a] for a in kept),
                letters=tuple(kept),
            )
        )
    return chosen, spaces
