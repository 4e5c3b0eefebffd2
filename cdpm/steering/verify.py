"""What a verdict means on the nonlinear robot: steer to targets around a pose.

:func:`verify_pose` decides POC at a pose and then shows it on the full
dynamics. At a YES pose it steers the output to the 2p targets
``y0 +- R e_i`` (and, on request, to random directions at distance R) with
pull-only tensions inside the bounds (:func:`cdpm.steer`). At a NO pose it
steers toward the blocked direction (the certificate's separating vector v)
and reports the best attempt: ``v.(y - y0)`` stays at most of second order
in R.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.linearisation import linearise
from cdpm.dynamics.reach import reach_unit
from cdpm.errors import InputError, checked_seed, is_integer, positive_number
from cdpm.printing import TextRepr
from cdpm.steering.output_range import output_range, outside_range
from cdpm.steering.shooting import SteerResult, steer

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = ["VerifyReport", "verify_pose", "default_radius"]

#: default radius of the targets, as a fraction of the robot's size (the
#: largest distance between two cable anchor points at the pose)
RADIUS_FRACTION = 2e-3
#: least radius of the targets, as a fraction of the robot's size (y0 + R
#: must differ from y0 by more than its round-off)
RADIUS_MIN_FRACTION = 1e-9
#: most random target directions of one verification (each is a steering)
MAX_RANDOM_DIRECTIONS = 1000


@dataclass(frozen=True)
class VerifyReport(TextRepr):
    """Steering runs around one pose.

    Printing it gives a short summary; :func:`cdpm.text.verify_text` prints
    it in full (a row per target), :func:`cdpm.text.verify_json` gives its
    JSON data; :func:`cdpm.plotting.plot_verify_report` draws its runs.

    Attributes:
        model_name, pose_name: what was verified (pose_name None for a q).
        verdict: the POC verdict at the pose (``"yes"``, ``"no"``, ``"marginal"``).
        radius: R, the distance of the targets [output units].
        y0: the output at the pose (p,).
        directions: unit target directions, shape (n, p).
        runs: one :class:`~cdpm.steering.shooting.SteerResult` per direction.
        blocked_direction: at a NO pose, the separating vector v (p,).
        robot_size: the length R is a fraction of [m].
    """

    model_name: str
    pose_name: str | None
    verdict: str
    radius: float
    y0: np.ndarray
    directions: np.ndarray
    runs: list[SteerResult] = field(default_factory=list)
    blocked_direction: np.ndarray | None = None
    robot_size: float = float("nan")
    radius_given: bool = False

    @property
    def demonstrated(self) -> bool:
        """The verdict shows on the robot: at a YES pose every target is
        reached; at a NO pose the blocked direction is not, and no pull
        moved the output along it by more than 1 % of R."""
        if self.verdict == "yes":
            return self.all_reached
        if self.verdict == "no":
            progress = self.blocked_progress()
            return not self.all_reached and progress is not None and progress <= 0.01
        return False

    @property
    def all_reached(self) -> bool:
        """Every target reached."""
        return all(r.reached for r in self.runs)

    @property
    def worst_relative_miss(self) -> float:
        """max miss / R over the runs."""
        return max((r.miss / self.radius for r in self.runs), default=0.0)

    def blocked_progress(self) -> float | None:
        """At a NO pose: the largest v.(y(t) - y0) over every attempt toward
        v (single-cable pulls, :attr:`SteerResult.blocked_progress`),
        relative to R (second-order small), else None."""
        if self.blocked_direction is None or not self.runs:
            return None
        progress = self.runs[0].blocked_progress
        return None if progress is None else progress / self.radius

    @property
    def unit(self) -> str:
        """The unit of R and the misses: the outputs' (``m``, ``rad`` or
        ``m and rad, one to one``, :func:`cdpm.dynamics.reach.reach_unit`)."""

        return reach_unit(self.runs[0].trajectory.units) if self.runs else "m"

    def __str__(self) -> str:
        # a summary; cdpm.text.verify_text gives the table of runs
        where = f"pose {self.pose_name!r}" if self.pose_name else "the given q"
        reached = sum(r.reached for r in self.runs)
        shown = "shown" if self.demonstrated else "NOT shown"
        return (
            f"cdpm verify: {self.model_name}, {where}: POC {self.verdict.upper()}\n"
            f"  {reached} of {len(self.runs)} targets reached at R = {self.radius:.4g} "
            f"{self.unit}; the verdict is {shown} on the robot"
        )

    def __repr__(self) -> str:
        # a few numbers: each run holds a whole simulation (verify_text shows the table)
        reached = sum(r.reached for r in self.runs)
        return (
            f"VerifyReport(model_name={self.model_name!r}, pose_name={self.pose_name!r}, "
            f"verdict={self.verdict!r}, radius={self.radius:.4g}, runs={len(self.runs)}, "
            f"reached={reached}, demonstrated={self.demonstrated})"
        )


def default_radius(robot: CableRobot, q: Any) -> tuple[float, float]:
    """(R, size): R = RADIUS_FRACTION times the robot's size, the largest
    distance between two cable attachment points at q [m]."""
    points = np.vstack(robot.attachment_points(q))
    diff = points[:, None, :] - points[None, :, :]
    size = float(np.sqrt((diff**2).sum(axis=2)).max(initial=0.0)) or 1.0
    return RADIUS_FRACTION * size, size


def verify_pose(
    robot: CableRobot,
    pose: Any,
    radius: float | None = None,
    *,
    random_directions: int = 0,
    seed: int | None = 0,
    tension: Any = None,
    pretension: float | None = None,
    duration: float | None = None,
) -> VerifyReport:
    """Show the POC verdict at a pose on the nonlinear robot.

    Args:
        robot: the robot.
        pose: a pose name, configuration (nq,) or natural coordinates (nv,).
        radius: R, the distance of the targets [output units], from
            RADIUS_MIN_FRACTION = 1e-9 times the robot's size to its size;
            default :func:`default_radius`.
        random_directions: extra targets in random unit directions (YES),
            at most MAX_RANDOM_DIRECTIONS = 1000.
        seed: their random seed (an integer from 0 to 2**63 - 1, or None
            for fresh entropy).
        tension, pretension: the equilibrium tension (as for
            :func:`cdpm.linearise`).
        duration: the steering time T [s] (default per pose).

    Returns:
        :class:`VerifyReport`.
    """
    # scipy: loaded on first use
    from cdpm.analysis import positive_output_controllability

    lin = linearise(robot, pose, tension=tension, pretension=pretension)
    poc = positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
    )
    q = lin.q
    size = default_radius(robot, q)[1]
    R = RADIUS_FRACTION * size
    if radius is not None:
        message = (
            f"radius must be a distance from {RADIUS_MIN_FRACTION:g} times the robot's size "
            f"to its size, {size:.3g} (targets near the pose: the check is local; closer ones "
            f"are the outputs' round-off), got {radius!r}"
        )
        R = positive_number(radius, message, largest=size, smallest=RADIUS_MIN_FRACTION * size)
    if not (is_integer(random_directions) and 0 <= random_directions <= MAX_RANDOM_DIRECTIONS):
        raise InputError(
            f"random_directions must be a count from 0 to {MAX_RANDOM_DIRECTIONS} (each is a "
            f"steering, about a second), got {random_directions!r}"
        )
    seed = None if seed is None else checked_seed(seed)
    p = robot.n_outputs
    y0 = lin.output
    verdict = poc.verdict.value
    blocked = None
    if verdict == "no":
        v = getattr(poc.certificate, "separator", None)
        blocked = np.asarray(v, dtype=float) / np.linalg.norm(v)
        directions = blocked[None]
    elif p == 1:  # the two directions are all there are
        directions = np.array([[1.0], [-1.0]])
    else:
        eye = np.eye(p)
        directions = np.vstack([np.stack([e, -e]) for e in eye]) if p else np.zeros((0, 0))
        if random_directions:
            extra = np.random.default_rng(seed).standard_normal((random_directions, p))
            directions = np.vstack([directions, extra / np.linalg.norm(extra, axis=1)[:, None]])
    _check_targets_in_range(robot, y0, R, directions)
    runs = [
        steer(
            robot,
            q,
            y0 + R * d,
            tension=tension,
            pretension=pretension,
            duration=duration,
        )
        for d in directions
    ]
    return VerifyReport(
        model_name=robot.spec.path.name,
        pose_name=pose if isinstance(pose, str) else None,
        verdict=verdict,
        radius=R,
        y0=y0.copy(),
        directions=directions,
        runs=runs,
        blocked_direction=blocked,
        robot_size=size,
        radius_given=radius is not None,
    )


def _check_targets_in_range(robot, y0: np.ndarray, R: float, directions: np.ndarray) -> None:
    """Raise when a target y0 + R d lies outside the outputs' range (no pose
    has it: :func:`~cdpm.steering.output_range.output_range`), naming the
    largest radius that keeps every target inside."""
    for d in directions:
        beyond = outside_range(robot, y0 + R * d)
        if beyond is None:
            continue
        lower, upper = output_range(robot)
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(directions > 0, (upper - y0) / directions, np.inf)
            room = np.minimum(room, np.where(directions < 0, (lower - y0) / directions, np.inf))
        largest = max(float(room.min()), 0.0)
        raise InputError(
            f"radius {R:.4g} puts a target out of reach: {beyond} (no pose goes past it); "
            f"give a radius of at most {largest:.4g}"
        )
