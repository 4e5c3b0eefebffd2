"""Map criteria of the tension search: POC for some feasible tension.

A map made with ``tension="best"`` (``cdpm map ... --tension best``) runs,
beside the default equilibrium's verdicts, the search of
:func:`cdpm.dynamics.tension_choice.best_tension_batch` at every pose and stores

- ``poc_some_tension``: verdict code, YES when some feasible equilibrium
  tension makes the pose POC (NO: none of the candidates tried is);
- ``reach_margin_best``: the reach margin r_T at the chosen tension;
- ``tension_best``: the chosen tension per cable [N].

Other maps leave them NOT_ANALYSED / NaN and spend nothing on them. The
criteria are registered when this module is imported; the map pipeline
(:mod:`cdpm.pipeline.evaluate`, which every worker imports) imports it.
"""

from __future__ import annotations

import numpy as np

from cdpm.dynamics.tension_choice.search import search_tensions
from cdpm.pipeline.criteria import CRITERIA, Criterion, PoseBatch, register
from cdpm.verdicts import NOT_ANALYSED, VERDICT_CODES

__all__ = ["search_result"]


def search_result(batch: PoseBatch):
    """The :class:`~cdpm.dynamics.tension_choice.search.BestTensionBatch` of the
    batch's poses (computed once per batch), or None when the map does not
    ask for the tension search."""
    if batch.tension_search is None:
        return None
    if batch.tension_search_cache is None:
        settings, reach, tol = batch.tension_search
        batch.tension_search_cache = search_tensions(batch.robot, batch.kin, settings, reach, tol)
    return batch.tension_search_cache


def _poc_some_tension(batch: PoseBatch) -> np.ndarray:
    result = search_result(batch)
    if result is None:
        return np.full(len(batch), NOT_ANALYSED, dtype=np.int8)
    return result.poc_possible.astype(np.int8)


def _reach_margin_best(batch: PoseBatch) -> np.ndarray:
    result = search_result(batch)
    return np.full(len(batch), np.nan) if result is None else result.reach_margin.copy()


def _tension_best(batch: PoseBatch) -> np.ndarray:
    result = search_result(batch)
    if result is None:
        return np.full((len(batch), batch.robot.n_cables), np.nan)
    return result.tension.copy()


def _reach_attrs(robot) -> dict:
    """The units of ``reach_margin`` (they are the same quantity)."""
    attrs = CRITERIA["reach_margin"].robot_attrs
    return {} if attrs is None else attrs(robot)


register(
    Criterion(
        "poc_some_tension",
        "int8",
        NOT_ANALYSED,
        "positive output controllability for some feasible equilibrium tension (tension search)",
        _poc_some_tension,
        VERDICT_CODES,
        description="yes: a feasible equilibrium tension (tension_best) makes the pose POC, "
        "certified there; no: none of the candidate tensions tried is POC (sampled, other "
        "tensions may be); not_analysed without the tension search (map with tension='best') "
        "or without any feasible tension (docs/analysis.md, 'Choosing the tension')",
        plot="verdict",
        on_request=True,
    )
)
register(
    Criterion(
        "reach_margin_best",
        "float64",
        np.nan,
        "reach margin r_T at the chosen feasible equilibrium tension (tension search)",
        _reach_margin_best,
        units="m",
        description="r_T (as reach_margin, same horizon and budget) at tension_best: the "
        "largest found among the candidate tensions; NaN without the tension search",
        plot="sequential",
        robot_attrs=_reach_attrs,
        on_request=True,
    )
)
register(
    Criterion(
        "tension_best",
        "float64",
        np.nan,
        "the chosen feasible equilibrium tension of each cable (tension search)",
        _tension_best,
        units="N",
        dims=("cable",),
        description="the tension of poc_some_tension and reach_margin_best; NaN without the "
        "tension search",
        on_request=True,
    )
)
