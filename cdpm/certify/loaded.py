"""POC proven on whole boxes of poses of a robot under load.

Under gravity, an external load or a minimum tension the equilibrium
tension f*(q) varies with the pose and the linearisation is not nilpotent,
so the zero-load proof of :mod:`cdpm.certify.box` does not apply. What
this module proves instead is the mixed-cone exit of the per-pose analyser
(:func:`cdpm.analysis.batch.analyse_systems`, :mod:`cdpm.analysis.poc`):
the *free* cables (strictly inside their tension bounds, so their tension
change takes both signs) alone reach every output direction, whatever the
other cables do. With ``C = [C_q, 0]`` and ``B = [0; -M^-1 L^T]``,
``C B = 0`` and ``C A B = C_q M^-1 (-L^T)`` for every stiffness and
damping block of A, so the free inputs reach every output direction when
the free columns of

    G(q) = C_q(q) M(q)^-1 (-L(q)^T)          (p, m)

have rank p; POC then holds at that pose (docs/analysis.md, free and
one-signed inputs).

The proof on a box Q (docs/analysis.md, "Certified boxes") has two parts.

1. **The equilibrium's active set is constant on Q.** The methods
   ``min_norm`` and ``pretension`` pick the least-norm f with
   ``L^T f = load`` (load = -G - w_ext) in a box of bounds [lower, upper]
   (:data:`cdpm.model.tension_methods.EQUILIBRIUM_METHODS`). Its KKT
   conditions with a split of the cables into free ones F and ones fixed
   at a bound (S_lo at lower, S_up at upper, tensions f_S) are: with
   ``N = L_F^T L_F`` invertible and ``lambda = N^-1 (load - L_S^T f_S)``,
   ``f_F = L_F lambda`` lies strictly inside (lower, upper) and the
   multipliers are positive (``(L lambda)_i < lower_i`` on S_lo,
   ``> upper_i`` on S_up). The problem is strictly convex, so this f is the
   one tension the method picks at every pose where these inequalities
   hold. The split is read off the equilibrium at the box's centre
   (cdpm's own solver) and the inequalities are proven on all of Q with
   interval enclosures (:func:`cdpm.certify.kinematics.box_jets`). The
   KKT system is solved in the scaled form ``[[alpha I, W L], [L^T W, 0]]
   (f_F, -alpha lambda) = (0, load - L^T f_S)`` (W = diag(free), alpha
   L_F's smallest singular value at the centre), whose condition number
   is about L_F's where N's is its square, by a mean-value form (``dz =
   K^-1 (db - dK z)``) with K^-1 enclosed over Q (:func:`_inverse_over_box`:
   entrywise Neumann bounds, and a norm bound in the centre's
   eigen-scaling that keeps the signs the entrywise one loses); the
   multipliers ``L lambda - f_S`` get a mean-value form of their own. Each
   inequality holds with a gap of CERTIFY_TENSION_GAP_RTOL times the
   tension scale. The solver's first try, the box's least-norm corner f =
   lower, must fail its statics test at every pose (its residual is
   bounded below), or it would be taken.
2. **The free cables reach every output.** A cable is free for the
   analysis when f* lies strictly inside the robot's bounds (f_min, f_max)
   (:func:`cdpm.dynamics.equilibrium.statics.classify`; a cable held at the
   pretension above f_min is free). With G's enclosure over Q (mean-value
   form as in :mod:`cdpm.certify.box`, C_q widened by the analyser's
   round-off rounding, OUTPUT_JACOBIAN_ZERO_RTOL), the free columns G_F
   scaled by fixed factors s_j (1 / |g_j(q_c)|) satisfy ``sigma_p(G_F(q)
   S) >= sigma_p(mid) - |spread|_F``; divided by the longest scaled column
   over Q this bounds the smallest singular value of the unit-column
   matrix below, which must exceed CERTIFY_FREE_RANK_MIN, a thousand
   times the analyser's rank thresholds (its Krylov rank test scales the
   columns to unit length too).

Besides: every cable segment is longer than MIN_SEGMENT_LENGTH and the
mass matrix's condition number stays below MASS_COND_MAX on Q (the
analyser's status tests).

Everything else is MARGINAL with the first failing condition as reason.
The proof is a recomputation from the model and the box:
:func:`verify_loaded` runs it again. The reach margin is not bounded over
a loaded box (its linearisation's exponential would need enclosures of the
stiffness): ``margin_lower`` is 0, true and trivial.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cdpm.certify.interval import Interval, matmul
from cdpm.certify.inverse import inverse_enclosures, inverse_over_box, norm_upper
from cdpm.certify.jet import Jet, mean_value
from cdpm.certify.kinematics import box_jets, check_boxes
from cdpm.errors import InputError
from cdpm.numerics import (
    CERTIFY_FREE_RANK_MIN,
    CERTIFY_TENSION_GAP_RTOL,
    MASS_COND_MAX,
    MIN_SEGMENT_LENGTH,
    OUTPUT_JACOBIAN_ZERO_RTOL,
    STATICS_RTOL,
)
from cdpm.verdicts import MARGINAL, YES

__all__ = ["loaded_reason", "certify_loaded", "verify_loaded"]

_EPS = float(np.finfo(float).eps)
_BETA = 10.0

#: the methods whose equilibrium is the least-norm tension in a box of bounds
_LEAST_NORM = ("min_norm", "pretension")


def loaded_reason(robot: Any) -> str:
    """Why loaded boxes cannot be certified for this robot, or "" when
    they can: its spec's equilibrium method must pick the least-norm
    tension in bounds (``min_norm`` or ``pretension``) and its joints must
    be ones certified boxes support (revolute, prismatic, fixed)."""
    from cdpm.dynamics.equilibrium import resolve_method

    method, _ = resolve_method(robot, None, None)
    if method not in _LEAST_NORM:
        return (
            f"the equilibrium method {method!r} is not a least-norm tension in bounds; loaded "
            f"boxes are certified for {' and '.join(_LEAST_NORM)}"
        )
    centre = np.zeros((1, robot.nv))
    try:
        box_jets(robot, centre, centre)
    except InputError as exc:
        return str(exc)
    return ""


def certify_loaded(
    robot: Any, lower: Any, upper: Any, reach: Any = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Prove POC on each box of a batch of a loaded robot (module
    docstring), or say why not.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` with
            ``loaded_reason(robot) == ""``.
        lower, upper: the boxes' corners, natural coordinates (B, nv)
            [rad or m] (the caller checks them against the joint limits).
        reach: the reach margin's :class:`~cdpm.dynamics.reach.ReachSettings`
            (unused: the bound returned is the trivial 0).

    Returns:
        (verdict (B,) int8: YES or MARGINAL; reason (B,) str: how it was
        proven, or the first condition that failed; margin_lower (B,)
        float: 0.0 for YES boxes (a true, trivial lower bound of the reach
        margin), NaN for the others).

    Raises:
        InputError: corners of the wrong shape, not finite or lower >
            upper; a robot :func:`loaded_reason` refuses.
    """
    del reach  # the margin bound is trivial (module docstring)
    why = loaded_reason(robot)
    if why:
        raise InputError(f"loaded boxes cannot be certified for this robot: {why}")
    lo, hi = _boxes(robot, lower, upper)
    proven, reason = _prove(robot, lo, hi)
    verdict = np.where(proven, YES, MARGINAL).astype(np.int8)
    margin = np.where(proven, 0.0, np.nan)
    return verdict, reason.astype(str), margin


