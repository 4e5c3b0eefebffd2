"""Slider ranges and units of a robot's natural coordinates.

:func:`coordinate_sliders` gives, for each natural coordinate, its range
(its default range, :func:`cdpm.model.coordinates.default_ranges`, holding
the current value) and its unit; the notebook sliders of
:class:`cdpm.viewer.PoseInspector` and the inspection page of ``cdpm view``
(:mod:`cdpm.viewer.page`) both use it. No optional dependency.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from cdpm.model.coordinates import default_ranges

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
    """Range and unit of each natural coordinate: its default range
    (:func:`cdpm.model.coordinates.default_ranges`, centred on ``natural``),
    widened to contain the current value.

    The default range is the URDF's limits when finite; else [-pi, pi] for
    an angle ([-pi/2, pi/2] for the pitch of a ball joint or free flyer);
    else, for a free flyer's x, y, z (a planar joint's x, y) hanging from
    the world, the box of the cables' anchor points fixed to the world;
    else the current value +- 1 m. A free flyer's position (x, y, z) is a
    length, its roll, pitch and yaw are angles.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        natural: current natural coordinates (nv,) [rad or m], a configuration
            (nq,) or a pose name; default the neutral pose.

    Returns:
        One :class:`CoordinateRange` per coordinate, in the order of
        ``robot.coordinate_names``.
    """
    natural = robot.to_natural(robot.neutral() if natural is None else robot.as_q(natural))
    ranges = default_ranges(robot, natural)
    return tuple(
        CoordinateRange(
            name=name,
            low=min(float(lo), float(value)),
            high=max(float(hi), float(value)),
            unit=unit,
            value=float(value),
        )
        for name, lo, hi, unit, value in zip(
            ranges.names, ranges.low, ranges.high, ranges.units, natural, strict=True
        )
    )


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
