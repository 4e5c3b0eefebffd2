"""Poses worth analysing: a random search for positive output controllable or
statically feasible poses (the library behind ``cdpm find``).

:func:`search_box` says where poses are drawn: each natural coordinate's
default range (:func:`cdpm.model.coordinates.default_ranges`: the URDF's
limits, else a turn for an angle, else the fixed anchor points' box or
+-1 m for a length), narrowed by given ranges and, around a pose, to
within a radius of it. :func:`find_poses` draws poses uniformly in that box,
rounded to :data:`DECIMALS` decimals, evaluates them with the map pipeline
(:func:`cdpm.pipeline.evaluate.evaluate_poses`: equilibrium, linearisation,
positive output controllability) and ranks those that satisfy ``where``:

- ``"poc"``: verdict YES, ranked by the reach margin r_T (largest first);
  poses needing more than :data:`STRAIN_FACTOR` times the tension budget F
  (near-singular: the linearisation holds only very close) come last.
- ``"feasible"``: a tension within the cables' bounds holds the pose (by the
  equilibrium method in use), ranked by the peak cable tension (least first).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cdpm.dynamics.reach import ReachSettings, reach_settings
from cdpm.errors import InputError, is_integer
from cdpm.expressions import parse_number
from cdpm.model.coordinates import default_ranges
from cdpm.model.robot import CableRobot, load_robot
from cdpm.pipeline.evaluate import evaluate_poses, single_threaded_blas
from cdpm.printing import TextRepr
from cdpm.verdicts import STATUS_CODES, VERDICT_LABELS, YES

__all__ = [
    "SearchBox",
    "FoundPose",
    "PoseSearch",
    "search_box",
    "find_poses",
    "WHERE",
    "DECIMALS",
    "STRAIN_FACTOR",
    "MAX_TRIES",
]

#: what the poses must be: positive output controllable (verdict YES) or
#: statically feasible (held by tensions within the cables' bounds)
WHERE = ("poc", "feasible")
#: decimals of the drawn (and evaluated) pose values, so a printed pose is
#: exactly the analysed one
DECIMALS = 4
#: poses evaluated per batch
BATCH = 256
#: a pose needing more than this many times the tension budget F is marked
#: strained and, with ``where="poc"``, ranked after the others
STRAIN_FACTOR = 10
#: most poses one search draws (about 0.1 ms each; for more, map them)
MAX_TRIES = 10**6


# --------------------------------------------------------------------------
# where to draw poses


@dataclass(frozen=True)
class SearchBox:
    """Where poses are drawn: a box of natural coordinates.

    Attributes:
        names: the coordinate names, in the robot's order (nv,).
        low, high: the box [rad or m], shape (nv,) each, ``low <= high``.
        center: natural coordinates (nv,) [rad or m] of the pose searched
            around (drawn first, exactly), or None.
        near: how that pose is shown: its name, or its values as given.
        radius: the half-width [rad or m] of the box around it, or None.
    """

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    center: np.ndarray | None = None
    near: str | None = None
    radius: float | None = None

    def describe(self) -> str:
        """One line: ``uniform in q1 [-3.142, 3.142], q2 0.5`` or ``uniform
        within 0.3 of nominal (q1 [..], ...)``."""
        parts = [
            f"{n} {lo:.4g}" if lo == hi else f"{n} [{lo:.4g}, {hi:.4g}]"
            for n, lo, hi in zip(self.names, self.low, self.high, strict=True)
        ]
        where = ", ".join(parts)
        if self.center is None:
            return f"uniform in {where}"
        return f"uniform within {self.radius:g} of {self.near} ({where})"

    def __str__(self) -> str:
        return self.describe()


def search_box(
    robot: CableRobot,
    *,
    ranges: Mapping[str, tuple[float, float]] | None = None,
    near: Any = None,
    radius: Any = 0.3,
    near_label: str | None = None,
) -> SearchBox:
    """The box poses are drawn from: the default ranges
    (:func:`cdpm.model.coordinates.default_ranges`), narrowed by ``ranges``
    and, with ``near``, to within ``radius`` of that pose (clipped to the
    URDF limits and the given ranges; a coordinate without either may leave
    its default range).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        ranges: coordinate name -> (low, high) [rad or m] to draw it within
            (low = high fixes it); it replaces the default range.
        near: the pose to search around: a pose name of the spec, a
            configuration (nq,) or natural coordinates (nv,); None for the
            whole box.
        radius: with ``near``: half-width [rad or m] of the box around it,
            the same for every coordinate; a number >= 0 or an expression
            such as ``"pi/20"``.
        near_label: how ``near`` is shown (:attr:`SearchBox.near`); default
            its name, or its values.

    Returns:
        :class:`SearchBox`.

    Raises:
        InputError: an unknown coordinate or a bad range in ``ranges``, a
            bad ``radius``, a ``near`` that is not a pose of the robot, or
            one more than ``radius`` outside a coordinate's limited range.
    """

    defaults = default_ranges(robot)
    names = defaults.names
    low, high, limited = defaults.low.copy(), defaults.high.copy(), defaults.limited.copy()
    for name, bounds in (ranges or {}).items():
        if name not in names:
            raise InputError(f"ranges: no coordinate {name!r}; coordinates: {', '.join(names)}")
        lo, hi = _check_range(name, bounds)
        i = names.index(name)
        low[i], high[i], limited[i] = lo, hi, True
    if near is None:
        return SearchBox(names, low, high)
    try:
        r = parse_number(radius)
    except ValueError as exc:
        raise InputError(f"radius {radius!r}: {exc}; give a half-width in rad or m") from exc
    if not (math.isfinite(r) and r >= 0):
        raise InputError(f"radius {radius!r}: give a finite half-width >= 0 (rad or m)")
    center = _natural(robot, near)
    label = near_label if near_label is not None else _label(near)
    lo = np.where(limited, np.maximum(low, center - r), center - r)
    hi = np.where(limited, np.minimum(high, center + r), center + r)
    outside = np.flatnonzero(lo > hi)
    if outside.size:
        i = int(outside[0])
        raise InputError(
            f"near pose {label}: {names[i]} = {center[i]:.4g} is more than radius {r:g} outside "
            f"its range [{low[i]:.4g}, {high[i]:.4g}]; give a pose within the range or a larger "
            "radius"
        )
    return SearchBox(names, lo, hi, center, label, r)


def _check_range(name: str, bounds: Any) -> tuple[float, float]:
    """(low, high) of one entry of ``ranges``: two finite numbers, low <= high."""
    try:
        lo, hi = (float(v) for v in bounds)
    except (TypeError, ValueError) as exc:
        raise InputError(f"ranges: {name!r} needs (low, high) [rad or m], got {bounds!r}") from exc
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise InputError(
            f"ranges: {name!r} needs finite low <= high [rad or m], got ({lo:g}, {hi:g})"
        )
    return lo, hi


def _natural(robot: CableRobot, pose: Any) -> np.ndarray:
    """Natural coordinates (nv,) of a pose name, configuration or natural
    coordinates; natural coordinates are kept as given (not sent through a
    quaternion and back, which may move them by rounding or by a turn)."""
    natural = robot.to_natural(robot.as_q(pose))  # validates any form
    if not isinstance(pose, (str, Mapping)) and robot.nq != robot.nv and np.size(pose) == robot.nv:
        natural = np.asarray(pose, dtype=float).reshape(-1).copy()
    return natural


def _label(near: Any) -> str:
    """A pose as shown: its name, else its values (as given when text)."""
    if isinstance(near, str):
        return near
    values = np.ravel(np.asarray(near, dtype=object))
    return " ".join(v.strip() if isinstance(v, str) else repr(float(v)) for v in values)


def _draw_poses(box: SearchBox, tries: int, seed: int) -> np.ndarray:
    """``tries`` poses (tries, nv) uniform in ``box``, rounded to DECIMALS
    (inwards at the box's ends); with a centre, the centre first (exact)."""
    rng = np.random.default_rng(seed)
    scale = 10.0**DECIMALS
    lo = np.ceil(np.round(box.low * scale, 6)) / scale
    hi = np.floor(np.round(box.high * scale, 6)) / scale
    hi = np.maximum(hi, lo)
    poses = np.round(rng.uniform(lo, hi, size=(tries, lo.size)), DECIMALS)
    poses = np.clip(poses, lo, hi)
    if box.center is not None:
        poses[0] = box.center
    return poses


# --------------------------------------------------------------------------
# the search and its result


@dataclass(frozen=True)
class FoundPose:
    """One pose a search found.

    Attributes:
        index: its row in :attr:`PoseSearch.natural` (0 with a centre: the
            pose searched around).
        natural: its natural coordinates (nv,) [rad or m].
        poc: the POC verdict's label (``"yes"``, ``"no"``, ``"marginal"``,
            ``"not analysed"``).
        static_feasible: the static feasibility verdict's label.
        reach_margin: r_T [output units], NaN when not computed.
        reach_margin_error: the bound on its error [output units], or NaN.
        peak_tension: the largest equilibrium cable tension [N].
        strained: it needs more than STRAIN_FACTOR times the tension budget
            F: near-singular, its r_T holds only very close to it.
        distance: with a centre, its inf-norm distance to it [rad or m];
            else None.
    """

    index: int
    natural: np.ndarray
    poc: str
    static_feasible: str
    reach_margin: float
    reach_margin_error: float
    peak_tension: float
    strained: bool
    distance: float | None


@dataclass(frozen=True)
class PoseSearch(TextRepr):
    """What :func:`find_poses` found.

    Attributes:
        where: ``"poc"`` or ``"feasible"`` (:data:`WHERE`).
        box: where the poses were drawn (:class:`SearchBox`).
        seed: the random seed.
        natural: every pose drawn, shape (tries, nv) [rad or m].
        statically_feasible: how many of them are statically feasible.
        poc_yes: how many are positive output controllable (YES).
        ranked: how many of those satisfying ``where`` were ranked (with
            ``"poc"`` at most ``rank``, drawn at random).
        reach: the reach margin's settings.
        poses: the best poses, best first (at most ``count``; none when no
            pose drawn satisfies ``where``).
    """

    where: str
    box: SearchBox
    seed: int
    natural: np.ndarray
    statically_feasible: int
    poc_yes: int
    ranked: int
    reach: ReachSettings
    poses: tuple[FoundPose, ...]

    @property
    def tried(self) -> int:
        """How many poses were drawn."""
        return int(self.natural.shape[0])

    def __str__(self) -> str:
        tried = self.tried
        lines = [
            f"{tried} poses tried, {self.box.describe()} (seed {self.seed}): "
            f"{self.statically_feasible} statically feasible, {self.poc_yes} positive output "
            "controllable (YES)"
        ]
        if not self.poses:
            lines.append(f"none is {'POC' if self.where == 'poc' else 'statically feasible'}")
        by = "the most reach margin r_T" if self.where == "poc" else "the least peak tension"
        if self.poses:
            lines.append(f"{len(self.poses)} pose(s) of {by}:")
        for k, pose in enumerate(self.poses, 1):
            values = ", ".join(
                f"{n} = {v:.{DECIMALS}f}" for n, v in zip(self.box.names, pose.natural, strict=True)
            )
            lines.append(
                f"  {k}: r_T {pose.reach_margin:.4g}, POC {pose.poc}"
                f"{' (strained)' if pose.strained else ''}, peak tension "
                f"{pose.peak_tension:.4g} N: {values}"
            )
        return "\n".join(lines)


def find_poses(
    robot: CableRobot | str | os.PathLike,
    box: SearchBox | None = None,
    *,
    where: str = "poc",
    count: int = 5,
    tries: int = 1000,
    rank: int = 200,
    seed: int = 0,
    tension: Any = None,
    reach: ReachSettings | None = None,
) -> PoseSearch:
    """Draw random poses, evaluate them and rank those satisfying ``where``.

    The poses are drawn uniformly in ``box``, rounded to :data:`DECIMALS`
    decimals (the pose searched around, if any, first and exact), and
    evaluated in batches by the map pipeline. With ``where="poc"`` the YES
    poses are ranked by the reach margin r_T (at most ``rank`` of them,
    drawn at random: r_T costs a fraction of a millisecond a pose with three
    outputs, about 0.2 s with six), strained poses last; with
    ``"feasible"`` the statically feasible poses by their peak tension.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` or the path of its
            cable spec.
        box: where to draw the poses (:func:`search_box`); default the
            whole box of default ranges.
        where: ``"poc"`` (verdict YES) or ``"feasible"``.
        count: most poses returned, >= 1.
        tries: poses drawn, from 1 to :data:`MAX_TRIES`.
        rank: with ``"poc"``: most YES poses ranked by r_T, >= ``count``.
        seed: the random seed (the draw, and which YES poses are ranked).
        tension: equilibrium tension setting: None (the spec's method), a
            method name or tensions [N] (m,) (as :func:`cdpm.evaluate_poses`).
        reach: the reach margin's :class:`~cdpm.dynamics.reach.ReachSettings`
            (:func:`cdpm.reach_settings`), or None for the model's defaults.

    Returns:
        :class:`PoseSearch`; its ``poses`` are empty when no pose drawn
        satisfies ``where``.

    Raises:
        InputError: a bad ``where``, ``count``, ``tries``, ``rank``,
            ``seed``, ``box``, ``reach`` or ``tension``.
    """

    robot = robot if isinstance(robot, CableRobot) else load_robot(robot)
    if where not in WHERE:
        raise InputError(f"where must be 'poc' or 'feasible', got {where!r}")
    for name, value, least in (("count", count, 1), ("tries", tries, 1), ("rank", rank, 1)):
        if not is_integer(value) or value < least:
            raise InputError(f"{name} {value!r}: give a whole number >= {least}")
    if tries > MAX_TRIES:
        raise InputError(
            f"tries {tries:,}: at most {MAX_TRIES:,} poses per search (about 0.1 ms each); "
            "for more, map them: cdpm.workspace_map(robot, cdpm.sample_axes(...))"
        )
    if rank < count:
        raise InputError(
            f"rank {rank} is less than count {count}: rank at least as many poses as are returned"
        )
    if not is_integer(seed) or seed < 0:
        raise InputError(f"seed {seed!r}: give a whole number >= 0")
    if box is None:
        box = search_box(robot)
    elif not isinstance(box, SearchBox) or box.names != tuple(robot.coordinate_names):
        raise InputError(
            "box must be a SearchBox of this robot (cdpm.regions.search_box(robot, ...))"
        )
    if reach is not None and not isinstance(reach, ReachSettings):
        raise InputError(
            f"reach must be None or a ReachSettings (cdpm.reach_settings(robot, horizon, "
            f"tension_budget)), got {type(reach).__name__}"
        )
    reach = reach_settings(robot, reach)

    natural = _draw_poses(box, tries, seed)
    data = _evaluate(robot, natural, tension, margin=False, reach=None)
    feasible = _feasible(data)
    poc = data["poc"] == YES
    candidates = np.flatnonzero(poc if where == "poc" else feasible)
    rng = np.random.default_rng(seed + 1)
    if where == "poc":
        ranked = candidates
        if ranked.size > rank:
            ranked = np.sort(rng.choice(ranked, size=rank, replace=False))
        if box.center is not None and candidates.size and candidates[0] == 0 and 0 not in ranked:
            ranked = np.concatenate([[0], ranked[1:]])  # the pose searched around is always ranked
        scored = _evaluate(robot, natural[ranked], tension, margin=True, reach=reach)
        margin = np.nan_to_num(scored.get("reach_margin", np.zeros(0)), nan=-np.inf)
        strained = _strained(scored.get("tension_max", np.zeros(0)), reach)
        order = np.lexsort((-margin, strained))[:count]
        chosen, chosen_data = ranked[order], {k: v[order] for k, v in scored.items()}
    else:
        ranked = candidates
        peak = data["tension_max"][candidates]
        order = np.argsort(np.nan_to_num(peak, nan=np.inf), kind="stable")[:count]
        chosen = candidates[order]
        chosen_data = _evaluate(robot, natural[chosen], tension, margin=True, reach=reach)
    strained = _strained(chosen_data.get("tension_max", np.zeros(0)), reach)
    poses = []
    for k, index in enumerate(chosen):
        distance = None
        if box.center is not None:
            distance = float(np.max(np.abs(natural[index] - box.center), initial=0.0))
        poses.append(
            FoundPose(
                index=int(index),
                natural=natural[index].copy(),
                poc=VERDICT_LABELS[int(chosen_data["poc"][k])],
                static_feasible=VERDICT_LABELS[int(chosen_data["static_feasible"][k])],
                reach_margin=float(chosen_data["reach_margin"][k]),
                reach_margin_error=float(chosen_data["reach_margin_error"][k]),
                peak_tension=float(chosen_data["tension_max"][k]),
                strained=bool(strained[k]),
                distance=distance,
            )
        )
    return PoseSearch(
        where=where,
        box=box,
        seed=int(seed),
        natural=natural,
        statically_feasible=int(feasible.sum()),
        poc_yes=int(poc.sum()),
        ranked=int(ranked.size),
        reach=reach,
        poses=tuple(poses),
    )


def _evaluate(robot: CableRobot, natural: np.ndarray, tension, margin: bool, reach) -> dict:
    """The map variables at ``natural`` (N, nv), in batches of BATCH."""

    if natural.shape[0] == 0:
        return {}
    parts = []
    with single_threaded_blas():
        for start in range(0, natural.shape[0], BATCH):
            chunk = natural[start : start + BATCH]
            parts.append(evaluate_poses(robot, chunk, tension, margin=margin, reach=reach))
    return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}


def _feasible(data: dict) -> np.ndarray:
    """Held by a tension within the bounds, by the equilibrium method in use."""

    return (data["static_feasible"] == YES) & (data["status"] != STATUS_CODES["no_equilibrium"])


def _strained(peak_tension: np.ndarray, reach) -> np.ndarray:
    """Poses whose equilibrium needs more than STRAIN_FACTOR times the
    tension budget F (the robot's weight by default): near-singular poses,
    where the linearisation, and so the reach margin, holds only very close
    to the pose."""
    return np.asarray(peak_tension) > STRAIN_FACTOR * reach.tension_budget