def verify_loaded(robot: Any, lower: Any, upper: Any) -> np.ndarray:
    """Re-check loaded YES proofs: the proof of :func:`certify_loaded`
    recomputed from the model on each box, (B,) bool (False where it does
    not go through, or for a robot :func:`loaded_reason` refuses)."""
    if loaded_reason(robot):
        return np.zeros(np.shape(lower)[0] if np.ndim(lower) == 2 else 1, dtype=bool)
    lo, hi = _boxes(robot, lower, upper)
    return _prove(robot, lo, hi)[0]


# --------------------------------------------------------------------------
# the proof


def _boxes(robot: Any, lower: Any, upper: Any) -> tuple[np.ndarray, np.ndarray]:
    """The corners as (B, nv) float arrays, finite, lower <= upper
    (:func:`cdpm.certify.kinematics.check_boxes`, boxes only in a batch)."""
    if np.ndim(lower) != 2 or np.ndim(upper) != 2:
        raise InputError(
            f"boxes need (B, {robot.nv}) lower and upper natural coordinates "
            f"({', '.join(robot.coordinate_names)}); got shapes {np.shape(lower)} and "
            f"{np.shape(upper)}"
        )
    lo, hi, _ = check_boxes(robot, lower, upper)
    return lo, hi


def _split(name: str, at_centre: dict, over_box: dict, radius: np.ndarray):
    """(value at the centre, mean-value enclosure over the box, derivative
    enclosure with the derivative axis second: (B, nv, ...)) of a quantity."""
    centre = at_centre[name]
    jet = over_box[name]
    if not isinstance(jet, Jet):  # constant over the box
        grad = Interval(np.zeros(centre.shape + (radius.shape[1],)))
        return centre, jet, grad.moveaxis(-1, 1)
    return centre, mean_value(centre, jet, radius), jet.grad.moveaxis(-1, 1)


