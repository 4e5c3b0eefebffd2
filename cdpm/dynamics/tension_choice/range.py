"""The feasible equilibrium tensions of a pose: :func:`tension_range`.

With more cables than degrees of freedom the tensions that hold a pose,

    P = {f : L(q)^T f = -G(q) - w_ext, f_min <= f <= f_max},

form a polytope, and which cables are slack (sign-constrained inputs) and
the cable stiffness ``sum f_i Hess(l_i)`` in A depend on the point chosen.
:func:`tension_range` describes P by linear programs (HiGHS): whether it
is empty, each cable's least and greatest feasible tension, which cables
can, must or cannot be slack, the null space of L^T and a point in its
relative interior. Everything here is exact up to the LP tolerance
(TENSION_LP_TOL) and the bound tolerance (TENSION_RANGE_RTOL).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium import statics
from cdpm.dynamics.reach import reach_settings
from cdpm.dynamics.tension_choice._polytope import Polytope, polish, polytope, solve_lp
from cdpm.errors import positive_number
from cdpm.numerics import MAX_TENSION, TENSION_CAP_BUDGETS, TENSION_RANGE_RTOL
from cdpm.printing import TextRepr

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = ["TensionRange", "tension_range", "default_tension_cap", "explore", "Exploration"]


def default_tension_cap(robot: CableRobot, tension_budget: Any = None) -> float:
    """The tension cap [N] of cables without an upper bound in the tension
    search: TENSION_CAP_BUDGETS (10) times the reach margin's tension budget
    F (:func:`cdpm.dynamics.reach.reach_settings`; the robot's weight, or its mass
    times 1 m/s^2), or the largest finite maximum tension of a cable if that
    is larger. A pose whose every equilibrium needs more raises it to twice
    what it needs (:class:`TensionRange` states the cap used)."""

    budget = reach_settings(robot, None, tension_budget).tension_budget
    finite = robot.tension_max[np.isfinite(robot.tension_max)]
    return float(max(TENSION_CAP_BUDGETS * budget, finite.max(initial=0.0)))


def checked_cap(cap: Any) -> float:
    """A tension cap [N] as a float in (0, MAX_TENSION], or an InputError."""

    return positive_number(
        cap,
        f"tension_cap must be a positive tension of at most {MAX_TENSION:g} N (the largest "
        f"tension the search gives a cable without an upper bound), got {cap!r}",
        largest=MAX_TENSION,
    )


@dataclass(frozen=True)
class Exploration:
    """The LPs of one pose (internal): ranges, cap, interior point and the
    vertices found on the capped polytope."""

    polytope: Polytope
    feasible: bool
    least: np.ndarray
    greatest: np.ndarray
    cap: float
    capped_upper: np.ndarray
    interior: np.ndarray
    interior_slack: float
    vertices: list[tuple[str, np.ndarray]] = field(default_factory=list)
    n_lps: int = 0


def explore(
    LT: np.ndarray,
    load: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    cap: float,
    names: tuple[str, ...],
    force: float,
) -> Exploration:
    """Feasibility, per-cable ranges (uncapped), the cap, the relative
    interior point and the per-cable extreme vertices (capped) of one pose.

    Args:
        LT: L^T, (nv, m); load: (nv,); lower, upper: bounds [N] (m,).
        cap: the stated cap [N] of cables without an upper bound.
        names: cable names (labels of the vertices).
        force: the robot's force scale [N]
            (:attr:`cdpm.model.robot.CableRobot.force_scale`).
    """
    P = polytope(LT, load, lower, upper, force)
    m = lower.shape[0]
    nan = np.full(m, np.nan)
    empty = Exploration(P, False, nan, nan.copy(), cap, upper.copy(), nan.copy(), np.nan)
    if not P.in_range:
        return empty
    n_lps = 0
    least, greatest = np.empty(m), np.empty(m)
    unbounded = ~np.isfinite(upper)
    solved: dict[tuple[int, float], np.ndarray | None] = {}
    for i in range(m):
        e = np.zeros(m)
        e[i] = 1.0
        status, f, _ = solve_lp(P, e)
        n_lps += 1
        if status != "optimal":  # min of f_i is bounded below by f_min: infeasible
            return dataclasses.replace(empty, n_lps=n_lps)
        least[i] = f[i]
        solved[i, 1.0] = f
        status, f, _ = solve_lp(P, -e)
        n_lps += 1
        greatest[i] = np.inf if status == "unbounded" else f[i]
        solved[i, -1.0] = f
    tol = P.tol
    least = np.where(least <= lower + tol, lower, least)
    greatest = np.where(np.isfinite(upper) & (greatest >= upper - tol), upper, greatest)
    greatest = np.where(greatest <= lower + tol, lower, greatest)  # round-off above f_min
    greatest = np.maximum(greatest, least)
    if unbounded.any():
        # the least cap with which some equilibrium stays: min max f_i over
        # the unbounded cables (an LP in (z, s))
        k = int(unbounded.sum())
        G = np.eye(m)[unbounded]
        status, _, need = solve_lp(P, np.r_[np.zeros(m), 1.0], extra=(G, -np.ones(k), np.zeros(k)))
        n_lps += 1
        if status == "optimal":
            cap = max(cap, 2.0 * need)
    capped = np.where(unbounded, cap, upper)
    # the vertices of each cable's least and greatest tension within the
    # cap: an uncapped optimum within the cap is one, else solve again
    per_cable: list[tuple[str, np.ndarray]] = []
    for i in range(m):
        for sign, word in ((1.0, "least"), (-1.0, "greatest")):
            f = solved[i, sign]
            if f is None or np.any(f > capped + tol):
                e = np.zeros(m)
                e[i] = sign
                status, f, _ = solve_lp(P, e, capped)
                n_lps += 1
                if status != "optimal":
                    continue
            per_cable.append((f"{word} {names[i]}", f))
    low_c = np.array([min(f[i] for _, f in per_cable) for i in range(m)]) if per_cable else least
    high_c = np.array([max(f[i] for _, f in per_cable) for i in range(m)]) if per_cable else least
    movable = high_c - low_c > tol
    interior, slack = _interior(P, capped, movable)
    n_lps += int(movable.any())
    if interior is None:
        interior, slack = per_cable[0][1], 0.0
    vertices = []
    for label, f in per_cable:
        g = polish(P, f, capped)
        if g is not None:
            vertices.append((label, g))
    interior = polish(P, interior, capped)
    if interior is None:
        interior, slack = vertices[0][1] if vertices else per_cable[0][1], 0.0
    return Exploration(
        P, True, least, greatest, cap, capped, interior, float(slack), vertices, n_lps
    )


def _interior(P: Polytope, capped: np.ndarray, movable: np.ndarray):
    """The point maximising the smallest distance s [N] of the movable
    cables (those with a feasible range) to their bounds (capped): a point
    of the relative interior when s > 0. (None, 0) when no cable moves."""
    if not movable.any():
        return None, 0.0
    m = movable.shape[0]
    idx = np.flatnonzero(movable)
    rows = [np.eye(m)[idx] * -1.0]  # s - f_i <= -lower_i
    rhs = [-P.lower[idx]]
    bounded = idx[np.isfinite(capped[idx])]
    rows.append(np.eye(m)[bounded])  # f_i + s <= upper_i
    rhs.append(capped[bounded])
    G = np.vstack(rows)
    g = np.ones(G.shape[0])
    h = np.concatenate(rhs)
    status, f, s = solve_lp(P, np.r_[np.zeros(m), -1.0], capped, extra=(G, g, h))
    if status != "optimal":
        return None, 0.0
    return f, max(s, 0.0)


@dataclass(frozen=True)
class TensionRange(TextRepr):
    """The feasible equilibrium tensions of one pose: the polytope
    ``{f : L(q)^T f = load(q), f_min <= f <= f_max}``, load = -G - w_ext.

    Printing it gives a short summary; :func:`cdpm.text.tension_range_text`
    prints it in full, :func:`cdpm.text.tension_range_json` gives its JSON
    data.

    Exact up to the LP tolerance (TENSION_LP_TOL) and the bound tolerance
    (TENSION_RANGE_RTOL): every number comes from a linear program (HiGHS).

    Attributes:
        q: configuration, shape (nq,).
        cable_names: names of the m cables.
        tension_min, tension_max: the cables' bounds [N], each (m,).
        feasible: some tension within the bounds holds the pose.
        least: each cable's least feasible tension [N], shape (m,) (NaN
            when infeasible).
        greatest: each cable's greatest feasible tension [N], shape (m,)
            (inf when unbounded above; NaN when infeasible).
        null_space: orthonormal basis of the null space of L^T, shape
            (m, m - rank): the directions in which tensions change without
            changing the statics (internal forces).
        rank: rank of L^T.
        can_be_slack: cables whose least feasible tension is f_min, (m,).
        must_be_slack: cables whose greatest feasible tension is f_min, (m,).
        can_be_taut: cables whose greatest feasible tension exceeds f_min, (m,).
        interior: a point of the relative interior [N], shape (m,): the
            feasible tension maximising the smallest distance, ``interior_slack``
            [N], of the cables that can move to their bounds (cables without
            an upper bound capped at ``tension_cap``).
        interior_slack: that distance [N] (0 when no cable can move).
        tension_cap: the cap [N] of cables without an upper bound (in the
            interior point and the search; not in ``greatest``).
        load: -G - w_ext at q, shape (nv,) [N or N m].
        n_lps: linear programs solved.
    """

    q: np.ndarray
    cable_names: tuple[str, ...]
    tension_min: np.ndarray
    tension_max: np.ndarray
    feasible: bool
    least: np.ndarray
    greatest: np.ndarray
    null_space: np.ndarray
    rank: int
    can_be_slack: np.ndarray
    must_be_slack: np.ndarray
    can_be_taut: np.ndarray
    interior: np.ndarray
    interior_slack: float
    tension_cap: float
    load: np.ndarray
    n_lps: int = 0

    @classmethod
    def from_exploration(cls, q, names, X: Exploration) -> TensionRange:
        P = X.polytope
        fmin = P.lower
        if X.feasible:
            tol = P.tol
            can_slack = X.least <= fmin + tol
            can_taut = X.greatest > fmin + tol
            must_slack = ~can_taut
        else:
            can_slack = must_slack = can_taut = np.zeros(fmin.shape, dtype=bool)
        return cls(
            q=np.array(q, dtype=float),
            cable_names=tuple(names),
            tension_min=fmin.copy(),
            tension_max=P.upper.copy(),
            feasible=bool(X.feasible),
            least=X.least.copy(),
            greatest=X.greatest.copy(),
            null_space=P.null_space.copy(),
            rank=int(P.rank),
            can_be_slack=can_slack,
            must_be_slack=must_slack,
            can_be_taut=can_taut,
            interior=X.interior.copy(),
            interior_slack=float(X.interior_slack),
            tension_cap=float(X.cap),
            load=P.load.copy(),
            n_lps=int(X.n_lps),
        )

    def cable_states(self) -> list[str]:
        """Per cable, in words: ``must be slack``, ``slack or taut``,
        ``always taut`` or ``fixed at F N`` (its range is one point above f_min)."""
        out = []
        for i in range(len(self.cable_names)):
            if not self.feasible:
                out.append("-")
            elif self.must_be_slack[i]:
                out.append("must be slack")
            elif self.can_be_slack[i]:
                out.append("slack or taut")
            elif self.greatest[i] - self.least[i] <= TENSION_RANGE_RTOL * abs(self.greatest[i]):
                out.append(f"fixed at {self.least[i]:.6g} N")
            else:
                out.append("always taut")
        return out

    def __str__(self) -> str:
        # a summary; cdpm.text.tension_range_text gives the table per cable
        if not self.feasible:
            return (
                "Feasible equilibrium tensions: none (no tension within the cable bounds holds "
                "the pose)"
            )

        def names(mask: np.ndarray) -> str:
            return ", ".join(n for n, m in zip(self.cable_names, mask, strict=True) if m) or "none"

        d = self.null_space.shape[1]
        return (
            f"Feasible equilibrium tensions: rank L^T = {self.rank}, {d} internal-force "
            f"direction(s); can be slack: {names(self.can_be_slack)}; must be slack: "
            f"{names(self.must_be_slack)}"
        )


def pose_statics(robot: CableRobot, q: Any):
    """(q (nq,), L^T (nv, m), load (nv,)) at one pose (name, configuration
    or natural coordinates); raises ModelError on a zero-length cable."""

    q = robot.kinematics(q).q
    LT, load = statics(robot, robot.kinematics_batch(q[None], dynamics=True))
    return q, LT[0], load[0]


def tension_range(
    robot: CableRobot, q: Any, *, tension_cap: Any = None, tension_budget: Any = None
) -> TensionRange:
    """The feasible equilibrium tensions at q (module docstring).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: a pose name, a configuration (nq,) or natural coordinates (nv,).
        tension_cap: cap [N] of cables without an upper bound for the
            interior point; default :func:`default_tension_cap`.
        tension_budget: the reach tension budget [N] the default cap is a
            multiple of (default the model's).

    Returns:
        :class:`TensionRange` (``feasible`` False at a pose no tension
        within the bounds holds; never raises for that).

    Raises:
        InputError: bad q or cap; ModelError: a cable of zero length at q.
    """
    cap = default_tension_cap(robot, tension_budget) if tension_cap is None else None
    cap = checked_cap(tension_cap) if cap is None else cap
    q, LT, load = pose_statics(robot, q)
    X = explore(
        LT, load, robot.tension_min, robot.tension_max, cap, robot.cable_names, robot.force_scale
    )
    return TensionRange.from_exploration(q, robot.cable_names, X)
