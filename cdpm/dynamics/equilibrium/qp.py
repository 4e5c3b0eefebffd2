"""Least-norm tensions at one pose with an exact QP solver (DAQP), and the
closest tensions in bounds when none holds the pose."""

from __future__ import annotations

from ctypes import c_int

import numpy as np

from cdpm.dynamics.equilibrium.statics import statics_tolerance
from cdpm.errors import MissingExtraError
from cdpm.numerics import STATICS_RANK_RTOL, STATICS_RTOL

__all__ = ["closest_in_bounds", "min_norm_in_bounds"]


def closest_in_bounds(lt, load, lower, upper) -> np.ndarray:
    """Tensions within [lower, upper] minimising |L^T f - load| (BVLS)."""
    # scipy: loaded on first use
    from scipy.optimize import lsq_linear

    pinned = lower >= upper
    f = lower.copy()
    free = ~pinned
    if not free.any():
        return f
    rhs = load - lt[:, pinned] @ lower[pinned]
    sol = lsq_linear(lt[:, free], rhs, bounds=(lower[free], upper[free]), method="bvls")
    f[free] = np.clip(sol.x, lower[free], upper[free])
    return f


def _polish(lt, load, lower, upper, x, force) -> np.ndarray:
    """Fix the cables the solver left on a bound exactly at it and solve the
    statics for the others in least norm (their closed-form optimum)."""
    m = x.shape[0]
    tol = STATICS_RTOL * max(force, float(np.max(np.abs(x), initial=0.0)))
    at_lower = x <= lower + tol
    at_upper = np.isfinite(upper) & (x >= upper - tol) & ~at_lower
    f = x.copy()
    for _ in range(m + 1):
        f[at_lower] = lower[at_lower]
        f[at_upper] = upper[at_upper]
        free = ~(at_lower | at_upper)
        if free.any():
            rhs = load - lt[:, ~free] @ f[~free]
            f[free] = np.linalg.lstsq(lt[:, free], rhs, rcond=None)[0]
        low = free & (f < lower)
        high = free & (f > upper)
        if not (low.any() or high.any()):
            return f
        at_lower |= low
        at_upper |= high
    return np.clip(f, lower, upper)  # pragma: no cover - the loop adds a cable each pass


#: What DAQP's negative exit flags mean, in words (DAQP's documentation).
_DAQP_FAILURES = {
    -2: "cycled between working sets",
    -3: "found the problem unbounded",
    -4: "reached its iteration limit",
    -5: "found the problem not convex",
    -6: "started from an overdetermined working set",
}


def _solver_failure(exitflag: int) -> str:
    """Why the least-norm QP gave no tension, in plain words (the solver's
    status code only where a bug report needs it)."""
    if exitflag == -1:
        return "no tension within the cable bounds balances the load (proved by an exact solver)"
    what = _DAQP_FAILURES.get(exitflag, "failed")
    return (
        f"the equilibrium solver stopped without a tension: it {what} (status {exitflag}; "
        "please report this pose)"
    )


def min_norm_in_bounds(lt, load, lower, upper, force) -> tuple[np.ndarray | None, str]:
    """Least-norm f with L^T f = load and lower <= f <= upper, or None
    (``force``: the robot's force scale [N], which the statics are judged
    relative to: :func:`cdpm.dynamics.equilibrium.statics.statics_tolerance`)."""
    try:
        # daqp: loaded on first use
        import daqp
    except ImportError as exc:  # pragma: no cover - daqp is a core dependency
        raise MissingExtraError(
            "the equilibrium solver needs the 'daqp' package: pip install daqp"
        ) from exc

    m = lt.shape[1]
    # Equalities in an orthonormal basis of the row space of L^T, so the QP
    # solver never sees dependent or badly scaled equality rows.
    u, s, vt = np.linalg.svd(lt, full_matrices=False)
    rank = int(np.count_nonzero(s > STATICS_RANK_RTOL * (s[0] if s.size else 0.0)))
    outside = load - u[:, :rank] @ (u[:, :rank].T @ load)
    tol = statics_tolerance(lt[None], load[None], np.zeros((1, 0)), force)[0]
    if np.linalg.norm(outside) > tol:
        return None, "the load has a component no cable can balance (L^T lacks rank there)"
    eq_matrix = vt[:rank]
    eq_rhs = (u[:, :rank].T @ load) / s[:rank]
    # DAQP's tolerances are absolute: it solves for the tensions in units of
    # the problem's tension scale (the robot's force scale, the least-norm
    # tension or a lower bound, whichever is largest)
    finite_lower = np.abs(lower[np.isfinite(lower)])
    unit = max(force, float(np.abs(eq_rhs).max(initial=0.0)), float(finite_lower.max(initial=0.0)))
    sense = np.array([0] * m + [5] * rank, dtype=c_int)
    x, _, exitflag, _ = daqp.solve(
        np.eye(m),
        np.zeros(m),
        np.ascontiguousarray(eq_matrix),
        np.concatenate([upper / unit, eq_rhs / unit]),
        np.concatenate([lower / unit, eq_rhs / unit]),
        sense,
    )
    if exitflag < 1:
        return None, _solver_failure(int(exitflag))
    x = np.asarray(x, dtype=float) * unit
    return _polish(lt, load, lower, upper, x, force), ""
