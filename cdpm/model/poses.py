"""Batched helpers for maps: configurations from natural coordinates.

Everything here works on a whole chunk of poses at once with array
arithmetic; the rigid-body quantities themselves come from Pinocchio
through :meth:`cdpm.model.robot.CableRobot.kinematics_batch`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from cdpm.errors import InputError, float_array
from cdpm.expressions import parse_number
from cdpm.model.coordinates import MAX_COORDINATE, joint_kind

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = ["configurations"]


def _rpy_quaternions(rpy: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) of ZYX Euler angles (roll, pitch, yaw)
    (N, 3) [rad]: the rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` of
    ``pinocchio.rpy.rpyToMatrix``, shape (N, 4)."""
    half = 0.5 * rpy
    c, s = np.cos(half), np.sin(half)
    cr, cp, cy = c[:, 0], c[:, 1], c[:, 2]
    sr, sp, sy = s[:, 0], s[:, 1], s[:, 2]
    return np.stack(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ],
        axis=1,
    )


def configurations(robot: CableRobot, natural: np.ndarray) -> np.ndarray:
    """Configuration vectors (N, nq) of natural coordinates (N, nv), the
    batched :meth:`cdpm.model.robot.CableRobot.from_natural` (quaternions may
    differ in sign, which is the same rotation)."""
    model = robot.model
    natural = np.asarray(natural, dtype=float).reshape(-1, robot.nv)
    if robot.nq == robot.nv and all(
        joint_kind(model.joints[j]) == "euclidean" for j in range(1, model.njoints)
    ):
        return natural
    qs = np.empty((natural.shape[0], robot.nq))
    for j in range(1, model.njoints):
        joint = model.joints[j]
        iq, iv, kind = joint.idx_q, joint.idx_v, joint_kind(joint)
        part = natural[:, iv : iv + joint.nv]
        if kind == "euclidean":
            qs[:, iq : iq + joint.nq] = part
        elif kind == "continuous":
            qs[:, iq], qs[:, iq + 1] = np.cos(part[:, 0]), np.sin(part[:, 0])
        elif kind == "planar":
            qs[:, iq : iq + 2] = part[:, :2]
            qs[:, iq + 2], qs[:, iq + 3] = np.cos(part[:, 2]), np.sin(part[:, 2])
        elif kind == "spherical":
            qs[:, iq : iq + 4] = _rpy_quaternions(part)
        else:  # freeflyer: position, then the quaternion of roll, pitch, yaw
            qs[:, iq : iq + 3] = part[:, :3]
            qs[:, iq + 3 : iq + 7] = _rpy_quaternions(part[:, 3:6])
    return qs


def check_poses(robot: CableRobot, natural) -> np.ndarray:
    """Poses as a float array (N, nv) of finite natural coordinates, or an
    InputError naming the expected shape. ``natural``: an array (N, nv) or
    (nv,); or poses one by one, each natural coordinates (nv,), a pose name
    of the spec or ``{coordinate: value}`` (coordinates not named are 0, as
    in a spec's poses); or one pose name or mapping alone."""

    def named(pose) -> bool:  # a pose name or mapping, not a number such as "pi/6"
        if isinstance(pose, Mapping):
            return True
        if not isinstance(pose, str):
            return False
        try:
            parse_number(pose)
        except ValueError:
            return True
        return False

    if isinstance(natural, np.ndarray) and natural.dtype.kind == "U":
        natural = natural.tolist()  # names or numbers as numpy strings
    if named(natural):
        natural = [natural]
    if isinstance(natural, (list, tuple)) and any(named(pose) for pose in natural):
        rows = []
        for i, pose in enumerate(natural):
            if named(pose):
                try:
                    pose = robot.to_natural(robot.as_q(pose))
                except InputError as exc:
                    raise InputError(f"pose {i}: {exc}") from None
            rows.append(pose)
        natural = rows
    try:
        arr = float_array(natural)
    except (TypeError, ValueError) as exc:
        raise InputError(f"poses must be numbers (natural coordinates): {exc}") from exc
    if arr.ndim == 1 and arr.size == robot.nv:
        arr = arr[None]
    elif arr.shape == (0,):  # no poses, as a list
        arr = arr.reshape(0, robot.nv)
    if arr.ndim != 2 or arr.shape[1] != robot.nv:
        raise InputError(
            f"poses must have shape (N, {robot.nv}) (natural coordinates "
            f"{', '.join(robot.coordinate_names)}), got shape {arr.shape}"
        )
    within = np.abs(arr) <= MAX_COORDINATE  # False for nan and inf too: one pass
    if not within.all():
        if not np.all(np.isfinite(arr)):
            bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
            raise InputError(f"poses {bad[:5].tolist()} have non-finite coordinates")
        bad = np.flatnonzero(~within.all(axis=1))
        raise InputError(
            f"poses {bad[:5].tolist()} have coordinates of magnitude above {MAX_COORDINATE:g} "
            "(rad or m); give coordinates within it"
        )
    return arr
