"""The tension search: is some feasible equilibrium tension POC, and which
one gives the largest reach margin r_T?

:func:`best_tension_batch` searches the polytope of feasible equilibrium
tensions of many poses (:mod:`cdpm.dynamics.tension_choice.range`) with candidates:
the default tension (the spec's method), the relative-interior point, the
LP vertices of the ranges (least and greatest tension of each cable), the
vertices in seeded random objective directions, pretension levels and
seeded random points inside the polytope (convex combinations of the
vertices and the interior point). Every candidate of every pose goes
through the map pipeline in one batch: batch kinematics once,
:func:`cdpm.dynamics.linearisation.linearise_batch` with a tension per candidate,
:func:`cdpm.analysis.batch.analyse_systems` and
:func:`cdpm.dynamics.reach.reach_margins_at`. With ``objective="margin"`` the best
candidate is refined by rounds of samples in a shrinking neighbourhood
inside the polytope. :func:`best_tension` is this on a batch of one.

What is exact and what is sampled: feasibility, the ranges and the slack
sets come from LPs; a YES comes with its certificate at the chosen
tension. A NO means that none of the candidates evaluated is POC (other
tensions may be), and the best margin is the best found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium import (
    equilibrium_tensions,
    resolve_method,
    solve_equilibria,
    statics,
)
from cdpm.dynamics.equilibrium.statics import classify, input_signs
from cdpm.dynamics.linearisation import linearise_batch, mass_inverse
from cdpm.dynamics.reach import reach_margins_at, reach_settings
from cdpm.dynamics.tension_choice._polytope import LPFailure, polish, solve_lp
from cdpm.dynamics.tension_choice.range import (
    TensionRange,
    checked_cap,
    default_tension_cap,
    explore,
)
from cdpm.errors import InputError, checked_seed, is_integer
from cdpm.model.poses import check_poses, configurations
from cdpm.numerics import MIN_SEGMENT_LENGTH, SPAN_TOL
from cdpm.verdicts import MARGINAL, NO, NOT_ANALYSED, STATUS_CODES, YES

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.reach import ReachSettings
    from cdpm.model.kinematics import BatchKinematics
    from cdpm.model.robot import CableRobot

__all__ = ["TensionSearch", "BestTensionBatch", "best_tension_batch", "search_tensions"]

#: the objectives of the search
OBJECTIVES = ("poc", "margin")

#: pretension levels tried, as fractions of the largest (capped) greatest
#: feasible tension of the pose
PRETENSION_FRACTIONS = (0.1, 0.25, 0.5)

#: verdict codes from worst to best (the ranking of candidates)
_RANK = {NOT_ANALYSED: 0, NO: 1, MARGINAL: 2, YES: 3}


@dataclass(frozen=True)
class TensionSearch:
    """How the tension search samples the polytope (plain data; a map
    stores :meth:`as_dict` in its settings).

    Attributes:
        objective: ``"poc"`` (is some tension POC; the YES candidate of
            largest r_T is chosen) or ``"margin"`` (the same, then refined
            towards a larger r_T).
        directions: vertices in seeded random objective directions, per pose.
        random_points: seeded random points inside the polytope, per pose.
        refine_rounds: refinement rounds (``"margin"`` only); round k
            samples within 2^-k of the way from the best tension to random
            points of the polytope.
        refine_samples: samples per refinement round and pose.
        seed: seed of the random directions and points (the same stream at
            every pose, so a pose's result does not depend on its batch).
        tension_cap: cap [N] of cables without an upper bound, or None for
            :func:`~cdpm.dynamics.tension_choice.range.default_tension_cap`.
    """

    objective: str = "poc"
    directions: int = 8
    random_points: int = 16
    refine_rounds: int = 3
    refine_samples: int = 8
    seed: int = 0
    tension_cap: float | None = None

    def as_dict(self) -> dict:
        return {
            "objective": self.objective,
            "directions": self.directions,
            "random_points": self.random_points,
            "refine_rounds": self.refine_rounds,
            "refine_samples": self.refine_samples,
            "seed": self.seed,
            "tension_cap": self.tension_cap,
        }


def tension_search(
    objective: Any = "poc",
    *,
    directions: Any = TensionSearch.directions,
    random_points: Any = TensionSearch.random_points,
    refine_rounds: Any = TensionSearch.refine_rounds,
    refine_samples: Any = TensionSearch.refine_samples,
    seed: Any = TensionSearch.seed,
    tension_cap: Any = None,
) -> TensionSearch:
    """A validated :class:`TensionSearch`.

    Raises:
        InputError: an unknown objective, a negative count, a seed that is
            not an integer or a cap that is not a positive tension.
    """
    if objective not in OBJECTIVES:
        raise InputError(
            f"objective must be one of {', '.join(map(repr, OBJECTIVES))} (POC for some tension, "
            f"or also the largest reach margin), got {objective!r}"
        )
    counts = {}
    for name, value in (
        ("directions", directions),
        ("random_points", random_points),
        ("refine_rounds", refine_rounds),
        ("refine_samples", refine_samples),
    ):
        if not is_integer(value) or value < 0:
            raise InputError(f"{name} must be an integer >= 0, got {value!r}")
        counts[name] = int(value)
    seed = checked_seed(seed)
    cap = None if tension_cap is None else checked_cap(tension_cap)
    return TensionSearch(objective, **counts, seed=int(seed), tension_cap=cap)


@dataclass(frozen=True)
class BestTensionBatch:
    """The tension search at N poses.

    Attributes:
        qs: the poses' configurations, shape (N, nq).
        status: :data:`cdpm.verdicts.STATUS_CODES` per pose (``ok``,
            ``zero_length_cable``, ``singular_mass_matrix``,
            ``no_equilibrium`` where no tension within the bounds holds the
            pose, ``analysis_failed`` where an LP or the analysis failed), (N,).
        poc_possible: verdict code per pose (:mod:`cdpm.verdicts`): YES when
            some candidate is POC, else the best verdict of the candidates
            (MARGINAL, NO), NOT_ANALYSED without candidates; int8 (N,).
        tension: the chosen tension [N], shape (N, m) (NaN without one).
        reach_margin: its r_T [output units, m], shape (N,) (NaN without one,
            or not resolvable within the horizon).
        reach_margin_error: the error bound of r_T, (N,): the true value is at most this more.
        found_by: how each chosen tension was found (``"default tension"``,
            ``"relative interior point"``, ``"greatest c1"``, ...).
        default_tension: the default tension [N] (the spec's method), (N, m)
            (NaN where that method finds none).
        default_verdict: its POC verdict code, int8 (N,).
        default_margin: its r_T, (N,).
        n_candidates: tensions evaluated per pose (refinement included), (N,).
        n_yes: how many of them are POC, (N,).
        ranges: the :class:`TensionRange` of each pose (None where the
            kinematics or mass matrix are degenerate).
        search: the :class:`TensionSearch` settings.
        reach: the reach margin's horizon and budget.
        default_method: the default tension's method name.
    """

    qs: np.ndarray
    status: np.ndarray
    poc_possible: np.ndarray
    tension: np.ndarray
    reach_margin: np.ndarray
    reach_margin_error: np.ndarray
    found_by: tuple[str, ...]
    default_tension: np.ndarray
    default_verdict: np.ndarray
    default_margin: np.ndarray
    n_candidates: np.ndarray
    n_yes: np.ndarray
    ranges: tuple[TensionRange | None, ...]
    search: TensionSearch
    reach: ReachSettings
    default_method: str

    def __len__(self) -> int:
        return int(self.status.shape[0])


def best_tension_batch(
    robot: CableRobot,
    natural: Any,
    objective: str = "poc",
    *,
    horizon: Any = None,
    tension_budget: Any = None,
    tension_cap: Any = None,
    seed: int = TensionSearch.seed,
    directions: int = TensionSearch.directions,
    random_points: int = TensionSearch.random_points,
    refine_rounds: int = TensionSearch.refine_rounds,
    refine_samples: int = TensionSearch.refine_samples,
    tol: float = SPAN_TOL,
) -> BestTensionBatch:
    """The tension search at N poses (module docstring).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        natural: natural coordinates of the poses, shape (N, nv).
        objective: ``"poc"`` or ``"margin"`` (:class:`TensionSearch`).
        horizon, tension_budget: the reach margin's T [s] and budget [N]
            (default the model's, as a map and ``cdpm analyze`` use).
        tension_cap: cap [N] of cables without an upper bound (default
            :func:`~cdpm.dynamics.tension_choice.range.default_tension_cap`).
        seed, directions, random_points, refine_rounds, refine_samples:
            the sampling (:class:`TensionSearch`).
        tol: angle-like tolerance of the span decisions.

    Returns:
        :class:`BestTensionBatch`.

    Raises:
        InputError: bad poses or settings.
    """

    settings = tension_search(
        objective,
        directions=directions,
        random_points=random_points,
        refine_rounds=refine_rounds,
        refine_samples=refine_samples,
        seed=seed,
        tension_cap=tension_cap,
    )
    reach = reach_settings(robot, horizon, tension_budget)
    natural = check_poses(robot, natural)
    kin = robot.kinematics_batch(configurations(robot, natural), dynamics=True)
    return search_tensions(robot, kin, settings, reach, tol)


def search_tensions(
    robot: CableRobot,
    kin: BatchKinematics,
    settings: TensionSearch,
    reach: ReachSettings,
    tol: float = SPAN_TOL,
) -> BestTensionBatch:
    """:func:`best_tension_batch` on batch kinematics with dynamics ``kin``
    of N poses (zero-length cables flagged, not raised), settings validated
    (a map's chunk calls this with the kinematics it already has)."""

    n, m = len(kin), robot.n_cables
    out = _Result.empty(n, m)
    method, pretension = resolve_method(robot, None, None)
    seg_min = kin.segment_lengths.min(axis=1, initial=np.inf)
    valid = seg_min >= MIN_SEGMENT_LENGTH
    out.status[~valid] = STATUS_CODES["zero_length_cable"]
    ok = np.flatnonzero(valid)
    ranges: list[TensionRange | None] = [None] * n
    if ok.size == 0:
        return out.finish(kin.qs, ranges, settings, reach, method)
    Minv, regular = mass_inverse(kin.mass_matrix[ok])
    out.status[ok[~regular]] = STATUS_CODES["singular_mass_matrix"]
    LT, load = statics(robot, kin)
    default = equilibrium_tensions(robot, LT[ok], load[ok], method, pretension)
    base_cap = (
        default_tension_cap(robot, reach.tension_budget)
        if settings.tension_cap is None
        else settings.tension_cap
    )
    minv = np.full((n, robot.nv, robot.nv), np.nan)
    minv[ok] = Minv
    cands: list[tuple[int, str, np.ndarray]] = []
    pools: dict[int, tuple] = {}
    for j, i in enumerate(ok):
        try:
            X = explore(
                LT[i],
                load[i],
                robot.tension_min,
                robot.tension_max,
                base_cap,
                robot.cable_names,
                robot.force_scale,
            )
        except LPFailure:
            out.status[i] = STATUS_CODES["analysis_failed"]
            continue
        ranges[i] = TensionRange.from_exploration(kin.qs[i], robot.cable_names, X)
        if not X.feasible:
            out.status[i] = STATUS_CODES["no_equilibrium"]
            continue
        if default.feasible[j]:
            out.default_tension[i] = default.tension[j]
        if not regular[j]:
            continue
        try:
            pose_cands = _candidates(
                robot, X, default.tension[j] if default.feasible[j] else None, settings, pretension
            )
        except LPFailure:
            out.status[i] = STATUS_CODES["analysis_failed"]
            continue
        pools[i] = (X, [f for _, f in pose_cands])
        cands += [(i, label, f) for label, f in pose_cands]
    _evaluate_into(robot, kin, minv, cands, reach, tol, out, first_is_default=True)
    if settings.objective == "margin" and settings.refine_rounds and settings.refine_samples:
        rng = {i: np.random.default_rng([settings.seed, 1]) for i in pools}
        for k in range(1, settings.refine_rounds + 1):
            batch = []
            for i, (X, pool) in pools.items():
                if out.poc_possible[i] != YES or not out.reach_margin[i] > 0:
                    continue
                points = _random_points(rng[i], pool, settings.refine_samples)
                for f in points:
                    g = polish(
                        X.polytope, out.tension[i] + 0.5**k * (f - out.tension[i]), X.capped_upper
                    )
                    if g is not None:
                        batch.append((i, f"refined (round {k})", g))
            if not batch:
                break
            _evaluate_into(robot, kin, minv, batch, reach, tol, out, first_is_default=False)
    return out.finish(kin.qs, ranges, settings, reach, method)


def _candidates(robot, X, default, settings: TensionSearch, pretension: float):
    """(label, tension) candidates of one pose, distinct, the default first."""

    P, m = X.polytope, robot.n_cables
    rng = np.random.default_rng([settings.seed, 0])
    out: list[tuple[str, np.ndarray]] = []
    if default is not None:
        out.append(("default tension", np.asarray(default, dtype=float)))
    out.append(("relative interior point", X.interior))
    out += X.vertices
    for k in range(settings.directions):
        status, f, _ = solve_lp(P, rng.standard_normal(m), X.capped_upper)
        g = polish(P, f, X.capped_upper) if status == "optimal" else None
        if g is not None:
            out.append((f"vertex of random direction {k + 1}", g))
    top = float(np.max(np.minimum(X.greatest, X.cap)))
    levels = [fraction * top for fraction in PRETENSION_FRACTIONS]
    if pretension > 0:
        levels.append(pretension)
    for level in levels:
        lower = np.maximum(P.lower, np.minimum(level, np.minimum(X.greatest, X.capped_upper)))
        eq = solve_equilibria(
            P.LT[None], P.load[None], lower, X.capped_upper, "min_norm", force=P.force
        )
        if eq.feasible[0]:
            g = polish(P, eq.tension[0], X.capped_upper)
            if g is not None:
                out.append((f"pretension level {level:.4g} N", g))
    pool = [f for _, f in out[1 if default is not None else 0 :]]
    for k, f in enumerate(_random_points(rng, pool, settings.random_points)):
        g = polish(P, f, X.capped_upper)
        if g is not None:
            out.append((f"random point {k + 1}", g))
    return _distinct(out, P.tol)


def _random_points(rng, pool: list[np.ndarray], n: int) -> list[np.ndarray]:
    """n convex combinations (uniform Dirichlet weights) of the pool's points."""
    if not pool or n == 0:
        return []
    V = np.array(pool)
    W = rng.dirichlet(np.ones(len(pool)), size=n)
    return list(W @ V)


def _distinct(cands: list[tuple[str, np.ndarray]], tol: float):
    """The candidates without repeats (within ``tol`` [N]), in order."""
    kept: list[tuple[str, np.ndarray]] = []
    for label, f in cands:
        if all(np.max(np.abs(f - g), initial=0.0) > tol for _, g in kept):
            kept.append((label, f))
    return kept


@dataclass
class _Result:
    """Mutable accumulator of :class:`BestTensionBatch` (internal)."""

    status: np.ndarray
    poc_possible: np.ndarray
    tension: np.ndarray
    reach_margin: np.ndarray
    reach_margin_error: np.ndarray
    found_by: list
    default_tension: np.ndarray
    default_verdict: np.ndarray
    default_margin: np.ndarray
    n_candidates: np.ndarray
    n_yes: np.ndarray

    @classmethod
    def empty(cls, n: int, m: int) -> _Result:
        return cls(
            status=np.full(n, STATUS_CODES["ok"], dtype=np.int8),
            poc_possible=np.full(n, NOT_ANALYSED, dtype=np.int8),
            tension=np.full((n, m), np.nan),
            reach_margin=np.full(n, np.nan),
            reach_margin_error=np.full(n, np.nan),
            found_by=[""] * n,
            default_tension=np.full((n, m), np.nan),
            default_verdict=np.full(n, NOT_ANALYSED, dtype=np.int8),
            default_margin=np.full(n, np.nan),
            n_candidates=np.zeros(n, dtype=np.int64),
            n_yes=np.zeros(n, dtype=np.int64),
        )

    def finish(self, qs, ranges, settings, reach, method) -> BestTensionBatch:
        return BestTensionBatch(
            qs=qs,
            status=self.status,
            poc_possible=self.poc_possible,
            tension=self.tension,
            reach_margin=self.reach_margin,
            reach_margin_error=self.reach_margin_error,
            found_by=tuple(self.found_by),
            default_tension=self.default_tension,
            default_verdict=self.default_verdict,
            default_margin=self.default_margin,
            n_candidates=self.n_candidates,
            n_yes=self.n_yes,
            ranges=tuple(ranges),
            search=settings,
            reach=reach,
            default_method=method,
        )


def _key(code: int, margin: float) -> tuple[int, float]:
    """Ranking of a candidate: verdict first, then r_T (NaN lowest)."""
    return _RANK[int(code)], (margin if math.isfinite(margin) else -math.inf)


def _evaluate_into(robot, kin, minv, cands, reach, tol, out: _Result, first_is_default: bool):
    """Evaluate the candidates (pose index, label, tension) in one batch
    through the map pipeline and keep, per pose, the best (in place)."""
    # scipy: loaded on first use
    from cdpm.analysis.batch import analyse_systems

    if not cands:
        return
    pose = np.array([i for i, _, _ in cands])
    F = np.array([f for _, _, f in cands])
    at_lower, at_upper, _ = classify(F, robot.tension_min, robot.tension_max, robot.force_scale)
    signs = input_signs(at_lower, at_upper)
    lin = linearise_batch(robot, kin.take(pose), minv[pose], F, signs)
    verdicts = analyse_systems(
        lin.A, lin.B_cone, lin.C, lin.sign_constrained, margin=False, tol=tol
    )
    r = reach_margins_at(robot, lin, reach, verdicts.poc == NO)
    codes = np.where(verdicts.failed, NOT_ANALYSED, verdicts.poc)
    seen: set[int] = set()
    for k, (i, label, f) in enumerate(cands):
        code, value = int(codes[k]), float(r.value[k])
        out.n_candidates[i] += 1
        out.n_yes[i] += int(code == YES)
        if first_is_default and label == "default tension" and i not in seen:
            out.default_verdict[i], out.default_margin[i] = code, value
        seen.add(i)
        best = _key(out.poc_possible[i], out.reach_margin[i]) if out.found_by[i] else None
        if best is None or _key(code, value) > best:
            out.poc_possible[i] = code
            out.tension[i] = f
            out.reach_margin[i], out.reach_margin_error[i] = value, float(r.error[k])
            out.found_by[i] = label
