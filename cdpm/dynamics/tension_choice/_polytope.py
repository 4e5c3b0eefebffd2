"""The polytope of equilibrium tensions of one pose, and its LPs.

The feasible equilibrium tensions at a pose are

    P = {f : L^T f = load, f_min <= f <= f_max}        (m cables)

with ``load = -G - w_ext`` (:func:`cdpm.dynamics.equilibrium.statics`). The statics
are solved once, by an SVD of L^T: ``f = f0 + N z`` with ``f0`` the
least-norm solution and ``N`` (m, d) an orthonormal basis of the null
space of L^T, d = m - rank. Every LP here then runs over z with the
bounds as inequalities, so each of its solutions meets the statics to
round-off (or, for cables the null space barely moves, within the
equilibrium solver's statics tolerance: :func:`lp_null_space`), whatever
the LP solver's tolerances. LPs are scipy's HiGHS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpm.dynamics.equilibrium.statics import holds, statics_tolerance
from cdpm.errors import CdpmError
from cdpm.numerics import (
    STATICS_RANK_RTOL,
    STATICS_RTOL,
    TENSION_LP_RTOL,
    TENSION_LP_TOL,
    TENSION_RANGE_RTOL,
)

__all__ = ["Polytope", "LPFailure", "polytope", "solve_lp", "polish"]


def _options(b: np.ndarray) -> dict:
    """HiGHS's feasibility tolerances for an LP with right-hand sides ``b``
    in units of the pose's tension scale (:attr:`Polytope.scale`):
    TENSION_LP_TOL, or TENSION_LP_RTOL times the largest |b| when that is
    more (a tension cap of 1e12 N next to a pose's tens of newtons: 1e-9 of
    the scale is below the round-off of 1e12, and HiGHS stopped with its
    status unknown)."""
    tol = max(TENSION_LP_TOL, TENSION_LP_RTOL * float(np.abs(b).max(initial=0.0)))
    return {"primal_feasibility_tolerance": tol, "dual_feasibility_tolerance": tol}


class LPFailure(CdpmError):
    """HiGHS stopped without an answer (neither optimal, infeasible nor
    unbounded) on a tension LP."""


@dataclass(frozen=True)
class Polytope:
    """The equilibrium tensions of one pose, ``f = f0 + N z`` within bounds.

    Attributes:
        LT: L^T, shape (nv, m).
        load: -G - w_ext, shape (nv,) [N or N m].
        lower, upper: tension bounds [N], each (m,) (upper may be inf).
        f0: least-norm solution of the statics, shape (m,) [N].
        null_space: orthonormal basis N of null(L^T), shape (m, d).
        rank: rank of L^T.
        in_range: the load lies in the range of L^T (within the statics
            tolerance); else no tension at all holds the pose.
        scale: the pose's tension scale [N]: max(the robot's force scale,
            the largest finite |bound|, |f0|); tolerances are relative to
            it, and the LPs solve in its units.
        force: the robot's force scale [N]
            (:attr:`cdpm.model.robot.CableRobot.force_scale`).
    """

    LT: np.ndarray
    load: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    f0: np.ndarray
    null_space: np.ndarray
    rank: int
    in_range: bool
    scale: float
    force: float

    @property
    def tol(self) -> float:
        """TENSION_RANGE_RTOL times the scale [N]: closer than this to a
        bound is on it."""
        return TENSION_RANGE_RTOL * self.scale

    def tension(self, z: np.ndarray) -> np.ndarray:
        """f0 + N z, shape (m,) [N]."""
        return self.f0 + self.null_space @ z


def polytope(
    LT: np.ndarray, load: np.ndarray, lower: np.ndarray, upper: np.ndarray, force: float
) -> Polytope:
    """The pose's :class:`Polytope` from L^T (nv, m), the load (nv,), the
    bounds [N] (m,) and the robot's force scale [N]."""
    nv, m = LT.shape
    if m == 0:
        U, s, Vt = np.zeros((nv, 0)), np.zeros(0), np.zeros((0, 0))
    else:
        U, s, Vt = np.linalg.svd(LT)
    rank = int(np.count_nonzero(s > STATICS_RANK_RTOL * (s[0] if s.size else 0.0)))
    coeff = (U[:, :rank].T @ load) / s[:rank]
    f0 = Vt[:rank].T @ coeff
    null = Vt[rank:].T.copy() if m else np.zeros((0, 0))
    residual = float(np.linalg.norm(LT @ f0 - load))
    tol = float(statics_tolerance(LT[None], load[None], f0[None], force)[0])
    bounds = np.concatenate([lower, upper])
    finite = np.abs(bounds[np.isfinite(bounds)])
    scale = max(force, float(finite.max(initial=0.0)), float(np.abs(f0).max(initial=0.0)))
    return Polytope(LT, load, lower, upper, f0, null, rank, residual <= tol, scale, force)


