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

This module is the one home of the coordinates: their names
(:func:`coordinate_names`), the kind of each joint (:func:`joint_kind`),
their units (:func:`coordinate_units`), URDF limits
(:func:`coordinate_limits`) and default ranges (:func:`default_ranges`, the
search box of ``cdpm find`` and the viewer's sliders), and the conversions
between natural coordinates and configurations, so specs, the CLI, maps,
regions, simulation and the viewer share one definition. Only
:func:`default_ranges` needs the robot (its poses and anchor points); the
rest take the Pinocchio model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cdpm.errors import InputError, float_array
from cdpm.expressions import parse_number
from cdpm.model.outputs import anchor_in_joint
from cdpm.numerics import CONFIGURATION_UNIT_NORM_TOL

__all__ = [
    "ConfigurationError",
    "JOINT_KINDS",
    "joint_kind",
    "coordinate_names",
    "coordinate_units",
    "coordinate_limits",
    "DefaultRanges",
    "default_ranges",
    "RANGE_REASONS",
    "TRANSLATION_HALF_SPAN",
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


#: what :func:`joint_kind` calls each kind of joint, by how its natural
#: coordinates (nv) sit in its q entries (nq): ``"euclidean"`` q = natural
#: (revolute, prismatic, translation, any joint with nq = nv);
#: ``"continuous"`` an angle as (cos, sin); ``"spherical"`` roll, pitch, yaw as
#: a quaternion; ``"planar"`` x, y, theta as (x, y, cos, sin); ``"freeflyer"``
#: x, y, z, roll, pitch, yaw as a position and a quaternion
JOINT_KINDS = ("euclidean", "continuous", "spherical", "planar", "freeflyer")

#: the translations among a multi-DOF joint's natural coordinates: the first
#: this many (x, y, z of a free flyer; x, y of a planar joint) [m]
_TRANSLATIONS = {"freeflyer": 3, "planar": 2}

#: index of the pitch among a joint's natural coordinates (roll, pitch, yaw)
_PITCH = {"freeflyer": 4, "spherical": 1}


def joint_kind(joint) -> str:
    """The kind of a Pinocchio joint model (one of :data:`JOINT_KINDS`): how
    its natural coordinates map to its configuration entries.

    Args:
        joint: a Pinocchio ``JointModel`` (``model.joints[j]``).

    Raises:
        ConfigurationError: a joint type whose q cannot be written in natural
            coordinates (nq != nv and not one of the kinds above).
    """
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


def _is_translation(joint, k: int) -> bool:
    """Whether the joint's k-th natural coordinate is a length [m] (else an
    angle [rad]): x, y, z of a free flyer, x, y of a planar joint, every
    coordinate of a prismatic or translation joint."""
    kind = joint_kind(joint)
    if kind in _TRANSLATIONS:
        return k < _TRANSLATIONS[kind]
    name = joint.shortname()
    prismatic = name.startswith("JointModelP") or name == "JointModelTranslation"
    return kind == "euclidean" and prismatic  # JointModelPX/PY/PZ/PrismaticUnaligned


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
        kind = joint_kind(joint)
        if kind in suffixes:
            names.extend(f"{jname}.{s}" for s in suffixes[kind])
        elif joint.nv == 1:
            names.append(jname)
        else:
            names.extend(f"{jname}.{k}" for k in range(joint.nv))
    return names


def coordinate_units(model) -> list[str]:
    """Unit of each of the ``nv`` natural coordinates, in the order of
    :func:`coordinate_names`: ``"m"`` for translations (prismatic and
    translation joints, a free flyer's x, y, z, a planar joint's x, y),
    ``"rad"`` for angles."""
    return [
        "m" if _is_translation(joint, k) else "rad"
        for _jname, joint in _joints(model)
        for k in range(joint.nv)
    ]


def coordinate_limits(model) -> tuple[np.ndarray, np.ndarray]:
    """The URDF position limits of each natural coordinate, as Pinocchio
    holds them (``model.lowerPositionLimit``/``upperPositionLimit``).

    Args:
        model: the Pinocchio model.

    Returns:
        (lower, upper), each shape (nv,) [rad or m], in the order of
        :func:`coordinate_names`; -inf and +inf where a coordinate has no
        limit in natural coordinates: the angles of continuous, spherical,
        planar and free-flyer joints (their q entries are a (cos, sin) pair
        or a quaternion). Values are as the URDF gives them: they may be
        equal, or huge where the URDF means "no limit"
        (:func:`default_ranges` tells which are usable).
    """
    limits_q = np.array([model.lowerPositionLimit, model.upperPositionLimit], dtype=float)
    limits = np.array([np.full(model.nv, -np.inf), np.full(model.nv, np.inf)])
    for _jname, joint in _joints(model):
        kind = joint_kind(joint)
        count = joint.nv if kind == "euclidean" else _TRANSLATIONS.get(kind, 0)
        iq, iv = joint.idx_q, joint.idx_v
        limits[:, iv : iv + count] = limits_q[:, iq : iq + count]
    return limits[0], limits[1]


#: half-width [m] of the default range of a translation without usable URDF
#: limits (and not a world-aligned free flyer's or planar joint's x, y, z),
#: either side of its value at the reference pose (:func:`default_ranges`)
TRANSLATION_HALF_SPAN = 1.0

#: narrowest box of fixed anchor points [m] along an axis that
#: :func:`default_ranges` uses (anchors in one plane leave that axis to the
#: +-1 m rule)
ANCHOR_BOX_MIN_WIDTH = 1e-9


#: why a coordinate got its default range (:attr:`DefaultRanges.reasons`)
RANGE_REASONS = {
    "limits": "URDF limits",
    "turn": "one turn",
    "pitch": "half a turn (a pitch of roll, pitch, yaw)",
    "anchors": "the box of the anchor points fixed to the world",
    "reference": f"+-{TRANSLATION_HALF_SPAN:g} m around the reference pose",
}


@dataclass(frozen=True)
class DefaultRanges:
    """The default range of each natural coordinate (:func:`default_ranges`).

    Attributes:
        names: the nv coordinate names (:func:`coordinate_names`).
        low, high: the range of each coordinate [rad or m], shape (nv,)
            each, ``low < high``; read-only.
        units: ``"rad"`` or ``"m"`` per coordinate (:func:`coordinate_units`).
        limited: shape (nv,) bool, read-only: the range is the URDF's limits.
        reasons: why each coordinate got its range (a value of
            :data:`RANGE_REASONS`).
    """

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    units: tuple[str, ...]
    limited: np.ndarray
    reasons: tuple[str, ...]

    def as_dict(self) -> dict[str, tuple[float, float]]:
        """``{coordinate name: (low, high)}`` [rad or m], in the robot's order."""
        return {
            n: (float(lo), float(hi))
            for n, lo, hi in zip(self.names, self.low, self.high, strict=True)
        }

    def __str__(self) -> str:
        rows = zip(self.names, self.low, self.high, self.units, self.reasons, strict=True)
        return "\n".join(
            f"{n} [{lo:.4g}, {hi:.4g}] {unit} ({why})" for n, lo, hi, unit, why in rows
        )


def default_ranges(robot: Any, reference: Any = None) -> DefaultRanges:
    """Where each natural coordinate of ``robot`` ranges by default: the
    one rule of ``cdpm find``'s search box and the viewer's sliders.

    - The URDF's limits (:func:`coordinate_limits`) when both are finite,
      ``low < high`` and within +-:data:`MAX_COORDINATE` (larger values mean
      "no limit").
    - Else an angle gets one turn [-pi, pi]; the pitch of a spherical joint
      or free flyer (roll, pitch, yaw) half a turn [-pi/2, pi/2].
    - Else a free flyer's x, y, z or a planar joint's x, y, when the joint
      hangs from the world with its axes along the world's, gets the box of
      the cables' route points fixed to the world along that axis (where
      the platform of a cable robot can be), when it has a width.
    - Else a length gets its value at ``reference`` +-
      :data:`TRANSLATION_HALF_SPAN` m.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` (typed ``Any``: the
            robot module imports this one).
        reference: the pose the +-1 m spans are centred on: a pose name, a
            configuration (nq,) or natural coordinates (nv,); default the
            spec's first pose, else the neutral configuration.

    Returns:
        :class:`DefaultRanges`, in the order of ``robot.coordinate_names``.

    Raises:
        InputError: ``reference`` is not a pose of the robot.
    """
    model = robot.model
    if reference is None:
        reference = next(iter(robot.poses.values())) if robot.poses else robot.neutral()
    natural = robot.to_natural(robot.as_q(reference))
    lower, upper = coordinate_limits(model)
    anchors = _fixed_anchors(robot)
    low, high = np.empty(model.nv), np.empty(model.nv)
    whys: list[str] = []
    for j, (_jname, joint) in enumerate(_joints(model), start=1):
        kind = joint_kind(joint)
        for k in range(joint.nv):
            iv = joint.idx_v + k
            lo, hi = lower[iv], upper[iv]
            if -MAX_COORDINATE <= lo < hi <= MAX_COORDINATE:
                why = "limits"
            elif not _is_translation(joint, k):
                why = "pitch" if _PITCH.get(kind) == k else "turn"
                lo, hi = (-math.pi / 2, math.pi / 2) if why == "pitch" else (-math.pi, math.pi)
            else:
                why = "reference"
                lo, hi = natural[iv] - TRANSLATION_HALF_SPAN, natural[iv] + TRANSLATION_HALF_SPAN
                offset = _world_aligned_offset(model, j) if kind in _TRANSLATIONS else None
                if offset is not None and anchors.size:
                    a_lo, a_hi = anchors[:, k].min() - offset[k], anchors[:, k].max() - offset[k]
                    if a_hi - a_lo >= ANCHOR_BOX_MIN_WIDTH:
                        why, lo, hi = "anchors", a_lo, a_hi
            low[iv], high[iv] = lo, hi
            whys.append(why)
    limited = np.array([why == "limits" for why in whys], dtype=bool)
    for array in (low, high, limited):
        array.setflags(write=False)
    return DefaultRanges(
        names=tuple(coordinate_names(model)),
        low=low,
        high=high,
        units=tuple(coordinate_units(model)),
        limited=limited,
        reasons=tuple(RANGE_REASONS[why] for why in whys),
    )


def _fixed_anchors(robot: Any) -> np.ndarray:
    """World positions (k, 3) [m] of the cables' route points fixed to the
    world (on a frame of the world's joint 0), in the order of the spec."""

    fixed = []
    for cable in robot.spec.cables:
        for point in cable.route:
            joint, position = anchor_in_joint(
                robot.model, point.frame, np.asarray(point.point_in_frame, dtype=float)
            )
            if joint == 0:
                fixed.append(position)
    return np.array(fixed, dtype=float).reshape(-1, 3)


def _world_aligned_offset(model, j: int) -> np.ndarray | None:
    """The world position (3,) [m] of joint j's origin at zero translation,
    when the joint hangs from the world with its axes along the world's
    (its x, y, z are then world x, y, z less this offset); else None."""
    placement = model.jointPlacements[j]
    if model.parents[j] != 0 or not np.allclose(placement.rotation, np.eye(3), rtol=0, atol=1e-12):
        return None
    return np.asarray(placement.translation, dtype=float)


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
        kind = joint_kind(joint)
        if kind in _LOCAL_TANGENT:
            names.extend(f"{jname}.{s}" for s in _LOCAL_TANGENT[kind][which])
        else:
            names.extend(f"{c}{suffix}" for c in coords[start : start + joint.nv])
        start += joint.nv
    return names


def _rpy_to_quaternion(rpy: np.ndarray) -> np.ndarray:
    # pinocchio: loaded on first use
    import pinocchio as pin

    rotation = pin.rpy.rpyToMatrix(*rpy)
    return pin.Quaternion(rotation).coeffs().copy()  # (x, y, z, w)


def _quaternion_to_rpy(quat: np.ndarray) -> np.ndarray:
    # pinocchio: loaded on first use
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
    kind = joint_kind(joint)
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
        kind = joint_kind(joint)
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
            kind = joint_kind(joint)
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
