"""The tension search at one pose: :func:`best_tension` and its result.

:func:`best_tension` is :func:`~cdpm.dynamics.tension_choice.search.best_tension_batch`
on a batch of one, plus the linearisation and the POC result at the chosen
tension (``cdpm.linearise(robot, q, tension=f)`` and
``cdpm.positive_output_controllability`` on it), so that the verdict can
be re-checked with the per-pose API and its certificate verified.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium import InfeasibleEquilibriumError, equilibrium_tension
from cdpm.dynamics.linearisation import linearise
from cdpm.dynamics.reach import reach_unit
from cdpm.dynamics.tension_choice.range import TensionRange
from cdpm.dynamics.tension_choice.search import TensionSearch, best_tension_batch
from cdpm.errors import CdpmError, ModelError
from cdpm.numerics import SPAN_TOL
from cdpm.printing import TextRepr, named_values
from cdpm.verdicts import STATUS_CODES, VERDICT_LABELS, YES

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.analysis.poc_result import POCResult
    from cdpm.dynamics.linearisation import Linearisation
    from cdpm.dynamics.reach import ReachSettings
    from cdpm.model.robot import CableRobot

__all__ = ["BestTension", "best_tension", "EXACT_AND_SAMPLED"]

#: what the search decides exactly and what it samples, in words
EXACT_AND_SAMPLED = (
    "exact: feasibility, the tension ranges and which cables can or must be slack (LPs); "
    "a YES is certified at the chosen tension. Sampled: a NO means that none of the "
    "candidates evaluated is POC (another tension may be), and the best margin is the best "
    "found"
)


@dataclass(frozen=True)
class BestTension(TextRepr):
    """Whether some feasible equilibrium tension makes a pose POC, and
    which tension the search chose.

    Printing it gives a short summary; :func:`cdpm.text.best_tension_text`
    prints it in full, :func:`cdpm.text.best_tension_json` gives its JSON
    data.

    Attributes:
        q: configuration, shape (nq,).
        natural: natural coordinates, shape (nv,).
        cable_names: names of the m cables.
        poc_possible: verdict code (:mod:`cdpm.verdicts`): YES when some
            candidate tension is POC (certified at ``tension``), else the
            best verdict among the candidates (NO: none of them is POC).
        tension: the chosen tension [N], shape (m,): the YES candidate of
            largest reach margin (or, without a YES, the best candidate).
        linearisation: ``cdpm.linearise(robot, q, tension=tension)``.
        poc: ``cdpm.positive_output_controllability`` of that
            linearisation (with its input cone): the certificate.
        reach_margin: r_T at ``tension`` [m], and its error bound [m] (the
            true r_T is at most that more).
        found_by: which candidate it is (``"relative interior point"``, ...).
        default_tension: the default tension [N] (the spec's method), (m,),
            NaN when that method finds no equilibrium here.
        default_method: that method's name.
        default_verdict: its POC verdict code (NOT_ANALYSED without one).
        default_margin: its r_T [m].
        tension_range: the :class:`TensionRange` of the pose.
        n_candidates: tensions evaluated (refinement included).
        n_yes: how many of them are POC.
        objective: ``"poc"`` or ``"margin"``.
        search: the sampling settings.
        reach: the reach margin's horizon and budget.
        method: how the tension was found, in words.
    """

    q: np.ndarray
    natural: np.ndarray
    cable_names: tuple[str, ...]
    poc_possible: int
    tension: np.ndarray
    linearisation: Linearisation
    poc: POCResult
    reach_margin: tuple[float, float]
    found_by: str
    default_tension: np.ndarray
    default_method: str
    default_verdict: int
    default_margin: float
    tension_range: TensionRange
    n_candidates: int
    n_yes: int
    objective: str
    search: TensionSearch
    reach: ReachSettings
    method: str
    margin_unit: str = "m"

    @property
    def verdict(self) -> str:
        """``"yes"``, ``"no"``, ``"marginal"`` or ``"not analysed"``."""
        return VERDICT_LABELS[int(self.poc_possible)]

    def __bool__(self) -> bool:
        return int(self.poc_possible) == YES

    def __str__(self) -> str:
        # a summary; cdpm.text.best_tension_text gives the range and the search
        r = self.reach_margin[0]
        margin = (
            f"r_T = {r + 0.0:.4g} {self.margin_unit}" if math.isfinite(r) else "r_T not resolvable"
        )
        return (
            f"Best tension (objective {self.objective}): {self.verdict.upper()}, {margin} "
            f"({self.found_by}; {self.n_yes} of {self.n_candidates} tensions tried POC)\n"
            f"  tension [N]: {named_values(self.cable_names, self.tension)}"
        )


def describe_search(search: TensionSearch, default_method: str, cap: float | None) -> str:
    """The candidates of the search, in words (``cap`` [N]: of the cables
    without an upper bound, None when every cable has one)."""
    refine = (
        f"; then {search.refine_rounds} refinement rounds of {search.refine_samples} samples "
        "within 1/2, 1/4, ... of the way to random points of the polytope"
        if search.objective == "margin"
        else ""
    )
    capped = "" if cap is None else f"; cables without an upper bound capped at {cap:.4g} N"
    return (
        f"candidates: the default tension ({default_method}), the relative interior point, "
        f"the LP vertices of each cable's least and greatest tension, {search.directions} "
        f"vertices of random directions, pretension levels, {search.random_points} random "
        f"points inside the polytope (seed {search.seed}{capped}), each evaluated by the map "
        f"pipeline in one batch{refine}"
    )


def best_tension(
    robot: CableRobot,
    q: Any,
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
) -> BestTension:
    """Whether some feasible equilibrium tension makes the pose q POC, and
    the candidate with the largest reach margin r_T.

    :func:`~cdpm.dynamics.tension_choice.search.best_tension_batch` on a batch of
    one (see there and docs/analysis.md, "Choosing the tension").

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: a pose name, a configuration (nq,) or natural coordinates (nv,).
        objective: ``"poc"`` (is some tension POC; the YES candidate of
            largest r_T is chosen) or ``"margin"`` (also refine the best
            candidate towards a larger r_T).
        horizon: T [s] of the reach margin (default the model's).
        tension_budget: its budget [N] for cables without an upper bound
            (default the model's).
        tension_cap: cap [N] of cables without an upper bound in the search
            (default :func:`~cdpm.dynamics.tension_choice.range.default_tension_cap`).
        seed, directions, random_points, refine_rounds, refine_samples:
            the sampling (:class:`~cdpm.dynamics.tension_choice.search.TensionSearch`).
        tol: angle-like tolerance of the span decisions.

    Returns:
        :class:`BestTension`; its ``linearisation`` and ``poc`` are
        ``cdpm.linearise(robot, q, tension=result.tension)`` and the POC
        result of that linearisation.

    Raises:
        InfeasibleEquilibriumError: no tension within the cable bounds
            holds the pose (nothing to choose from).
        InputError: bad q or settings (an unknown objective, ...).
        ModelError: a cable of zero length or a singular mass matrix at q.
    """
    # scipy: loaded on first use
    from cdpm import analysis

    kin = robot.kinematics(q)  # validates q; raises on a zero-length cable
    natural = robot.to_natural(kin.q)
    batch = best_tension_batch(
        robot,
        natural[None],
        objective,
        horizon=horizon,
        tension_budget=tension_budget,
        tension_cap=tension_cap,
        seed=seed,
        directions=directions,
        random_points=random_points,
        refine_rounds=refine_rounds,
        refine_samples=refine_samples,
        tol=tol,
    )
    rng = batch.ranges[0]
    if rng is not None and not rng.feasible:
        raise InfeasibleEquilibriumError(equilibrium_tension(robot, kin.q, method="min_norm"))
    if batch.found_by[0] == "" or not np.all(np.isfinite(batch.tension[0])):
        status = {v: k for k, v in _status_codes().items()}[int(batch.status[0])]
        if status == "singular_mass_matrix":
            raise ModelError(
                f"mass matrix is singular at q={kin.q.tolist()}: check the URDF inertias"
            )
        why = status.replace("_", " ")
        raise CdpmError(f"the tension search found no tension to analyse at this pose ({why})")
    f = batch.tension[0]
    lin = linearise(robot, kin.q, tension=f)
    poc = analysis.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained, tol=tol
    )
    return BestTension(
        q=kin.q.copy(),
        natural=natural,
        cable_names=tuple(robot.cable_names),
        poc_possible=int(batch.poc_possible[0]),
        tension=f.copy(),
        linearisation=lin,
        poc=poc,
        reach_margin=(float(batch.reach_margin[0]), float(batch.reach_margin_error[0])),
        found_by=batch.found_by[0],
        default_tension=batch.default_tension[0].copy(),
        default_method=batch.default_method,
        default_verdict=int(batch.default_verdict[0]),
        default_margin=float(batch.default_margin[0]),
        tension_range=rng,
        n_candidates=int(batch.n_candidates[0]),
        n_yes=int(batch.n_yes[0]),
        objective=batch.search.objective,
        search=batch.search,
        reach=batch.reach,
        method=describe_search(
            batch.search,
            batch.default_method,
            rng.tension_cap if np.any(~np.isfinite(robot.tension_max)) else None,
        ),
        margin_unit=reach_unit(robot.output_units),
    )


def _status_codes() -> dict[str, int]:
    return STATUS_CODES