def _spread(grad: Interval, radius: np.ndarray) -> Interval:
    """``sum_k grad_k [-h_k, h_k]`` for derivatives (B, nv, ...)."""
    r = radius.reshape(radius.shape + (1,) * (grad.ndim - 2))
    return (grad * Interval(-r, r)).sum(axis=1)


def _norm_lower(x: Interval) -> np.ndarray:
    """A lower bound of |v| over every v in the interval vectors x (B, n)."""
    gap = np.where((x.lo > 0) | (x.hi < 0), np.minimum(np.abs(x.lo), np.abs(x.hi)), 0.0)
    return np.nextafter(np.sqrt(np.sum(gap * gap, axis=-1)) * (1 - 4 * _EPS), 0.0)


def _centre_split(robot: Any, lo: np.ndarray, hi: np.ndarray, lower, upper):
    """The equilibrium at each box's centre by cdpm's own solver, and its
    split of the cables against the method's bounds: (feasible (B,),
    at_lo (B, m), at_hi (B, m))."""
    from cdpm.dynamics.equilibrium import equilibrium_tensions, statics
    from cdpm.model.poses import configurations

    centre = np.clip(0.5 * lo + 0.5 * hi, lo, hi)
    kin = robot.kinematics_batch(configurations(robot, centre), dynamics=True)
    seg = kin.segment_lengths.min(axis=1, initial=np.inf)
    ok = seg >= MIN_SEGMENT_LENGTH
    B, m = lo.shape[0], robot.n_cables
    at_lo = np.zeros((B, m), dtype=bool)
    at_hi = np.zeros((B, m), dtype=bool)
    feasible = np.zeros(B, dtype=bool)
    if not ok.any():
        return feasible, at_lo, at_hi
    LT, load = statics(robot, kin)
    eq = equilibrium_tensions(robot, LT[ok], load[ok])
    f = eq.tension
    scale = np.maximum(robot.force_scale, np.abs(f))
    at_lo[ok] = f <= lower + STATICS_RTOL * scale
    at_hi[ok] = np.isfinite(upper) & (f >= upper - STATICS_RTOL * scale) & ~at_lo[ok]
    feasible[ok] = eq.feasible
    return feasible, at_lo, at_hi


