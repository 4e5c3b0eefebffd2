"""Slider ranges and units of a robot's natural coordinates.

:func:`coordinate_sliders` gives, for each natural coordinate, its range
(from the URDF joint limits, else a default) and its unit; the notebook
sliders of :class:`cdpm.viewer.PoseInspector` and the inspection page of
``cdpm view`` (:mod:`cdpm.viewer.page`) both use it. No optional dependency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover - for static type checkers only
    from cdpm.model.robot import CableRobot

__all__ = ["CoordinateRange", "coordinate_sliders", "coordinate_ranges"]


@dataclass(frozen=True)
class CoordinateRange:
    """Slider of one natural coordinate.

    Attributes:
        name: the coordinate's name (``robot.coordinate_names``).
        low, high: the range [rad or m]; it contains ``value``.
        unit: ``"rad"`` (an angle) or ``"m"`` (a length).
        value: the coordinate's current value [rad or m].
    """

    name: str
    low: float
    high: float
    unit: str
    value: float


def coordinate_sliders(robot: CableRobot, natural: Any = None) -> tuple[CoordinateRange, ...]:
    """Range and unit of each natural coordinate, from the URDF joint limits.

    Finite limits (``robot.model.lowerPositionLimit``/``upperPositionLimit``)
    are used as they are; an angle without them gets [-pi, pi] (pitch of a
    ball joint or free flyer [-pi/2, pi/2]); a length without them gets the
    current value +- 1 m. A free flyer's position (x, y, z) is a length, its
    roll, pitch and yaw are angles. The range always contains the current value.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        natural: current natural coordinates (nv,) [rad or m], a configuration
            (nq,) or a pose name; default the neutral pose.

    Returns:
        One :class:`CoordinateRange` per coordinate, in the order of
        ``robot.coordinate_names``.
    """
    model = robot.model
    natural = robot.to_natural(robot.neutral() if natural is None else robot.as_q(natural))
    lower, upper = np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)
    names = list(robot.coordinate_names)
    sliders: list[CoordinateRange] = []
    for j in range(1, model.njoints):
        joint = model.joints[j]
        kind = joint.shortname()
        for k in range(joint.nv):
            iv = joint.idx_v + k
            name = names[iv]
            suffix = name.rsplit(".", 1)[-1] if "." in name else ""
            # JointModelPX/PY/PZ/PrismaticUnaligned, Translation: lengths
            prismatic = kind.startswith(("JointModelP", "JointModelTranslation"))
            is_length = (joint.nq == joint.nv and prismatic) or (
                joint.nq != joint.nv and suffix in ("x", "y", "z")
            )
            if joint.nq == joint.nv or is_length:
                lo, hi = float(lower[joint.idx_q + k]), float(upper[joint.idx_q + k])
            else:
                lo, hi = -math.inf, math.inf
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                if is_length:
                    lo, hi = natural[iv] - 1.0, natural[iv] + 1.0
                elif suffix == "pitch":
                    lo, hi = -math.pi / 2, math.pi / 2
                else:
                    lo, hi = -math.pi, math.pi
            value = float(natural[iv])
            sliders.append(
                CoordinateRange(
                    name=name,
                    low=min(lo, value),
                    high=max(hi, value),
                    unit="m" if is_length else "rad",
                    value=value,
                )
            )
    return tuple(sliders)


def coordinate_ranges(robot: CableRobot, natural: Any = None) -> dict[str, tuple[float, float]]:
    """Slider range of each natural coordinate (see :func:`coordinate_sliders`).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        natural: current natural coordinates (nv,); default the neutral pose.

    Returns:
        ``{coordinate name: (low, high)}`` [rad or m] in the order of
        ``robot.coordinate_names``.
    """
    return {s.name: (s.low, s.high) for s in coordinate_sliders(robot, natural)}
