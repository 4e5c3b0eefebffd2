"""A verdict proven on a whole box of poses: :func:`certify_box`.

The per-pose analysis decides positive output controllability (POC,
seed paper Theorem 1) at one pose. A box ``Q = [lower, upper]`` of natural
coordinates is *certified* YES when a proof covers every pose in it, and
certified NO when one vector separates the inputs from some output
direction at every pose in it (shared THEORY.md section 6).

The case certified here is the seed paper's: **zero load** (no gravity, no
external load, every tension bound from 0), so the equilibrium tension is
f* = 0, every cable sits on its lower bound (a one-signed input), the
cable stiffness vanishes, and with no joint damping the linearisation is
nilpotent: ``C B = 0`` and POC holds iff the columns g_j of

    G(q) = C_q(q) M(q)^-1 (-L(q)^T)         (p, m)

positively span R^p. The proof works in direction space. Every unit
direction v is a positive multiple of some w on a face of the cube
``[-1, 1]^p`` (``w_k = +-1``, the other entries ``t`` in ``[-1, 1]``). The
faces are cut into patches (boxes of t), and for each patch one column j
is found with ``w . g_j(q) > 0`` for every w in the patch and every q in
Q, using interval enclosures of G over Q
(:func:`cdpm.certify.kinematics.box_kinematics`, mean-value form, round-off
included) and of M^-1 (a Neumann bound around the inverse of the midpoint
matrix). Patches that no column proves are bisected, down to a least size.
When every patch is proven, every direction has a column pointing into it
at every pose: POC YES on all of Q. The same enclosures give a lower bound
of the reach margin over Q: ``r_T = (T^2 / 2) rho``, ``rho = min_|v|=1
sum_j hi_j max(0, v . g_j)`` (hi_j the cable's tension budget), bounded
below patch by patch.

A NO proof is a point vector v with ``v . g_j(q) < 0`` for every column j
and every q in Q: no admissible input moves the outputs along v (to first
order) anywhere in Q. NO sets of zero area (the paper arm's curves) cannot
be proven; boxes across them stay undecided (MARGINAL).

Everything else is MARGINAL with a reason: a robot under load (its
equilibrium tension varies over Q; not certified yet), joint damping, a
pinned cable, a mass matrix that may be singular on Q, a cable segment that
may vanish, or patches left unproven.

Every certificate carries what :meth:`BoxCertificate.verify` needs to
re-check it from the model without any search: the patches with their
proving columns (YES) or the separator (NO).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np

from cdpm.certify.interval import Interval, matmul
from cdpm.certify.jet import Jet, mean_value
from cdpm.certify.kinematics import box_jets, box_kinematics
from cdpm.errors import InputError
from cdpm.model.coordinates import coordinate_limits
from cdpm.numerics import (
    CERTIFY_ANGLE_MIN,
    CERTIFY_MAX_PATCHES,
    CERTIFY_NEUMANN_MAX,
    CERTIFY_SEPARATOR_CANDIDATES,
)
from cdpm.verdicts import MARGINAL, NO, YES

__all__ = ["BoxCertificate", "certify_box", "inverse_enclosure", "zero_load_reason"]


@dataclass(frozen=True)
class BoxCertificate:
    """A verdict on a whole box of poses, and its proof.

    Attributes:
        lower, upper: the box in natural coordinates [rad or m], each (nv,).
        verdict: YES (proven POC at every pose of the box), NO (proven not
            POC at every pose) or MARGINAL (undecided), cdpm's verdict codes.
        reason: one line on how it was decided, or why not.
        margin_lower: YES: a lower bound [the outputs' unit] of the reach
            margin r_T at every pose of the box (within ``horizon`` and
            ``tension_budget``); else NaN.
        horizon: T [s] of that bound.
        tension_budget: the budget [N] of cables without an upper bound.
        faces: YES: the face of each direction patch, (P,) int: face
            ``2 k + (0 if +1 else 1)`` has ``w_k = +1`` or ``-1``.
        patches: YES: each patch's box of the other entries t, (P, p - 1, 2)
            (lower, upper), dyadic fractions of [-1, 1].
        columns: YES: the cable proving each patch, (P,) int.
        separator: NO: the vector v (p,) with ``v . g_j < 0`` on the box.
        margin_unit: the unit of ``margin_lower`` (the outputs' common unit).
    """

    lower: np.ndarray
    upper: np.ndarray
    verdict: int
    reason: str
    margin_lower: float = float("nan")
    horizon: float = float("nan")
    tension_budget: float = float("nan")
    faces: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    patches: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    columns: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    separator: np.ndarray = field(default_factory=lambda: np.zeros(0))
    margin_unit: str = "m"

    def __bool__(self) -> bool:
        return self.verdict == YES

    def verify(self, robot: Any) -> bool:
        """Re-check the proof from the model: the enclosures of G over the
        box are computed again, and then (YES) the patches must tile every
        face of the direction cube and each patch's column must point into
        every direction of it at every pose of the box, with the stated
        margin bound; (NO) the separator must have ``v . g_j < 0`` for
        every column. A MARGINAL certificate proves nothing: False."""
        if self.verdict not in (YES, NO):
            return False
        reason = zero_load_reason(robot)
        if reason:
            return False
        enclosure = _g_enclosure(robot, self.lower, self.upper)
        if isinstance(enclosure, str):
            return False
        G, _ = enclosure
        p, m = G.shape
        if self.verdict == NO:
            v = np.asarray(self.separator, dtype=float)
            return v.shape == (p,) and bool(np.all(matmul(v, G).hi < 0))
        if not _tile_faces(self.faces, self.patches, p):
            return False
        cols = np.asarray(self.columns)
        if cols.shape != self.faces.shape or np.any((cols < 0) | (cols >= m)):
            return False
        dots = _patch_dots(self.faces, self.patches, G)  # (P, m)
        rows = np.arange(cols.shape[0])
        if not np.all(dots.lo[rows, cols] > 0):
            return False
        bound = _margin_bound(
            robot, self.faces, self.patches, dots, self.horizon, self.tension_budget
        )
        return bool(self.margin_lower <= bound)

    def __str__(self) -> str:
        box = ", ".join(f"[{a:.6g}, {b:.6g}]" for a, b in zip(self.lower, self.upper, strict=True))
        if self.verdict == MARGINAL:
            return f"not certified (MARGINAL) on the box {box}: {self.reason}"
        word = "YES" if self.verdict == YES else "NO"
        margin = ""
        if self.verdict == YES:
            margin = (
                f"; r_T >= {self.margin_lower:.4g} {self.margin_unit} within "
                f"T = {self.horizon:.3g} s"
            )
        return f"certified {word} on the box {box}{margin}: {self.reason}"


def zero_load_reason(robot: Any) -> str:
    """Why the robot is outside the certified case (zero load, bounds from
    0, no damping, no pinned cable), or "" when it is inside."""
    if np.any(robot.gravity) or np.any(robot.external_wrench):
        return (
            "the robot is under load (gravity or an external load): its equilibrium tension "
            "varies over the box, which certified boxes do not cover yet"
        )
    if np.any(robot.tension_min != 0):
        return "a cable has a minimum tension above 0: the equilibrium is loaded"
    method = str(robot.spec.equilibrium_method)
    if method == "pretension" and (robot.spec.pretension or 0) > 0:
        return "the pretension method loads every cable: not certified yet"
    if np.any(robot.tension_max <= 0):
        return "a cable is pinned at zero tension (its maximum is 0)"
    if np.any(robot.joint_damping):
        return "the joints are damped: the linearisation is not nilpotent"
    return ""


def _checked_box(robot: Any, lower: Any, upper: Any) -> tuple[np.ndarray, np.ndarray]:
    nv = robot.nv
    try:
        lo = np.array(lower, dtype=float).reshape(-1)
        hi = np.array(upper, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(
            f"a box needs lower and upper natural coordinates, {nv} numbers each"
        ) from None
    if lo.shape != (nv,) or hi.shape != (nv,):
        raise InputError(
            f"a box needs {nv} lower and {nv} upper natural coordinates "
            f"({', '.join(robot.coordinate_names)}); got {lo.size} and {hi.size}"
        )
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise InputError("a box's corners must be finite numbers")
    bad = np.flatnonzero(lo > hi)
    if bad.size:
        names = ", ".join(robot.coordinate_names[i] for i in bad)
        raise InputError(f"the box has lower > upper for {names}: give each lower <= upper")
    low, high = coordinate_limits(robot.model)
    out = np.flatnonzero((lo < low) | (hi > high))
    if out.size:
        i = out[0]
        raise InputError(
            f"the box leaves the joint limits of {robot.coordinate_names[i]}: "
            f"[{lo[i]:.6g}, {hi[i]:.6g}] is not within [{low[i]:.6g}, {high[i]:.6g}]; "
            "give a box inside the URDF's limits"
        )
    return lo, hi


def inverse_enclosure(M: Interval) -> Interval | str:
    """An enclosure of M^-1 for every matrix in the interval matrix M
    (..., n, n), or the reason there is none.

    With X the inverse of M's midpoint and E = I - M X (an interval
    matrix), ``M^-1 = X (I - E)^-1 = X + X E (I + E + E^2 + ...)``; when
    the row sums of |E| stay below delta < 1, entry by entry
    ``|M^-1 - X| <= |X E| (I + |E| + |E|^2 J / (1 - delta))`` (J all ones:
    every entry of ``sum_k |E|^k`` is at most 1 / (1 - delta)). Rounded
    upward throughout."""
    mid = M.midpoint
    if not np.all(np.isfinite(mid)):
        return "the mass matrix is not finite in the box"
    try:
        X = np.linalg.inv(mid)
    except np.linalg.LinAlgError:
        return "the mass matrix is singular in the box"
    if not np.all(np.isfinite(X)):
        return "the mass matrix is singular in the box"
    n = X.shape[-1]
    E = Interval(np.eye(n)) - matmul(M, X)
    absE = Interval(E.magnitude)
    delta = float(absE.sum(axis=-1).hi.max(initial=0.0))
    if not delta < CERTIFY_NEUMANN_MAX:
        return (
            f"the mass matrix may be singular or varies too much over the box (Neumann "
            f"bound {delta:.3g}, needs < {CERTIFY_NEUMANN_MAX:g})"
        )
    tail = (Interval(1.0) - Interval(delta)).reciprocal().hi  # 1 / (1 - delta), up
    E2 = matmul(absE, absE)
    series = Interval(np.eye(n)) + absE + matmul(E2, np.ones((n, n))) * float(tail)
    R = matmul(Interval(matmul(X, E).magnitude), Interval(series.hi)).hi
    return Interval(X) + Interval(-R, R)


def _g_enclosure(robot: Any, lo: np.ndarray, hi: np.ndarray) -> tuple[Interval, Any] | str:
    """(G = C_q M^-1 (-L^T) over the box (p, m), or the reason there is
    none): the mean-value form of G, from its value at the box's centre
    and the enclosure of its derivatives over the box,
    ``dG = dC M^-1 (-L^T) - C M^-1 dM M^-1 (-L^T) + C M^-1 (-dL^T)``."""
    at_centre, over_box, radius = box_jets(robot, lo, hi)
    if np.any(over_box["segment_may_vanish"]):
        return "a cable segment may have zero length in the box"
    # the value at the centre (a point box: round-off wide)
    Mc_inv = inverse_enclosure(at_centre["mass_matrix"][0])
    if isinstance(Mc_inv, str):
        return Mc_inv
    C_c, L_c = at_centre["output_jacobian"][0], at_centre["jacobian"][0]
    G_c = matmul(C_c, matmul(Mc_inv, -L_c.mT))
    # the derivatives over the box
    C, L, M = (over_box[k] for k in ("output_jacobian", "jacobian", "mass_matrix"))
    C, L, M = (
        x if isinstance(x, Jet) else Jet(x, Interval(np.zeros(x.shape + (lo.size,))))
        for x in (C, L, M)
    )
    M_box = mean_value(at_centre["mass_matrix"], M, radius)[0]
    Minv = inverse_enclosure(M_box)
    if isinstance(Minv, str):
        return Minv
    C0, L0 = C.val[0], L.val[0]
    dC, dL, dM = (x.grad[0] for x in (C, L, M))  # (..., nv) on the last axis
    B = matmul(Minv, -L0.mT)  # M^-1 (-L^T) over the box (nv, m)
    CMinv = matmul(C0, Minv)  # (p, nv)
    parts = []
    for k in range(lo.size):
        dCk, dLk, dMk = dC[..., k], dL[..., k], dM[..., k]
        parts.append(matmul(dCk, B) - matmul(CMinv, matmul(dMk, B)) + matmul(CMinv, -dLk.mT))
    spread = None
    for k, part in enumerate(parts):
        term = part * Interval(-radius[0, k], radius[0, k])
        spread = term if spread is None else spread + term
    G = G_c if spread is None else G_c + spread
    return G, None


def _face_points(faces: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """(axis k (P,), sign s (P,)) of each face index."""
    faces = np.asarray(faces, dtype=int)
    return faces // 2, np.where(faces % 2 == 0, 1.0, -1.0)


def _patch_directions(faces: np.ndarray, patches: np.ndarray, p: int) -> Interval:
    """The directions w of each patch, (P, p) intervals: +-1 on the face's
    axis, the patch's t intervals on the others (in order)."""
    k, sign = _face_points(faces, p)
    P = faces.shape[0]
    lo = np.empty((P, p))
    hi = np.empty((P, p))
    rows = np.arange(P)
    lo[rows, k] = hi[rows, k] = sign
    # the other axes of each row, in order: (P, p - 1)
    others = np.sort(np.where(np.arange(p)[None, :] == k[:, None], p, np.arange(p)), axis=1)
    others = others[:, : p - 1]
    lo[rows[:, None], others] = patches[:, :, 0]
    hi[rows[:, None], others] = patches[:, :, 1]
    return Interval(lo, hi)


def _patch_dots(faces: np.ndarray, patches: np.ndarray, G: Interval) -> Interval:
    """w . g_j over each patch and the box, (P, m) intervals."""
    W = _patch_directions(faces, patches, G.shape[0])
    return matmul(W, G)


def _margin_bound(robot, faces, patches, dots: Interval, horizon, budget) -> float:
    """A lower bound of r_T = (T^2 / 2) min_|v|=1 sum_j hi_j max(0, v . g_j)
    over the box, patch by patch (v = w / |w|, |w| <= sqrt(1 + sum t^2))."""
    from cdpm.dynamics.reach import reach_bounds

    m = dots.shape[1]
    _, hi = reach_bounds(robot, np.zeros((1, m)), budget)
    support = (Interval(np.maximum(dots.lo, 0.0)) * hi[0]).sum(axis=-1).lo  # (P,)
    t_max = np.max(np.abs(patches), axis=2) if patches.size else np.zeros((faces.shape[0], 0))
    w_norm = (Interval(1.0) + Interval(t_max).square().sum(axis=-1)).sqrt().hi
    per_patch = (Interval(support) * Interval(w_norm).reciprocal()).lo
    rho = float(np.min(per_patch, initial=np.inf))
    if not rho > 0:
        return 0.0
    half_t2 = (Interval(horizon).square() * 0.5).lo
    return float((Interval(rho) * half_t2).lo)


def _tile_faces(faces: np.ndarray, patches: np.ndarray, p: int) -> bool:
    """Do the patches tile every face of the cube [-1, 1]^p: on each face,
    boxes inside [-1, 1]^(p-1), with disjoint interiors and total volume
    2^(p-1) (computed exactly: the patches' corners are dyadic)."""
    faces = np.asarray(faces, dtype=int)
    patches = np.asarray(patches, dtype=float)
    if faces.ndim != 1 or patches.shape != (faces.shape[0], p - 1, 2):
        return False
    if np.any(patches[..., 0] >= patches[..., 1]) if p > 1 else False:
        return False
    if np.any(np.abs(patches) > 1):
        return False
    for face in range(2 * p):
        mine = patches[faces == face]
        if p == 1:
            if mine.shape[0] != 1:
                return False
            continue
        volume = sum(
            (np.prod([Fraction(b) - Fraction(a) for a, b in box], dtype=object) for box in mine),
            Fraction(0),
        )
        if volume != 2 ** (p - 1):
            return False
        lo, hi = mine[:, :, 0], mine[:, :, 1]
        overlap = np.all(
            (np.maximum(lo[:, None], lo[None]) < np.minimum(hi[:, None], hi[None])), axis=2
        )
        np.fill_diagonal(overlap, False)
        if overlap.any():
            return False
    return True


def _prove_yes(G: Interval, p: int):
    """Cut the direction cube's faces into patches until a column proves
    each, within CERTIFY_MAX_PATCHES patches. Returns (faces, patches,
    columns) or None."""
    faces = np.arange(2 * p)
    patches = np.tile(np.array([[-1.0, 1.0]]), (2 * p, p - 1, 1)) if p > 1 else np.zeros((2, 0, 2))
    done_f, done_p, done_c = [], [], []
    angle_scale = np.maximum(np.abs(G.lo), np.abs(G.hi))
    col_norm = Interval(Interval(angle_scale).square().sum(axis=0).hi).sqrt().hi  # (m,)
    while faces.size:
        dots = _patch_dots(faces, patches, G)  # (P, m)
        t_max = np.max(np.abs(patches), axis=2) if p > 1 else np.zeros((faces.shape[0], 0))
        w_norm = np.sqrt(1.0 + np.sum(t_max * t_max, axis=1)) * (1 + 1e-12)
        # proven with an angular margin: the per-pose analyser calls sets
        # within its angle tolerance of the boundary NO
        angle = dots.lo / (w_norm[:, None] * col_norm[None, :])
        best = np.argmax(angle, axis=1)
        ok = angle[np.arange(faces.size), best] > CERTIFY_ANGLE_MIN
        done_f.append(faces[ok])
        done_p.append(patches[ok])
        done_c.append(best[ok])
        faces, patches = faces[~ok], patches[~ok]
        total = sum(x.size for x in done_f) + 2 * faces.size
        if not faces.size:
            break
        if p == 1 or total > CERTIFY_MAX_PATCHES:
            return None
        # bisect each open patch along its widest side
        widths = patches[:, :, 1] - patches[:, :, 0]
        side = np.argmax(widths, axis=1)
        rows = np.arange(faces.size)
        mid = 0.5 * (patches[rows, side, 0] + patches[rows, side, 1])
        first, second = patches.copy(), patches.copy()
        first[rows, side, 1] = mid
        second[rows, side, 0] = mid
        faces = np.concatenate([faces, faces])
        patches = np.concatenate([first, second])
    return np.concatenate(done_f), np.concatenate(done_p), np.concatenate(done_c)


def _separator(G: Interval, p: int) -> np.ndarray | None:
    """A point v with v . g_j < 0 for every column over the box, tried from
    CERTIFY_SEPARATOR_CANDIDATES directions (the best at the box's centre
    first), or None."""
    Gc = G.midpoint
    if p == 1:
        candidates = np.array([[1.0], [-1.0]])
    elif p == 2:
        a = np.linspace(0, 2 * np.pi, CERTIFY_SEPARATOR_CANDIDATES, endpoint=False)
        candidates = np.stack([np.cos(a), np.sin(a)], axis=1)
    else:
        rng = np.random.default_rng(0)
        candidates = rng.standard_normal((CERTIFY_SEPARATOR_CANDIDATES, p))
        candidates /= np.linalg.norm(candidates, axis=1, keepdims=True)
    score = np.max(candidates @ Gc, axis=1)
    for i in np.argsort(score)[:8]:
        if score[i] >= 0:
            break
        v = candidates[i]
        if np.all(matmul(v, G).hi < 0):
            return v
    return None


def certify_box(
    robot: Any,
    lower: Any,
    upper: Any,
    *,
    horizon: Any = None,
    tension_budget: Any = None,
) -> BoxCertificate:
    """Prove positive output controllability (POC) on a whole box of poses,
    or its absence, or say why neither (module docstring).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` (or a spec path) with
            revolute and prismatic joints.
        lower, upper: the box's corners, natural coordinates (nv,) [rad or m],
            within the URDF's joint limits.
        horizon, tension_budget: T [s] and budget [N] of the reach-margin
            bound (default: the model's, as :func:`cdpm.analyze_pose`).

    Returns:
        :class:`BoxCertificate` (YES, NO or MARGINAL with its reason).

    Raises:
        InputError: corners of the wrong size, not finite, lower > upper,
            beyond the joint limits, or a joint type certified boxes do not
            support (named).
    """
    # loaded on first use: the model and the reach settings
    from cdpm.dynamics.reach import reach_settings, reach_unit
    from cdpm.model.robot import load_robot

    if not hasattr(robot, "spec"):
        robot = load_robot(robot)
    lo, hi = _checked_box(robot, lower, upper)
    reach = reach_settings(robot, horizon, tension_budget)
    T, F = reach.horizon, reach.tension_budget
    unit = reach_unit(robot.output_units)
    reason = zero_load_reason(robot)
    if reason:
        box_kinematics(robot, lo, hi)  # unsupported joints are an error all the same
        return BoxCertificate(lo, hi, MARGINAL, reason, horizon=T, tension_budget=F)
    enclosure = _g_enclosure(robot, lo, hi)
    if isinstance(enclosure, str):
        return BoxCertificate(lo, hi, MARGINAL, enclosure, horizon=T, tension_budget=F)
    G, _ = enclosure
    p = G.shape[0]
    proof = _prove_yes(G, p)
    if proof is not None:
        faces, patches, columns = proof
        dots = _patch_dots(faces, patches, G)
        bound = _margin_bound(robot, faces, patches, dots, T, F)
        return BoxCertificate(
            lo,
            hi,
            YES,
            f"every output direction has a cable that moves the outputs into it at every pose "
            f"of the box ({faces.size} direction patches)",
            margin_lower=bound,
            margin_unit=unit,
            horizon=T,
            tension_budget=F,
            faces=faces,
            patches=patches,
            columns=columns,
        )
    v = _separator(G, p)
    if v is not None:
        return BoxCertificate(
            lo,
            hi,
            NO,
            "no cable moves the outputs along the separator v at any pose of the box",
            horizon=T,
            tension_budget=F,
            separator=v,
        )
    return BoxCertificate(
        lo,
        hi,
        MARGINAL,
        "neither proven: the box may hold a NO set, or it is too wide for the enclosures "
        "(bisect it)",
        horizon=T,
        tension_budget=F,
    )