def solve_lp(
    P: Polytope,
    cost: np.ndarray,
    upper: np.ndarray | None = None,
    extra: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[str, np.ndarray | None, float]:
    """Minimise ``cost . f`` over the polytope (with ``upper`` instead of
    its upper bounds, e.g. capped).

    Args:
        P: the polytope.
        cost: (m,) cost on the tensions, or (m + 1,) with a last entry for
            an extra variable s (then ``extra`` gives its constraints).
        upper: upper bounds [N] (m,); default P.upper.
        extra: (G, g, h) adding rows ``G f + g s <= h`` for the extra
            variable s (G (k, m), g (k,), h (k,)).

    Returns:
        (status, f, s): status ``"optimal"`` (f (m,) the minimiser, s the
        extra variable or NaN), ``"infeasible"`` or ``"unbounded"`` (f None).

    Raises:
        LPFailure: HiGHS stopped for another reason.
    """
    # scipy: loaded on first use
    from scipy.optimize import linprog

    upper = P.upper if upper is None else upper
    N, f0 = lp_null_space(P), P.f0
    m, d = N.shape
    with_s = cost.shape[0] == m + 1
    rows, rhs = [], []
    hi = np.isfinite(upper)
    rows.append(N[hi])
    rhs.append(upper[hi] - f0[hi])
    rows.append(-N)
    rhs.append(f0 - P.lower)
    A = np.vstack(rows)
    b = np.concatenate(rhs)
    if with_s:
        A = np.hstack([A, np.zeros((A.shape[0], 1))])
        if extra is not None:
            G, g, h = extra
            A = np.vstack([A, np.hstack([G @ N, g[:, None]])])
            b = np.concatenate([b, h - G @ f0])
        c = np.concatenate([N.T @ cost[:m], cost[m:]])
    else:
        c = N.T @ cost
    n_var = d + (1 if with_s else 0)
    if n_var == 0:
        ok = bool(np.all(b >= -P.tol))
        return ("optimal", f0.copy(), np.nan) if ok else ("infeasible", None, np.nan)
    # HiGHS's tolerances are absolute: z and s in units of the pose's scale
    b = b / P.scale
    res = linprog(
        c, A_ub=A, b_ub=b, bounds=[(None, None)] * n_var, method="highs", options=_options(b)
    )
    if res.status == 2:
        return "infeasible", None, np.nan
    if res.status == 3:
        return "unbounded", None, np.nan
    if res.status != 0 or res.x is None:
        raise LPFailure(f"the tension LP stopped: {res.message}")
    z = res.x[:d] * P.scale
    return "optimal", f0 + N @ z, float(res.x[d] * P.scale) if with_s else np.nan


def lp_null_space(P: Polytope) -> np.ndarray:
    """The null space the LPs run over, shape (m, d): ``P.null_space``
    with the rows of the cables it moves by at most STATICS_RTOL per newton
    of internal force set to zero.

    Such a cable is fixed at its least-norm tension f0_i by the statics rule
    of the equilibrium solver (:func:`cdpm.dynamics.equilibrium.statics.holds`):
    moving it along the null space changes ``L^T f`` by about STATICS_RTOL
    |L^T| |f - f0|, within the statics tolerance (and :func:`polish` checks
    every tension the LPs give with that rule). So the LPs judge
    feasibility by the same rule as the solver. Left in, such a row is
    below HiGHS's smallest matrix entry (1e-9): HiGHS drops it, and with it
    the cable's bounds, and calls a pose where two cables are opposed to
    within 1e-9 rad infeasible (a least-tension LP "unbounded") although
    zero tension holds it.
    """
    N = P.null_space
    if N.size == 0:
        return N
    fixed = np.abs(N).max(axis=1) <= STATICS_RTOL
    return np.where(fixed[:, None], 0.0, N) if fixed.any() else N


def polish(P: Polytope, f: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
    """``f`` (m,) [N] made an exact member of the polytope (with bounds
    ``upper``): clipped into the bounds, tensions within the tolerance of a
    bound put on it, and the statics residual this leaves taken up by the
    cables strictly inside their bounds (least squares), a few times.

    Returns:
        The tensions (m,) [N], or None when they do not hold the pose
        within the statics tolerance (:func:`cdpm.dynamics.equilibrium.statics.holds`).
    """
    f = np.array(f, dtype=float)
    lower = P.lower
    for _ in range(4):
        f = np.clip(f, lower, upper)
        at_low = f <= lower + P.tol
        at_high = np.isfinite(upper) & (f >= upper - P.tol) & ~at_low
        f = np.where(at_low, lower, np.where(at_high, upper, f))
        r = P.load - P.LT @ f
        free = ~(at_low | at_high)
        tol = statics_tolerance(P.LT[None], P.load[None], f[None], P.force)[0]
        if np.linalg.norm(r) <= 1e-3 * tol:
            break
        if not free.any():
            break
        f[free] += np.linalg.lstsq(P.LT[:, free], r, rcond=None)[0]
    f = np.clip(f, lower, upper)
    if not holds(P.LT[None], P.load[None], f[None], P.force)[0]:
        return None
    return f