def _prove(robot: Any, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(proven (B,) bool, reason (B,) object): the module docstring's
    proof on each box."""
    from cdpm.dynamics.equilibrium import resolve_method
    from cdpm.model.tension_methods import EQUILIBRIUM_METHODS

    B, nv = lo.shape
    m = robot.n_cables
    reason = np.full(B, "", dtype=object)
    if B == 0:
        return np.zeros(0, dtype=bool), reason
    method, pretension = resolve_method(robot, None, None)
    fmin, fmax = robot.tension_min, robot.tension_max
    lower, upper = EQUILIBRIUM_METHODS[method].box(fmin, fmax, pretension)
    force = robot.force_scale

    def fail(mask: np.ndarray, why: str) -> None:
        reason[(reason == "") & mask] = why

    # the active set at each box's centre
    feasible, at_lo, at_hi = _centre_split(robot, lo, hi, lower, upper)
    fail(~feasible, "no tension in bounds holds the box's centre (no equilibrium)")
    free = ~(at_lo | at_hi)  # free in the method's box (the QP's active set)
    fixed = np.where(at_lo, lower, np.where(at_hi, np.where(np.isfinite(upper), upper, 0.0), 0.0))

    at_centre, over_box, radius = box_jets(robot, lo, hi)
    vanish = np.asarray(over_box["segment_may_vanish"]).reshape(B)
    seg = over_box["segment_lengths"]
    seg_lo = (seg.val if isinstance(seg, Jet) else seg).lo
    fail(
        vanish | ~np.all(seg_lo > MIN_SEGMENT_LENGTH, axis=1),
        "a cable segment may be shorter than MIN_SEGMENT_LENGTH in the box",
    )
    L_c, L_b, dL = _split("jacobian", at_centre, over_box, radius)  # (B, m, nv), (B, k, m, nv)
    G_c, G_b, dG = _split("gravity", at_centre, over_box, radius)  # (B, nv), (B, k, nv)
    w_ext = robot.external_wrench
    load_c, load_b, dload = -G_c - w_ext, -G_b - w_ext, -dG
    M_c, M_b, dM = _split("mass_matrix", at_centre, over_box, radius)
    C_c, C_b, dC = _split("output_jacobian", at_centre, over_box, radius)

    # mass matrix: regular for the analyser (condition number below MASS_COND_MAX)
    Minv_b, why_m = inverse_over_box(M_b, M_c, dM, radius)
    fail(
        (why_m != "") | ~_mass_regular(M_b, Minv_b),
        "the mass matrix may be singular (ill-conditioned) in the box",
    )

    # 1. the active set: the scaled KKT system of the least-norm tension,
    # K z = b with K = [[alpha I, W L], [L^T W, 0]] (W = diag(free)),
    # b = [0; load - L^T f_S]: z = (f_F, mu) with mu = -alpha lambda (0 on
    # the fixed cables). Its condition number is about L_F's (alpha its
    # smallest singular value at the centre), where the normal matrix
    # L_F^T L_F would square it
    w = free.astype(float)
    fS = fixed
    Lw_c = L_c.midpoint * w[:, :, None]
    sv = np.linalg.svd(Lw_c, compute_uv=False)[:, -1] if m >= nv else np.zeros(B)
    alpha = np.where(sv > 0, sv, 1.0)
    corner = np.broadcast_to(alpha[:, None], (B, m))
    K_c = _kkt(L_c * w[:, :, None], corner)
    K_b = _kkt(L_b * w[:, :, None], corner)
    dK = _kkt(dL * w[:, None, :, None], np.zeros(dL.shape[:2] + (m,)))  # (B, k, m+nv, m+nv)
    top = Interval(np.zeros((B, m)))

    def rhs(L: Interval, load: Interval) -> Interval:
        return _concat(top, load - matmul(L.mT, fS[:, :, None])[..., 0])

    Kinv_c, why_c = inverse_enclosures(K_c)
    Kinv_b, why_b = inverse_over_box(K_b, K_c, dK, radius)
    fail(
        (why_c != "") | (why_b != ""),
        "the free cables' Jacobian L_F may lose rank in the box (fewer free cables than "
        "degrees of freedom, or a box too wide for the enclosure of the tensions)",
    )
    z_c = matmul(Kinv_c, rhs(L_c, load_c)[..., None])[..., 0]  # (B, m + nv)
    z_b = matmul(Kinv_b, rhs(L_b, load_b)[..., None])[..., 0]
    # dz_k = K^-1 (db_k - dK_k z), db_k = [0; d load_k - dL_k^T f_S]
    d_r = dload - matmul(dL.mT, fS[:, None, :, None])[..., 0]  # (B, k, nv)
    d_b = _concat(Interval(np.zeros(d_r.shape[:2] + (m,))), d_r)
    d_z = d_b - matmul(dK, z_b[:, None, :, None])[..., 0]
    dz = matmul(Kinv_b[:, None], d_z[..., None])[..., 0]  # (B, k, m + nv)
    z = z_c + _spread(dz, radius)
    z = Interval._raw(np.maximum(z.lo, z_b.lo), np.minimum(z.hi, z_b.hi))
    # g = L lambda - f_S: f on the free cables (where z holds it too, often
    # far tighter: lambda is large where L_F is ill-conditioned), minus the
    # multiplier on the fixed ones; a mean-value form with lambda = -mu / alpha
    lam_c = z_c[:, m:] * (-1.0 / alpha)[:, None]
    lam = z[:, m:] * (-1.0 / alpha)[:, None]
    dlam = dz[:, :, m:] * (-1.0 / alpha)[:, None, None]
    dg = matmul(dL, lam[:, None, :, None])[..., 0] + matmul(L_b[:, None], dlam[..., None])[..., 0]
    g = matmul(L_c, lam_c[..., None])[..., 0] + _spread(dg, radius) - fS
    y = z[:, :m]
    g = Interval._raw(
        np.where(free, np.maximum(g.lo, y.lo), g.lo), np.where(free, np.minimum(g.hi, y.hi), g.hi)
    )
    bad = ~np.all(np.isfinite(g.lo) & np.isfinite(g.hi), axis=1)
    g = Interval._raw(np.where(bad[:, None], -np.inf, g.lo), np.where(bad[:, None], np.inf, g.hi))
    finite_fixed = np.where(free, 0.0, np.abs(fS))
    scale = np.maximum(force, np.max(np.where(free, g.magnitude, finite_fixed), axis=1))
    gap = CERTIFY_TENSION_GAP_RTOL * scale[:, None]  # (B, 1)
    inside = (g.lo > lower + gap) & (g.hi < upper - gap)
    pulls = np.where(at_lo, g.hi < -gap, np.where(at_hi, g.lo > gap, True))
    fail(
        np.any(free & ~inside, axis=1),
        "a free cable's equilibrium tension may reach its bound in the box (the tensions' "
        "active set may change)",
    )
    fail(
        np.any(~free & ~pulls, axis=1),
        "a cable on its bound may leave it in the box (its multiplier may vanish: the "
        "tensions' active set may change)",
    )
    # the solver's first try, f = lower, must not hold any pose of the box
    corner = matmul(L_b.mT, np.broadcast_to(lower, (B, m))[:, :, None])[..., 0] - load_b
    frob = norm_upper(L_b.magnitude, (1, 2))
    corner_tol = STATICS_RTOL * np.maximum(
        norm_upper(load_b.magnitude, 1), frob * max(force, float(np.linalg.norm(lower)))
    )
    fail(
        ~(_norm_lower(corner) > corner_tol * (1 + 1e-6)),
        "the least-norm corner of the bounds (f = lower) may hold a pose of the box",
    )

    # 2. the free cables (strictly inside (f_min, f_max) for the analyser)
    f_lo = np.where(free, g.lo, fS)
    f_hi = np.where(free, g.hi, fS)
    f_scale = np.maximum(force, np.maximum(np.abs(f_lo), np.abs(f_hi)))
    analysed_free = (f_lo > fmin + CERTIFY_TENSION_GAP_RTOL * f_scale) & (
        f_hi < fmax - CERTIFY_TENSION_GAP_RTOL * f_scale
    )
    ratio = _free_rank(robot, analysed_free, L_c, L_b, dL, M_c, Minv_b, dM, C_c, C_b, dC, radius)
    fail(
        ~(ratio > CERTIFY_FREE_RANK_MIN),
        f"the free cables may not reach every output direction in the box (their unit output "
        f"directions' smallest singular value is not proven above {CERTIFY_FREE_RANK_MIN:g})",
    )
    proven = reason == ""
    n_free = analysed_free.sum(axis=1)
    for b in np.flatnonzero(proven):
        reason[b] = (
            f"{n_free[b]} of {m} cables stay strictly inside their tension bounds at every pose "
            f"of the box (constant active set) and their inputs alone reach every output "
            f"direction (unit-column singular value >= {ratio[b]:.3g}); reach margin bound "
            "not computed under load (0)"
        )
    return proven, reason


def _kkt(WL: Interval, corner: np.ndarray) -> Interval:
    """The block matrix ``[[diag(corner), WL], [WL^T, 0]]`` for matrices WL
    (..., m, nv) and the diagonal ``corner`` (..., m): (..., m + nv, m + nv)."""
    pre, (m, nv) = WL.shape[:-2], WL.shape[-2:]
    lo = np.zeros(pre + (m + nv, m + nv))
    hi = np.zeros(pre + (m + nv, m + nv))
    eye = np.eye(m) * np.asarray(corner)[..., None, :]
    for out, part in ((lo, WL.lo), (hi, WL.hi)):
        out[..., :m, :m] = eye
        out[..., :m, m:] = part
        out[..., m:, :m] = np.swapaxes(part, -1, -2)
    return Interval._raw(lo, hi)


def _concat(a: Interval, b: Interval) -> Interval:
    """Intervals a (..., i) and b (..., j) joined along the last axis."""
    return Interval._raw(np.concatenate([a.lo, b.lo], -1), np.concatenate([a.hi, b.hi], -1))


def _mass_regular(M: Interval, inverse: Interval) -> np.ndarray:
    """Whether every matrix in each enclosure M (B, n, n) has condition
    number below MASS_COND_MAX: |M|_2 |M^-1|_2, each bounded by the
    Frobenius norm of its enclosure's magnitudes (``inverse``: an
    enclosure of M^-1)."""
    with np.errstate(over="ignore", invalid="ignore"):
        cond = norm_upper(M.magnitude, (1, 2)) * norm_upper(inverse.magnitude, (1, 2))
    return cond * (1 + 1e-12) < MASS_COND_MAX


def _free_rank(robot, free, L_c, L_b, dL, M_c, Mb_inv, dM, C_c, C_b, dC, radius) -> np.ndarray:
    """A lower bound (B,) over each box of the smallest singular value of
    the free columns of G = C_q M^-1 (-L^T) scaled to unit length (0 where
    none is proven): ``(sigma_p(G_F(q_c)) - |G_F - G_F(q_c)|_F) / max_j
    |g_j|`` over the box."""
    B, m = free.shape
    p = C_c.shape[1]
    out = np.zeros(B)
    if p == 0:
        return np.full(B, np.inf)
    Mc_inv, why_c = inverse_enclosures(M_c)
    ok = (why_c == "") & (free.sum(axis=1) >= p)
    # the analyser's C_q has round-off entries zeroed: within this of the true one
    floor = OUTPUT_JACOBIAN_ZERO_RTOL * np.asarray(robot.output_scales, dtype=float)
    rounding = Interval(-floor, floor)[None, :, None]
    G_c = matmul(C_c + rounding, matmul(Mc_inv, -L_c.mT))
    X = matmul(Mb_inv, -L_b.mT)  # M^-1 (-L^T) over the box (B, nv, m)
    CMinv = matmul(C_b, Mb_inv)  # (B, p, nv)
    part = (
        matmul(dC, X[:, None])
        - matmul(CMinv[:, None], matmul(dM, X[:, None]))
        + matmul(CMinv[:, None], -dL.mT)
    )  # (B, k, p, m)
    G = G_c + _spread(part, radius) + matmul(rounding, X)
    G_naive = matmul(C_b + rounding, X)
    G = Interval._raw(np.maximum(G.lo, G_naive.lo), np.minimum(G.hi, G_naive.hi))
    finite = np.all(np.isfinite(G.lo) & np.isfinite(G.hi), axis=(1, 2))
    ok &= finite
    if not ok.any():
        return out
    # columns scaled by the inverse of their length at the centre (any fixed
    # scaling s > 0 is valid: sigma_min(G_F D^-1) >= sigma_min(G_F S) /
    # max_j s_j |g_j| with D the columns' lengths)
    w = free[ok][:, None, :]
    centre_len = np.sqrt(np.sum(G_c.midpoint[ok] ** 2, axis=1))  # (b, m)
    s_col = np.where(
        free[ok] & (centre_len > 0), 1.0 / np.where(centre_len > 0, centre_len, 1.0), 0.0
    )
    Gs = G[ok] * s_col[:, None, :]
    lo_, hi_ = np.where(w, Gs.lo, 0.0), np.where(w, Gs.hi, 0.0)
    mid = np.clip(0.5 * lo_ + 0.5 * hi_, lo_, hi_)
    spread = np.maximum(hi_ - mid, mid - lo_)
    sv = np.linalg.svd(mid, compute_uv=False)  # (b, p)
    size = p + m
    sigma = sv[:, p - 1] - 8 * size * _EPS * sv[:, 0] - norm_upper(spread, (1, 2))
    mag = np.maximum(np.abs(lo_), np.abs(hi_))
    col = norm_upper(mag, 1).max(axis=1)  # the longest scaled free column over the box
    with np.errstate(divide="ignore", invalid="ignore"):
        out[ok] = np.where((sigma > 0) & (col > 0), sigma / col, 0.0)
    return out
