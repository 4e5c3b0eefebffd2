"""Configuration vectors and the coordinates users type.

Pinocchio's configuration vector q has ``nq`` entries and its tangent
(velocity) space ``nv``; they differ for joints with a quaternion or a
(cos, sin) pair. Users think in *natural coordinates*: one value per degree
of freedom, ``nv`` in all:

=================  ==========================  ======================
joint              natural coordinates          q entries
=================  ==========================  ======================
revolute, prismatic  angle [rad] or offset [m]    same value
continuous         angle [rad]                  (cos, sin)
spherical          roll, pitch, yaw [rad]       quaternion (x, y, z, w)
planar             x, y [m], theta [rad]        (x, y, cos, sin)
free-flyer         x, y, z [m], roll, pitch,    (x, y, z, qx, qy, qz, qw)
                   yaw [rad] (ZYX Euler)
=================  ==========================  ======================

This module converts between the two without touching the robot layer, so
specs, the CLI and maps share one definition.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from cdpm.errors import InputError, float_array
from cdpm.expressions import parse_number
from cdpm.numerics import CONFIGURATION_UNIT_NORM_TOL

__all__ = [
    "ConfigurationError",
    "coordinate_names",
    "coordinate_units",
    "configuration_from_values",
    "configuration_from_natural",
    "natural_from_configuration",
    "as_configuration",
]


class ConfigurationError(InputError):
    """A configuration given by the user does not fit the model."""


#: largest magnitude of a coordinate [rad or m] (the lengths cdpm analyses
#: are bounded alike: :data:`cdpm.model.robot.MAX_MODEL_LENGTH`)
MAX_COORDINATE = 1e5


def _check_magnitudes(values: np.ndarray, name: str) -> None:
    """Refuse non-finite coordinates and magnitudes above MAX_COORDINATE."""
    bad = ~(np.abs(values) <= MAX_COORDINATE)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ConfigurationError(
            f"{name}[{k}] = {values[k]:g}: coordinates must be finite numbers of at most "
            f"{MAX_COORDINATE:g} (rad or m)"
        )


def _joints(model):
    """(name, joint model) of every joint but the universe."""
    return [(model.names[j], model.joints[j]) for j in range(1, model.njoints)]


def _kind(joint) -> str:
    name = joint.shortname()
    if name == "JointModelFreeFlyer":
        return "freeflyer"
    if name == "JointModelSpherical":
        return "spherical"
    if name == "JointModelPlanar":
        return "planar"
    if name.startswith("JointModelRUB"):
        return "continuous"
    if joint.nq == joint.nv:
        return "euclidean"
    raise ConfigurationError(f"joint type {name} is not supported in natural coordinates")


def coordinate_names(model) -> list[str]:
    """Names of the ``nv`` natural coordinates, in tangent-space order.

    One-DOF joints give their joint name; multi-DOF joints give
    ``joint.x``, ``joint.roll`` etc.
    """
    names: list[str] = []
    suffixes = {
        "freeflyer": ("x", "y", "z", "roll", "pitch", "yaw"),
        "spherical": ("roll", "pitch", "yaw"),
        "planar": ("x", "y", "theta"),
    }
    for jname, joint in _joints(model):
        kind = _kind(joint)
        if kind in suffixes:
            names.extend(f"{jname}.{s}" for s in suffixes[kind])
        elif joint.nv == 1:
            names.append(jname)
        else:
            names.extend(f"{jname}.{k}" for k in range(joint.nv))
    return names


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


#: the components of a multi-DOF joint's tangent displacement and of its
#: velocity, in Pinocchio's order and in the joint's own frame:
#: translations d_x [m] with velocities v_x [m/s], rotations th_x [rad]
#: (a rotation vector) with angular velocities w_x [rad/s]
_LOCAL_TANGENT = {
    "freeflyer": (
        ("d_x", "d_y", "d_z", "th_x", "th_y", "th_z"),
        ("v_x", "v_y", "v_z", "w_x", "w_y", "w_z"),
    ),
    "spherical": (("th_x", "th_y", "th_z"), ("w_x", "w_y", "w_z")),
    "planar": (("d_x", "d_y", "th_z"), ("v_x", "v_y", "w_z")),
}


def velocity_names(model) -> list[str]:
    """Names of the ``nv`` components of a velocity (Pinocchio's ``v``), in
    order: ``name_dot`` where ``v`` is the rate of a natural coordinate
    (joints of one degree of freedom, and joints whose configuration is a
    vector); for a free-flyer ``joint.v_x``, ``v_y``, ``v_z`` (linear)
    and ``joint.w_x``, ``w_y``, ``w_z`` (angular), for a planar joint
    ``joint.v_x``, ``v_y``, ``w_z``, for a spherical one ``joint.w_x``,
    ``w_y``, ``w_z``: the body's velocity in its own frame, not the rates
    of its x, y, z and roll, pitch, yaw."""
    return _tangent_names(model, 1, "_dot")


def displacement_names(model) -> list[str]:
    """Names of the ``nv`` components of a tangent displacement ``dq``
    (``q = pin.integrate(q0, dq)``), in order: the natural coordinate's
    name where ``dq`` is its change (as for :func:`velocity_names`); for a
    free-flyer ``joint.d_x``, ``d_y``, ``d_z`` (translation) and
    ``joint.th_x``, ``th_y``, ``th_z`` (rotation vector), for a planar joint
    ``joint.d_x``, ``d_y``, ``th_z``, for a spherical one ``joint.th_x``,
    ``th_y``, ``th_z``: in the body's own frame, not changes of its x, y, z
    and roll, pitch, yaw."""
    return _tangent_names(model, 0, "")


def _tangent_names(model, which: int, suffix: str) -> list[str]:
    """:func:`displacement_names` (``which`` 0) or :func:`velocity_names`
    (1, ``suffix`` "_dot" on natural coordinates' names)."""
    names: list[str] = []
    start = 0
    coords = coordinate_names(model)
    for jname, joint in _joints(model):
        kind = _kind(joint)
        if kind in _LOCAL_TANGENT:
            names.extend(f"{jname}.{s}" for s in _LOCAL_TANGENT[kind][which])
        else:
            names.extend(f"{c}{suffix}" for c in coords[start : start + joint.nv])
        start += joint.nv
    return names


def _rpy_to_quaternion(rpy: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    rotation = pin.rpy.rpyToMatrix(*rpy)
    return pin.Quaternion(rotation).coeffs().copy()  # (x, y, z, w)


def _quaternion_to_rpy(quat: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    x, y, z, w = quat
    return np.array(pin.rpy.matrixToRpy(pin.Quaternion(w, x, y, z).toRotationMatrix()))


def configuration_from_natural(model, natural: Any) -> np.ndarray:
    """Configuration vector q (nq,) from natural coordinates (nv,)."""
    try:
        values = float_array(natural).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"natural coordinates must be a vector of numbers: {exc}") from exc
    _check_magnitudes(values, "natural coordinates")
    if values.shape[0] != model.nv:
        raise ConfigurationError(
            f"got {values.shape[0]} natural coordinates, expected nv={model.nv} "
            f"({', '.join(coordinate_names(model))})"
        )
    q = np.zeros(model.nq)
    for jname, joint in _joints(model):
        iq, iv = joint.idx_q, joint.idx_v
        part = values[iv : iv + joint.nv]
        q[iq : iq + joint.nq] = _joint_q_from_natural(jname, joint, part)
    return q


def _joint_q_from_natural(jname: str, joint, part: np.ndarray) -> np.ndarray:
    kind = _kind(joint)
    if kind == "euclidean":
        return part
    if kind == "continuous":
        return np.array([np.cos(part[0]), np.sin(part[0])])
    if kind == "spherical":
        return _rpy_to_quaternion(part)
    if kind == "planar":
        return np.array([part[0], part[1], np.cos(part[2]), np.sin(part[2])])
    if kind == "freeflyer":
        return np.concatenate([part[:3], _rpy_to_quaternion(part[3:6])])
    raise ConfigurationError(f"joint {jname!r}: unsupported joint type")  # pragma: no cover


def natural_from_configuration(model, q: Any) -> np.ndarray:
    """Natural coordinates (nv,) of a configuration vector q (nq,)."""
    q = as_configuration(model, q)
    out = np.zeros(model.nv)
    for _jname, joint in _joints(model):
        iq, iv = joint.idx_q, joint.idx_v
        part = q[iq : iq + joint.nq]
        kind = _kind(joint)
        if kind == "euclidean":
            value = part
        elif kind == "continuous":
            value = [np.arctan2(part[1], part[0])]
        elif kind == "spherical":
            value = _quaternion_to_rpy(part)
        elif kind == "planar":
            value = [part[0], part[1], np.arctan2(part[3], part[2])]
        else:  # freeflyer
            value = np.concatenate([part[:3], _quaternion_to_rpy(part[3:7])])
        out[iv : iv + joint.nv] = value
    return out


def as_configuration(model, q: Any, name: str = "q") -> np.ndarray:
    """Validate a configuration vector: float array of shape (nq,), finite,
    unit quaternions and (cos, sin) pairs (normalised when within 1e-6).

    Also accepts natural coordinates (nv values) when nq != nv.

    Raises:
        ConfigurationError: wrong length, non-finite or non-unit entries.
    """
    try:
        arr = float_array(q, copy=True).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{name} must be a vector of numbers: {exc}") from exc
    _check_magnitudes(arr, name)
    if arr.shape[0] != model.nq:
        if arr.shape[0] == model.nv:
            return configuration_from_natural(model, arr)
        raise ConfigurationError(
            f"{name} has {arr.shape[0]} entries, expected nq={model.nq} "
            f"(configuration vector) or nv={model.nv} natural coordinates "
            f"({', '.join(coordinate_names(model))})"
        )
    if model.nq != model.nv:
        for jname, joint in _joints(model):
            kind = _kind(joint)
            if kind == "euclidean":
                continue
            sl = {
                "continuous": slice(0, 2),
                "planar": slice(2, 4),
                "spherical": slice(0, 4),
                "freeflyer": slice(3, 7),
            }[kind]
            seg = arr[joint.idx_q : joint.idx_q + joint.nq][sl]
            norm = float(np.linalg.norm(seg))
            if abs(norm - 1.0) > CONFIGURATION_UNIT_NORM_TOL:
                what = "quaternion" if sl.stop - sl.start == 4 else "(cos, sin) pair"
                raise ConfigurationError(
                    f"{name}: joint {jname!r} needs a unit {what}, "
                    f"got norm {norm:.6g}; pass natural coordinates "
                    f"({', '.join(coordinate_names(model))}) to avoid this"
                )
            start = joint.idx_q + sl.start
            arr[start : start + (sl.stop - sl.start)] = seg / norm
    return arr


def configuration_from_values(model, value: Any) -> np.ndarray:
    """Configuration vector from a spec or CLI value.

    Args:
        model: the Pinocchio model.
        value: a list of nq numbers (configuration vector), a list of nv
            natural coordinates, or a mapping ``{joint name or coordinate
            name: value(s)}``; coordinates not named stay at zero (neutral).
            Numbers may be arithmetic strings such as ``"pi/6"``.

    Raises:
        ConfigurationError: the value does not fit the model.
    """

    def number(x: Any, where: str) -> float:
        try:
            return parse_number(x)
        except ValueError as exc:
            raise ConfigurationError(f"{where}: {exc}") from exc

    if isinstance(value, Mapping):
        names = coordinate_names(model)
        natural = np.zeros(model.nv)
        joint_names = {jname: joint for jname, joint in _joints(model)}
        for key, item in value.items():
            if key in joint_names:
                joint = joint_names[key]
                if isinstance(item, np.ndarray):
                    items = list(item.reshape(-1))
                else:
                    items = list(item) if isinstance(item, (list, tuple)) else [item]
                if len(items) != joint.nv:
                    raise ConfigurationError(
                        f"joint {key!r} takes {joint.nv} natural coordinate(s), got {len(items)}"
                    )
                for k, x in enumerate(items):
                    natural[joint.idx_v + k] = number(x, f"{key}[{k}]" if joint.nv > 1 else key)
            elif key in names:
                natural[names.index(key)] = number(item, str(key))
            else:
                raise ConfigurationError(
                    f"{key!r} is not a joint or coordinate; valid: {', '.join(names)}"
                )
        return configuration_from_natural(model, natural)
    if isinstance(value, (list, tuple, np.ndarray)):
        numbers = [number(x, f"[{k}]") for k, x in enumerate(value)]
        return as_configuration(model, numbers)
    raise ConfigurationError(
        f"expected a list of {model.nq} numbers or a mapping joint -> value, got {value!r}"
    )
