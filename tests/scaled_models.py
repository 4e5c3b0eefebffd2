"""Geometric and mass-scaled copies of a cable robot model, for tests
that check that no decision of cdpm depends on the robot's units.

:func:`scaled_copy` writes a copy of a spec and its URDF with every mass
multiplied by ``mass`` and every length by ``length``: inertias by
mass length^2, cable attachment points, joint origins and prismatic limits
by length, the cable tension bounds and the pretension by ``mass`` (the
tensions that hold a scaled robot under the same gravity), and joint
damping and friction so that the dynamics keep their shape (time scales by
length^(1/2) under fixed gravity). Visuals and collision shapes are left
out. Coordinates in metres (prismatic joints) scale by ``length``, angles
do not: :func:`scaled_pose`.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import yaml

__all__ = ["scaled_copy", "scaled_pose", "scaled_spec"]


def _scale_attr(element, name: str, factor: float) -> None:
    value = element.get(name)
    if value is not None:
        element.set(name, " ".join(repr(float(v) * factor) for v in value.split()))


def _scaled_urdf(text: str, mass: float, length: float) -> str:
    root = ET.fromstring(text)
    for link in root.iter("link"):  # the statics need no meshes
        for part in link.findall("visual") + link.findall("collision"):
            link.remove(part)
    prismatic = {j.get("name") for j in root.iter("joint") if j.get("type") == "prismatic"}
    for origin in root.iter("origin"):
        _scale_attr(origin, "xyz", length)
    for inertial in root.iter("inertial"):
        for m in inertial.iter("mass"):
            _scale_attr(m, "value", mass)
        for inertia in inertial.iter("inertia"):
            for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                _scale_attr(inertia, key, mass * length**2)
    for geometry in root.iter("geometry"):
        for shape in geometry:
            for key in ("size", "radius", "length", "scale"):
                _scale_attr(shape, key, length)
    for joint in root.iter("joint"):
        slides = joint.get("name") in prismatic
        for limit in joint.iter("limit"):
            if slides:
                _scale_attr(limit, "lower", length)
                _scale_attr(limit, "upper", length)
            _scale_attr(limit, "effort", mass * (1.0 if slides else length))
        for dynamics in joint.iter("dynamics"):
            # force ~ mass g, speed ~ (g length)^(1/2): damping ~ mass length^-1/2
            # (prismatic) or mass length^3/2 (revolute); friction ~ the force
            _scale_attr(dynamics, "damping", mass * length ** (-0.5 if slides else 1.5))
            _scale_attr(dynamics, "friction", mass * (1.0 if slides else length))
    return ET.tostring(root, encoding="unicode")


def scaled_spec(
    data: dict, mass: float, length: float, equilibrium: dict | None, unbounded: bool
) -> dict:
    """A spec mapping (a copy) for the scaled URDF ``robot.urdf``: cable
    attachment and output points times ``length``; tension bounds times
    ``mass``, or left out (bounds [0, inf)) when ``unbounded``; the
    ``equilibrium`` mapping given (else the spec's) with its pretension times
    ``mass``; no named poses (they may hold lengths: tests give poses)."""
    spec = copy.deepcopy(data)
    spec["urdf"] = "robot.urdf"
    for cable in spec["cables"]:
        for point in cable["route"]:
            point["point"] = [float(x) * length for x in point["point"]]
        if unbounded:
            cable.pop("tension", None)
        elif "tension" in cable:
            cable["tension"] = [float(x) * mass for x in cable["tension"]]
    for output in spec.get("outputs", []):
        if "point" in output:
            output["point"] = [float(x) * length for x in output["point"]]
    eq = dict(equilibrium if equilibrium is not None else spec.get("equilibrium") or {})
    if "pretension" in eq:
        eq["pretension"] = float(eq["pretension"]) * mass
    spec["equilibrium"] = eq
    spec.pop("poses", None)
    return spec


def scaled_copy(
    spec_path: Path,
    urdf_path: Path,
    out: Path,
    mass: float,
    length: float,
    equilibrium: dict | None = None,
    unbounded: bool = False,
) -> Path:
    """Write the scaled copy of a spec (and its URDF) into folder ``out``.

    Args:
        spec_path: the spec YAML.
        urdf_path: its URDF file (resolved).
        out: folder to write into (created).
        mass, length: the factors (dimensionless).
        equilibrium: the unit robot's ``equilibrium`` mapping to use instead
            of the spec's (its pretension [N] is scaled by ``mass``).
        unbounded: leave the cables' tension bounds out ([0, inf)).

    Returns:
        The path of the scaled spec.
    """
    out.mkdir(parents=True, exist_ok=True)
    data = yaml.safe_load(Path(spec_path).read_text())
    (out / "robot.urdf").write_text(_scaled_urdf(Path(urdf_path).read_text(), mass, length))
    path = out / "robot.yaml"
    spec = scaled_spec(data, mass, length, equilibrium, unbounded)
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def scaled_pose(robot, q: np.ndarray, length: float) -> np.ndarray:
    """Natural coordinates q (nv,) of the unit robot at the scaled one:
    metres (prismatic coordinates) times ``length``, angles unchanged."""
    from cdpm.model.coordinates import coordinate_units

    units = coordinate_units(robot.model)
    return np.array([v * length if u == "m" else v for v, u in zip(q, units, strict=True)])
