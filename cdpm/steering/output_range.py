"""The range of a robot's outputs: bounds no pose of the robot goes past.

A steering target beyond them cannot be reached by any tension, so
:func:`~cdpm.steering.shooting.steer` says so at once instead of simulating
attempts. The bounds are conservative (every pose's output lies inside;
not every value inside is reached), from the kinematic chain alone:

- a point fixed in a link is at most ``r`` from the origin ``c`` of the
  first joint of its chain, ``r`` the sum of the distances between the
  joints along the chain, the point's distance from its joint, and the
  travel of every prismatic, planar, translation or free-flyer joint on the
  way (the largest magnitude within its URDF limits; unbounded without
  them); each position output lies in ``c_i +- r``;
- a rotation component is at most pi in magnitude (a rotation vector);
- a joint output lies within the joint's limits;
- a cable length is at most the sum over its segments of the distance
  between their ends' centres plus their radii;
- a weighted sum adds its terms' intervals;
- outputs that are coordinates of one point must together lie in that
  point's ball (each may be in range while the point is not).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from cdpm.model.coordinates import MAX_COORDINATE, coordinate_limits
from cdpm.model.outputs import anchor_in_joint
from cdpm.numerics import STEER_RANGE_RTOL

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = ["output_range", "outside_range"]

#: Pinocchio joints that only turn their child (no travel of its origin)
_TURNING = ("JointModelR", "JointModelSpherical", "JointModelUniversal")
#: joints that move their child's origin: how many of their natural
#: coordinates (from the first) are translations
_TRANSLATING = {
    "JointModelPX": 1,
    "JointModelPY": 1,
    "JointModelPZ": 1,
    "JointModelPrismaticUnaligned": 1,
    "JointModelTranslation": 3,
    "JointModelPlanar": 2,
    "JointModelFreeFlyer": 3,
}


def _travel(joint, lower: np.ndarray, upper: np.ndarray) -> float:
    """How far a joint can move its child's origin [m] (inf without limits)."""
    name = joint.shortname()
    if name.startswith(_TURNING):
        return 0.0
    count = _TRANSLATING.get(name)
    if count is None:  # a joint type not known here: no bound
        return math.inf
    iv = joint.idx_v
    ends = np.abs(np.concatenate([lower[iv : iv + count], upper[iv : iv + count]]))
    if not np.all(ends <= MAX_COORDINATE):  # no limit (or a huge one meaning none)
        return math.inf
    return float(np.linalg.norm(np.maximum(ends[:count], ends[count:])))


def _point_ball(robot: CableRobot, frame: str, point) -> tuple[np.ndarray, float]:
    """(centre (3,) [m], radius [m]) of a ball in the world that holds the
    point ``point`` (in ``frame``) at every pose."""
    model = robot.model
    joint, local = anchor_in_joint(model, frame, np.asarray(point, dtype=float))
    if joint == 0:
        return np.asarray(local, dtype=float), 0.0
    lower, upper = coordinate_limits(model)
    radius = float(np.linalg.norm(local))
    while True:
        radius += _travel(model.joints[joint], lower, upper)
        placement = model.jointPlacements[joint]
        parent = int(model.parents[joint])
        if parent == 0:
            return np.array(placement.translation, dtype=float), radius
        radius += float(np.linalg.norm(placement.translation))
        joint = parent


def _term_interval(robot: CableRobot, term) -> tuple[float, float]:
    """(least, largest) value of one output term over every pose."""
    if term.kind == "position":
        centre, radius = _point_ball(robot, term.frame, term.point_in_frame)
        return centre[term.axis] - radius, centre[term.axis] + radius
    if term.kind == "rotation":
        return -math.pi, math.pi
    if term.kind == "joint":
        model = robot.model
        joint = model.joints[model.getJointId(term.joint)]
        lower, upper = coordinate_limits(model)
        lo, hi = float(lower[joint.idx_v]), float(upper[joint.idx_v])
        if not (abs(lo) <= MAX_COORDINATE and abs(hi) <= MAX_COORDINATE):
            return -math.inf, math.inf
        return lo, hi
    if term.kind == "cable":
        cable = next(c for c in robot.spec.cables if c.name == term.cable)
        balls = [_point_ball(robot, p.frame, p.point_in_frame) for p in cable.route]
        longest = sum(
            float(np.linalg.norm(a[0] - b[0])) + a[1] + b[1]
            for a, b in zip(balls[:-1], balls[1:], strict=True)
        )
        return 0.0, longest
    return -math.inf, math.inf


def output_range(robot: CableRobot) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of each output over every pose of the robot (module docstring).

    Returns:
        (lower, upper), each shape (p,) [each output's unit]; -inf / +inf
        where nothing bounds it (e.g. a free-flyer without position limits).
    """
    lower, upper = np.zeros(robot.n_outputs), np.zeros(robot.n_outputs)
    for i, out in enumerate(robot.spec.outputs):
        for term in out.terms:
            lo, hi = _term_interval(robot, term)
            w = term.weight
            lower[i] += w * lo if w >= 0 else w * hi
            upper[i] += w * hi if w >= 0 else w * lo
    return lower, upper


def _beyond_reach(robot: CableRobot, target: np.ndarray) -> str | None:
    """Outputs that are coordinates of one point (single position terms of
    one frame and point): their target together must lie in the ball that
    holds the point (each alone may be in range while the point is not)."""
    groups: dict[tuple, list[tuple[int, int, float]]] = {}
    for i, out in enumerate(robot.spec.outputs):
        if len(out.terms) == 1 and out.terms[0].kind == "position" and out.terms[0].weight:
            t = out.terms[0]
            key = (t.frame, tuple(np.round(np.asarray(t.point_in_frame, dtype=float), 12)))
            groups.setdefault(key, []).append((i, t.axis, t.weight))
    for (frame, point), members in groups.items():
        axes = [a for _, a, _ in members]
        if len(members) < 2 or len(set(axes)) != len(axes):
            continue
        centre, radius = _point_ball(robot, frame, point)
        if not math.isfinite(radius):
            continue
        at = np.array([target[i] / w for i, _, w in members])
        distance = float(np.linalg.norm(at - centre[axes]))
        slack = STEER_RANGE_RTOL * max(radius, 1.0)
        if distance > radius + slack:
            names = ", ".join(robot.output_names[i] for i, _, _ in members)
            values = ", ".join(f"{target[i]:.4g}" for i, _, _ in members)
            return (
                f"({names}) = ({values}) lies {distance:.4g} m from "
                f"({', '.join(f'{c:.4g}' for c in centre[axes])}), farther than the point can "
                f"reach from there ({radius:.4g} m)"
            )
    return None


def outside_range(robot: CableRobot, target: np.ndarray) -> str | None:
    """Which outputs of ``target`` (p,) lie outside :func:`output_range`
    (by more than STEER_RANGE_RTOL of the output's scale), or, for outputs
    that are coordinates of one point, where that point lies farther than
    it can reach; in words, or None when the target lies within both."""
    lower, upper = output_range(robot)
    slack = STEER_RANGE_RTOL * np.maximum(robot.output_scales, 1.0)
    outside = (target < lower - slack) | (target > upper + slack)
    if not outside.any():
        return _beyond_reach(robot, target)
    return "; ".join(
        f"{robot.output_names[i]} = {target[i]:.4g} {robot.output_units[i]} lies outside the "
        f"range it can take, [{lower[i]:.4g}, {upper[i]:.4g}] {robot.output_units[i]}"
        for i in np.flatnonzero(outside)
    )
