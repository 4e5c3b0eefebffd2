"""URDF files read safely and checked before Pinocchio builds a model.

The URDF is parsed with :mod:`defusedxml` (no entity declarations or
external references: they can expand without bound or read other files), and every
number Pinocchio would read (origins, masses, inertias, axes, limits,
dynamics) is checked to be finite and of the right length, so a broken file
gives a :class:`~cdpm.errors.SpecError` that names the element instead of
an exception from inside Pinocchio or a linear-algebra failure later.
"""

from __future__ import annotations

import math
from pathlib import Path

__all__ = ["read_urdf", "MAX_URDF_BYTES", "MAX_URDF_LINKS"]

#: largest URDF file read [bytes]
MAX_URDF_BYTES = 50_000_000

#: most links a URDF may have
MAX_URDF_LINKS = 1000

# element -> {attribute: number of values}; all values must be finite
_NUMBERS = {
    "origin": {"xyz": 3, "rpy": 3},
    "mass": {"value": 1},
    "inertia": {a: 1 for a in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")},
    "axis": {"xyz": 3},
    "limit": {"lower": 1, "upper": 1, "effort": 1, "velocity": 1},
    "dynamics": {"damping": 1, "friction": 1},
}


def read_urdf(path: Path):
    """Parse and check a URDF file.

    Args:
        path: the URDF file.

    Returns:
        (root, problems): the ``<robot>`` element (None when the file could
        not be parsed) and one line per problem found (empty when the file
        is fit for Pinocchio).
    """
    # defusedxml: loaded on first use
    from defusedxml import DefusedXmlException
    from defusedxml.ElementTree import ParseError, fromstring

    try:
        size = path.stat().st_size
        if size > MAX_URDF_BYTES:
            return None, [f"the file has {size:,} bytes, more than the {MAX_URDF_BYTES:,} read"]
        text = path.read_bytes()
    except OSError as exc:
        return None, [f"cannot read {path}: {exc.strerror or exc}"]
    try:
        root = fromstring(text)
    except DefusedXmlException:
        return None, [
            f"{path.name} declares entities or external references (in <!DOCTYPE ...>), "
            "which cdpm does not read because they can expand without bound or read other "
            "files; remove them and write the values out"
        ]
    except (ParseError, LookupError, ValueError) as exc:  # LookupError: unknown encoding
        return None, [f"{path.name} is not well-formed XML: {exc}"]
    if root.tag != "robot":
        return None, [f"{path.name}: the root element is <{root.tag}>, expected <robot>"]
    problems = []
    links = root.findall("link")
    if len(links) > MAX_URDF_LINKS:
        problems.append(f"{len(links)} links, more than the {MAX_URDF_LINKS} cdpm reads")
        return root, problems
    for parent in root:
        name = parent.get("name", "?")
        for element in parent.iter():
            wanted = _NUMBERS.get(element.tag)
            if wanted is None:
                continue
            for attribute, count in wanted.items():
                raw = element.get(attribute)
                if raw is None:
                    continue
                problem = _number_problem(raw, count)
                if problem:
                    problems.append(
                        f"<{parent.tag} name={name!r}> <{element.tag} {attribute}={raw[:40]!r}>: "
                        f"{problem}"
                    )
    return root, problems


def _number_problem(raw: str, count: int) -> str:
    """What is wrong with an attribute that should hold ``count`` finite
    numbers ("" when nothing)."""
    parts = raw.split()
    if len(parts) != count:
        return f"expected {count} number{'s' if count > 1 else ''}, got {len(parts)}"
    try:
        values = [float(p) for p in parts]
    except ValueError:
        return "not a number"
    if not all(math.isfinite(v) for v in values):
        return "values must be finite"
    return ""
