"""Choosing the equilibrium tension: verdicts that account for it.

With more cables than degrees of freedom the equilibrium tension at a pose
is not unique, and the POC verdict depends on it: which cables are slack
(sign-constrained inputs) and the cable stiffness ``sum f_i Hess(l_i)`` in
A. :func:`tension_range` describes the feasible tensions (LPs: exact);
:func:`best_tension` searches them for a POC tension and the largest reach
margin (sampled; docs/analysis.md, "Choosing the tension");
:func:`best_tension_batch` is the search at many poses, which maps run with
``tension="best"``.
"""

from __future__ import annotations

from cdpm.dynamics.tension_choice.best import EXACT_AND_SAMPLED, BestTension, best_tension
from cdpm.dynamics.tension_choice.range import TensionRange, default_tension_cap, tension_range
from cdpm.dynamics.tension_choice.search import (
    OBJECTIVES,
    BestTensionBatch,
    TensionSearch,
    best_tension_batch,
    tension_search,
)

__all__ = [
    "TensionRange",
    "tension_range",
    "default_tension_cap",
    "BestTension",
    "best_tension",
    "BestTensionBatch",
    "best_tension_batch",
    "TensionSearch",
    "tension_search",
    "OBJECTIVES",
    "EXACT_AND_SAMPLED",
]
