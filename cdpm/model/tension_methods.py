"""The equilibrium methods a spec, a map and the command line may name.

:data:`EQUILIBRIUM_METHODS` is the one registry of methods. Each method
chooses among the tensions that hold a pose as the least-norm tension in a
box of bounds (or f = 0 for ``zero``); the solver that finds it for many
poses at once is :func:`cdpm.dynamics.equilibrium.methods.solve_equilibria`.
A new method is an entry here: its box (or a solver of its own there). The
registry lives with the model because a spec names its method and is
checked against it when it loads.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["EquilibriumMethod", "EQUILIBRIUM_METHODS", "DEFAULT_METHOD"]

Box = Callable[[np.ndarray, np.ndarray, float], "tuple[np.ndarray, np.ndarray] | None"]


@dataclass(frozen=True)
class EquilibriumMethod:
    """One way to choose the equilibrium tension.

    Attributes:
        name: the name specs, maps and the command line use.
        summary: one line on what it picks.
        uses_pretension: whether the pretension [N] changes its result.
        box: ``(f_min, f_max, pretension) -> (lower, upper)``, the bounds
            [N] (each (m,)) of the least-norm tension it picks; None picks
            f = 0.
    """

    name: str
    summary: str
    uses_pretension: bool
    box: Box | None


def _min_norm_box(fmin, fmax, pretension):
    return fmin, fmax


def _pretension_box(fmin, fmax, pretension):
    return np.maximum(fmin, pretension), fmax


#: name -> method; iterating gives the names in this order
EQUILIBRIUM_METHODS: dict[str, EquilibriumMethod] = {
    m.name: m
    for m in (
        EquilibriumMethod("zero", "f = 0 (no load to balance; the seed paper's case)", False, None),
        EquilibriumMethod(
            "min_norm",
            "the least-norm tension within the bounds (unneeded cables slack)",
            False,
            _min_norm_box,
        ),
        EquilibriumMethod(
            "pretension",
            "the least-norm tension with every cable at least the pretension",
            True,
            _pretension_box,
        ),
    )
}

#: Method used when neither the call nor the spec names one.
DEFAULT_METHOD = "min_norm"
