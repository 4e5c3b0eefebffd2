"""The equilibrium methods and the batched solver every caller uses.

:data:`EQUILIBRIUM_METHODS` is the one registry of methods: a spec, a map
and the command line accept its names. Each method chooses among the
tensions that hold a pose as the least-norm tension in a box of bounds (or
f = 0 for ``zero``); :func:`solve_equilibria` finds it for many poses at
once, and :func:`cdpm.equilibrium_tension` is that function on one pose.
A new method is an entry here: its box (or a solver of its own).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from cdpm.dynamics.equilibrium.newton import min_norm_tensions
from cdpm.dynamics.equilibrium.qp import min_norm_in_bounds
from cdpm.dynamics.equilibrium.statics import classify, holds, input_signs, residuals
from cdpm.model.tension_methods import DEFAULT_METHOD, EQUILIBRIUM_METHODS, EquilibriumMethod

__all__ = [
    "EquilibriumMethod",
    "EquilibriumBatch",
    "EQUILIBRIUM_METHODS",
    "DEFAULT_METHOD",
    "HOW",
    "solve_equilibria",
]

#: how each pose's tension was found (:attr:`EquilibriumBatch.how`)
HOW = {
    "given": 0,  # tensions given by the caller
    "zero": 1,  # f = 0 (method zero)
    "box_corner": 2,  # the box's least-norm corner holds the pose
    "solved": 3,  # least-norm tension in the box (batched Newton or the QP)
    "bound_conflict": 4,  # the pretension exceeds a cable's maximum tension
    "infeasible": 5,  # proved: no tension in the box holds the pose
    "solver_failed": 6,  # the QP stopped without a tension
}


@dataclass(frozen=True)
class EquilibriumBatch:
    """Equilibrium tensions of N poses.

    Attributes:
        tension: tensions [N], shape (N, m) (infeasible poses: the box's
            least-norm corner or the solver's last iterate).
        feasible: the tensions hold the pose within the bounds, shape (N,).
        residual: statics residual |L^T f + G + w_ext| [N or N m], shape (N,).
        at_lower_bound, at_upper_bound, taut: cable states, each (N, m)
            (:func:`cdpm.dynamics.equilibrium.statics.classify`).
        how: a :data:`HOW` code per pose, shape (N,).
        method: the method name (``given`` for given tensions).
        pretension: the pretension the method used [N].
    """

    tension: np.ndarray
    feasible: np.ndarray
    residual: np.ndarray
    at_lower_bound: np.ndarray
    at_upper_bound: np.ndarray
    taut: np.ndarray
    how: np.ndarray
    method: str
    pretension: float

    @property
    def sign_constrained(self) -> np.ndarray:
        """Cables on a bound (one-signed tension change), shape (N, m)."""
        return self.at_lower_bound | self.at_upper_bound

    @property
    def input_sign(self) -> np.ndarray:
        """+1 at the lower bound, -1 at the upper one, 0 free, shape (N, m)."""
        return input_signs(self.at_lower_bound, self.at_upper_bound)

    def take(self, idx) -> EquilibriumBatch:
        """The equilibria of the poses ``idx`` (indices or a boolean mask)."""
        return dataclasses.replace(
            self,
            **{
                f.name: getattr(self, f.name)[idx]
                for f in dataclasses.fields(self)
                if isinstance(getattr(self, f.name), np.ndarray)
            },
        )


def solve_equilibria(
    LT: np.ndarray,
    load: np.ndarray,
    fmin: np.ndarray,
    fmax: np.ndarray,
    method: str | np.ndarray,
    pretension: float = 0.0,
    *,
    force: float,
) -> EquilibriumBatch:
    """Equilibrium tensions of many poses by one method (or given tensions).

    The least-norm methods try the box's least-norm corner (f = lower),
    then the batched Newton solver (:func:`~cdpm.dynamics.equilibrium.newton.min_norm_tensions`),
    then the exact QP (DAQP) for the poses Newton leaves undecided.

    Args:
        LT: L^T at each pose, shape (N, nv, m).
        load: the generalised force to balance, -G - w_ext, shape (N, nv).
        fmin, fmax: tension bounds [N], each (m,).
        method: a name in :data:`EQUILIBRIUM_METHODS` (validated by the
            caller), or given tensions [N] of shape (m,).
        pretension: least tension for methods that use one [N].
        force: the robot's force scale [N], which the statics are judged
            relative to (:attr:`cdpm.model.robot.CableRobot.force_scale`).

    Returns:
        :class:`EquilibriumBatch`.
    """
    k, m = LT.shape[0], LT.shape[2]
    how = np.empty(k, dtype=np.int8)
    if not isinstance(method, str):
        f = np.tile(np.asarray(method, dtype=float), (k, 1))
        in_bounds = bool(np.all((f[0] >= fmin) & (f[0] <= fmax))) if k else True
        feasible = holds(LT, load, f, force) & in_bounds
        how[:] = HOW["given"]
        return _batch(LT, load, f, feasible, how, fmin, fmax, "given", 0.0, force)
    box = EQUILIBRIUM_METHODS[method].box
    used = pretension if EQUILIBRIUM_METHODS[method].uses_pretension else 0.0
    if box is None:
        f = np.zeros((k, m))
        feasible = holds(LT, load, f, force) & bool(np.all(fmin <= 0))
        how[:] = HOW["zero"]
        return _batch(LT, load, f, feasible, how, fmin, fmax, method, used, force)
    lower, upper = box(fmin, fmax, pretension)
    if np.any(lower > upper):
        f = np.tile(np.minimum(lower, upper), (k, 1))
        how[:] = HOW["bound_conflict"]
        return _batch(
            LT, load, f, np.zeros(k, bool), how, fmin, fmax, method, used, force, (lower, upper)
        )
    if not np.any(lower) and not np.any(load):
        # no load and a box with corner 0: f = 0 holds every pose exactly
        how[:] = HOW["box_corner"]
        return _batch(
            LT, load, np.zeros((k, m)), np.ones(k, bool), how, fmin, fmax, method, used, force
        )
    f = np.tile(lower, (k, 1))
    feasible = holds(LT, load, f, force)  # the box's least-norm point holds the pose
    how[:] = HOW["box_corner"]
    rest = np.flatnonzero(~feasible)
    if rest.size:
        f_rest, solved, infeasible = min_norm_tensions(LT[rest], load[rest], lower, upper, force)
        f[rest] = f_rest
        feasible[rest] = solved & holds(LT[rest], load[rest], f_rest, force)
        how[rest] = np.where(feasible[rest], HOW["solved"], HOW["infeasible"])
        for i in rest[~solved & ~infeasible]:
            x, _ = min_norm_in_bounds(LT[i], load[i], lower, upper, force)
            if x is None:
                how[i] = HOW["solver_failed"]
                continue
            f[i] = x
            feasible[i] = bool(holds(LT[i : i + 1], load[i : i + 1], x[None], force)[0])
            how[i] = HOW["solved"] if feasible[i] else HOW["infeasible"]
    return _batch(LT, load, f, feasible, how, fmin, fmax, method, used, force, (lower, upper))


def _batch(
    LT, load, f, feasible, how, fmin, fmax, method, pretension, force, box=None
) -> EquilibriumBatch:
    at_lower, at_upper, _ = classify(f, fmin, fmax, force)
    if method != "given":
        # a solved cable on a bound sits exactly on it (round-off apart,
        # the solvers leave it within STATICS_RTOL), never outside the
        # method's own box: a pretension below the bound test's resolution
        # (STATICS_RTOL times a huge robot's force scale) stays as asked
        low, high = (
            (fmin, fmax)
            if box is None
            else (np.clip(fmin, box[0], box[1]), np.clip(fmax, box[0], box[1]))
        )
        f = np.where(at_lower, low, np.where(at_upper, high, f))
    taut = f > 0
    exact = not np.any(f) and not np.any(load)  # nothing to balance, nothing pulling
    return EquilibriumBatch(
        tension=f,
        feasible=feasible,
        residual=np.zeros(f.shape[0]) if exact else residuals(LT, load, f),
        at_lower_bound=at_lower,
        at_upper_bound=at_upper,
        taut=taut,
        how=how,
        method=method if isinstance(method, str) else "given",
        pretension=float(pretension),
    )
