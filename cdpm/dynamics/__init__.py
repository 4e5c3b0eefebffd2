"""The robot's dynamics about a pose: equilibrium tensions
(:mod:`~cdpm.dynamics.equilibrium`), the linearisation
(:mod:`~cdpm.dynamics.linearisation`), the reach margin's settings and scales
(:mod:`~cdpm.dynamics.reach`), the choice of tension
(:mod:`~cdpm.dynamics.tension_choice`) and the simulation of the nonlinear
robot (:mod:`~cdpm.dynamics.simulation`).

Only the equilibrium and the linearisation are re-exported here: the other
modules load SciPy, which a map's worker does not need.
"""

from cdpm.dynamics.equilibrium import (
    EquilibriumResult,
    EquilibriumWarning,
    InfeasibleEquilibriumError,
    check_equilibrium,
    equilibrium_tension,
)
from cdpm.dynamics.linearisation import Linearisation, linearise

__all__ = [
    "EquilibriumResult",
    "EquilibriumWarning",
    "InfeasibleEquilibriumError",
    "check_equilibrium",
    "equilibrium_tension",
    "Linearisation",
    "linearise",
]
