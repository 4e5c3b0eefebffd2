"""Least-norm equilibrium tensions of many poses at once (semismooth Newton
on the dual), deciding most poses without a per-pose QP."""

from __future__ import annotations

import numpy as np

from cdpm.numerics import (
    BATCH_NEWTON_STOP_RTOL,
    BATCH_STATICS_RTOL,
    FARKAS_RTOL,
    NEWTON_DAMPING,
    NEWTON_HALVINGS,
    NEWTON_ITERATIONS,
    NEWTON_RIDGE_RTOL,
)

__all__ = ["min_norm_tensions"]


def min_norm_tensions(
    LT: np.ndarray,
    load: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    force: float,
    iterations: int = NEWTON_ITERATIONS,
):
    """Least-norm tensions ``f`` with ``L^T f = load`` and ``lower <= f <= upper``
    at many poses (the problem of :func:`cdpm.dynamics.equilibrium.equilibrium_tension`).

    Semismooth Newton ascent on the dual, with a backtracking line search,
    pose after pose in a compiled loop (:mod:`cdpm.dynamics.equilibrium._newton_kernel`;
    a pose's result depends on that pose alone): the optimum is
    ``f = clip(L lam, lower, upper)`` for the multipliers lam solving
    ``L^T clip(L lam) = load`` (KKT), so a pose whose statics residual
    vanishes has the exact optimum (bounds met exactly). A pose whose
    multipliers run off along a direction v proving
    ``v.load > max_{lower <= f <= upper} v.L^T f`` (Farkas) has no
    equilibrium. Poses with neither are left undecided for the per-pose
    solver.

    Args:
        LT: L^T of each pose, shape (k, nv, m).
        load: the generalised force to balance, -G - w_ext, shape (k, nv).
        lower, upper: tension bounds [N], each (m,) (upper may be inf).
        force: the robot's force scale [N], which the statics are judged
            relative to (:attr:`cdpm.model.robot.CableRobot.force_scale`).
        iterations: Newton steps at most.

    Returns:
        (f (k, m), solved (k,), infeasible (k,)): ``solved`` poses have the
        least-norm tension with a statics residual below BATCH_STATICS_RTOL of the
        statics' scale (max(|load|, |L| max(force, |f|))); ``infeasible`` ones provably have none.
    """
    # scipy: loaded on first use
    from cdpm.dynamics.equilibrium._newton_kernel import solve_poses

    # C-contiguous, writeable float arrays: the kernel's one compiled signature
    LT = np.require(LT, dtype=float, requirements="CW")
    k, nv, m = LT.shape
    load = np.require(load, dtype=float, requirements="CW")
    lower = np.require(np.broadcast_to(lower, (m,)), dtype=float, requirements="CW")
    upper = np.require(np.broadcast_to(upper, (m,)), dtype=float, requirements="CW")
    f = np.empty((k, m))
    solved = np.empty(k, dtype=bool)
    infeasible = np.empty(k, dtype=bool)
    solve_poses(
        LT,
        load,
        lower,
        upper,
        int(iterations),
        NEWTON_HALVINGS,
        NEWTON_DAMPING,
        NEWTON_RIDGE_RTOL,
        BATCH_NEWTON_STOP_RTOL,
        BATCH_STATICS_RTOL,
        FARKAS_RTOL,
        float(force),
        f,
        solved,
        infeasible,
    )
    return f, solved, infeasible
