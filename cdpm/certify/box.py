"""A verdict proven on a whole box of poses: :func:`certify_box`.

The per-pose analysis decides positive output controllability (POC,
seed paper Theorem 1) at one pose. A box ``Q = [lower, upper]`` of natural
coordinates is *certified* YES when a proof covers every pose in it, and
certified NO when one vector separates the inputs from some output
direction at every pose in it (docs/analysis.md, "Certified boxes").

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

A robot outside this case (under load, with a pretension, damped joints
or a pinned cable) goes to :mod:`cdpm.certify.loaded` when its equilibrium
is a least-norm tension in bounds: YES where the equilibrium's active set
is constant on Q and the free cables alone move the outputs in every
direction (no NO proofs there; the margin bound is the trivial 0).

Everything else is MARGINAL with a reason: a robot in neither case, a
mass matrix that may be singular on Q, a cable segment that may vanish, an
output Jacobian that may lose rank, or patches left unproven.

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
from cdpm.certify.inverse import inverse_enclosures as shared_inverse_enclosures
from cdpm.certify.jet import Jet, mean_value
from cdpm.certify.kinematics import box_jets, box_kinematics
from cdpm.errors import InputError
from cdpm.model.coordinates import coordinate_limits
from cdpm.numerics import (
    CERTIFY_ANGLE_MIN,
    CERTIFY_MAX_PATCHES,
    CERTIFY_SEPARATOR_CANDIDATES,
)
from cdpm.verdicts import MARGINAL, NO, YES

__all__ = [
    "BoxCertificate",
    "CertifiedBoxes",
    "certify_box",
    "certified_case",
    "certify_boxes",
    "concatenate_boxes",
    "inverse_enclosure",
    "inverse_enclosures",
    "zero_load_reason",
]


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
        every column. A MARGINAL certificate proves nothing: False.
        (:meth:`CertifiedBoxes.verify` on a batch of one.)"""
        p = len(robot.output_names)
        try:
            faces = np.asarray(self.faces, dtype=np.int64).reshape(-1)
            patches = np.asarray(self.patches, dtype=float)
            columns = np.asarray(self.columns, dtype=np.int64).reshape(-1)
            sep = np.asarray(self.separator, dtype=float).reshape(-1)
            lo = np.asarray(self.lower, dtype=float).reshape(1, -1)
            hi = np.asarray(self.upper, dtype=float).reshape(1, -1)
        except (TypeError, ValueError):
            return False
        if patches.ndim != 3 and faces.size == 0:
            patches = np.zeros((0, max(p - 1, 0), 2))
        if sep.shape != (p,):
            sep = np.full(p, np.nan) if self.verdict != NO else np.full(p, np.nan)
            if self.verdict == NO:
                return False
        batch = CertifiedBoxes(
            lo,
            hi,
            np.array([self.verdict], dtype=np.int8),
            np.array([self.reason]),
            np.array([self.margin_lower]),
            self.horizon,
            self.tension_budget,
            self.margin_unit,
            np.array([0, faces.size], dtype=np.int64),
            faces,
            patches,
            columns,
            sep[None, :],
        )
        return bool(batch.verify(robot)[0])

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
        return "the robot is under load (gravity or an external load)"
    if np.any(robot.tension_min != 0):
        return "a cable has a minimum tension above 0: the equilibrium is loaded"
    method = str(robot.spec.equilibrium_method)
    if method == "pretension" and (robot.spec.pretension or 0) > 0:
        return "the pretension method loads every cable"
    if np.any(robot.tension_max <= 0):
        return "a cable is pinned at zero tension (its maximum is 0)"
    if np.any(robot.joint_damping):
        return "the joints are damped: the linearisation is not nilpotent"
    return ""


def certified_case(robot: Any) -> tuple[str, str]:
    """Which proof applies to the robot: ``("zero_load", "")`` (the module
    docstring's), ``("loaded", "")`` (:mod:`cdpm.certify.loaded`: a
    least-norm equilibrium tension with a constant active set), or
    ``("", reason)`` when neither does (every box is then MARGINAL with
    that reason)."""
    from cdpm.certify.loaded import loaded_reason

    zero = zero_load_reason(robot)
    if not zero:
        return "zero_load", ""
    loaded = loaded_reason(robot)
    if not loaded:
        return "loaded", ""
    return "", f"{zero}, and loaded boxes cannot be certified: {loaded}"


def _checked_box(robot: Any, lower: Any, upper: Any) -> tuple[np.ndarray, np.ndarray]:
    """One box's corners as (nv,) arrays, checked as :func:`_checked_boxes`."""
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
    lo, hi = _checked_boxes(robot, lo[None], hi[None])
    return lo[0], hi[0]


def inverse_enclosure(M: Interval) -> Interval | str:
    """An enclosure of M^-1 for every matrix in the interval matrix M
    (n, n), or the reason there is none (:func:`inverse_enclosures` on a
    batch of one)."""
    inv, reason = inverse_enclosures(M[None])
    return reason[0] if reason[0] else inv[0]


def inverse_enclosures(M: Interval) -> tuple[Interval, np.ndarray]:
    """Enclosures of M^-1 for every mass matrix in each interval matrix of a
    batch M (B, n, n), and per matrix the reason there is none ("" where
    there is one): :func:`cdpm.certify.inverse.inverse_enclosures`, its
    plain Neumann bound."""
    inv, why = shared_inverse_enclosures(M, weighted=False)
    reason = np.array([f"the mass matrix {w}" if w else "" for w in why], dtype=object)
    return inv, reason


def _g_enclosure(
    robot: Any, lo: np.ndarray, hi: np.ndarray
) -> tuple[Interval, np.ndarray, np.ndarray]:
    """G = C_q M^-1 (-L^T) over each box of a batch (B, p, m), per box the
    reason there is none ("" where there is one), and per box whether the
    output Jacobian C_q may lose rank in it (B,) bool: the mean-value form
    of G, from its value at the box's centre and the enclosure of its
    derivatives over the box,
    ``dG = dC M^-1 (-L^T) - C M^-1 dM M^-1 (-L^T) + C M^-1 (-dL^T)``."""
    at_centre, over_box, radius = box_jets(robot, lo, hi)
    B = lo.shape[0]
    reason = np.full(B, "", dtype=object)
    vanish = np.asarray(over_box["segment_may_vanish"]).reshape(B, -1).any(axis=1)
    reason[vanish] = "a cable segment may have zero length in the box"
    # the value at the centre (a point box: round-off wide)
    Mc_inv, why = inverse_enclosures(at_centre["mass_matrix"])
    reason = np.where(reason == "", why, reason)
    C_c, L_c = at_centre["output_jacobian"], at_centre["jacobian"]
    G_c = matmul(C_c, matmul(Mc_inv, -L_c.mT))
    # the derivatives over the box
    C, L, M = (over_box[k] for k in ("output_jacobian", "jacobian", "mass_matrix"))
    C, L, M = (
        x if isinstance(x, Jet) else Jet(x, Interval(np.zeros(x.shape + (lo.shape[1],))))
        for x in (C, L, M)
    )
    M_box = mean_value(at_centre["mass_matrix"], M, radius)
    Minv, why = inverse_enclosures(M_box)
    reason = np.where(reason == "", why, reason)
    # the values over the box in their mean-value forms (cut to the naive
    # ones): tighter factors in the derivative's products below
    C0 = mean_value(at_centre["output_jacobian"], C, radius)
    L0 = mean_value(at_centre["jacobian"], L, radius)
    # can C_q lose rank in the box? (sigma_min of its midpoint against the
    # spread; only names the reason of a box left undecided, never a proof)
    sigma = np.linalg.svd(C0.midpoint, compute_uv=False)
    rank_may_drop = ~(
        sigma.min(axis=-1, initial=np.inf) > np.linalg.norm(C0.width / 2, axis=(1, 2))
    )
    B_mat = matmul(Minv, -L0.mT)  # M^-1 (-L^T) over the box (B, nv, m)
    CMinv = matmul(C0, Minv)  # (B, p, nv)
    G = G_c
    for k in range(lo.shape[1]):
        dCk, dLk, dMk = C.grad[..., k], L.grad[..., k], M.grad[..., k]
        part = matmul(dCk, B_mat) - matmul(CMinv, matmul(dMk, B_mat)) + matmul(CMinv, -dLk.mT)
        r = radius[:, k][:, None, None]
        G = G + part * Interval(-r, r)
    # boxes without an enclosure: the whole line, finite so arithmetic runs
    failed = (reason != "") | ~np.all(np.isfinite(G.lo) & np.isfinite(G.hi), axis=(1, 2))
    reason[failed & (reason == "")] = "the enclosure of the linearisation is not finite"
    G = Interval._raw(
        np.where(failed[:, None, None], -1.0, G.lo), np.where(failed[:, None, None], 1.0, G.hi)
    )
    return G, reason, rank_may_drop


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
    """w . g_j over each patch and its box, (P, m) intervals; G (P, p, m)
    holds each patch's box's enclosure."""
    W = _patch_directions(faces, patches, G.shape[-2])
    return matmul(W[:, None, :], G)[:, 0, :]


def _margin_bounds(robot, owner, faces, patches, dots_lo, n_boxes, horizon, budget):
    """Lower bounds (n_boxes,) of r_T = (T^2 / 2) min_|v|=1 sum_j hi_j
    max(0, v . g_j) over each box, patch by patch (v = w / |w|, |w| <=
    sqrt(1 + sum t^2)); ``owner`` (P,) is each patch's box, ``dots_lo``
    (P, m) the lower bounds of w . g_j over each patch and its box. Boxes
    without patches get +inf."""
    from cdpm.dynamics.reach import reach_bounds

    m = dots_lo.shape[1]
    _, hi = reach_bounds(robot, np.zeros((1, m)), budget)
    support = (Interval(np.maximum(dots_lo, 0.0)) * hi[0]).sum(axis=-1).lo  # (P,)
    t_max = np.max(np.abs(patches), axis=2) if patches.shape[1] else np.zeros((faces.size, 0))
    w_norm = (Interval(1.0) + Interval(t_max).square().sum(axis=-1)).sqrt().hi
    per_patch = (Interval(support) * Interval(w_norm).reciprocal()).lo
    rho = np.full(n_boxes, np.inf)
    np.minimum.at(rho, owner, per_patch)
    half_t2 = (Interval(horizon).square() * 0.5).lo
    bound = (Interval(np.where(rho > 0, rho, 0.0)) * half_t2).lo
    return np.where(rho > 0, bound, 0.0)


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


def _prove_yes(G: Interval, live: np.ndarray):
    """Cut the direction cube's faces into patches, box by box, until a
    column proves each patch, within CERTIFY_MAX_PATCHES patches per box.

    Args:
        G: the enclosures (B, p, m).
        live: (B,) the boxes to try.

    Returns:
        (proven (B,) bool, owner (P,), faces (P,), patches (P, p - 1, 2),
        columns (P,), dots_lo (P, m)): the patches of the proven boxes,
        sorted by box, with the lower bounds of w . g_j over each.
    """
    B, p, _ = G.shape
    boxes = np.flatnonzero(live)
    owner = np.repeat(boxes, 2 * p)
    faces = np.tile(np.arange(2 * p), boxes.size)
    patches = np.tile(np.array([-1.0, 1.0]), (owner.size, p - 1, 1))
    failed = ~live.copy()
    count = np.zeros(B, dtype=np.int64)  # proven patches per box
    done_o, done_f, done_p, done_c, done_d = [], [], [], [], []
    angle_scale = np.maximum(np.abs(G.lo), np.abs(G.hi))
    col_norm = Interval(Interval(angle_scale).square().sum(axis=1).hi).sqrt().hi  # (B, m)
    while owner.size:
        Gp = G[owner]
        dots = _patch_dots(faces, patches, Gp)  # (P, m)
        t_max = np.max(np.abs(patches), axis=2) if p > 1 else np.zeros((owner.size, 0))
        w_norm = np.sqrt(1.0 + np.sum(t_max * t_max, axis=1)) * (1 + 1e-12)
        # proven with an angular margin: the per-pose analyser calls sets
        # within its angle tolerance of the boundary NO
        angle = dots.lo / (w_norm[:, None] * col_norm[owner])
        best = np.argmax(angle, axis=1)
        ok = angle[np.arange(owner.size), best] > CERTIFY_ANGLE_MIN
        # a patch no column can prove (each upper bound <= 0) fails its box
        hopeless = ~ok & np.all(dots.hi <= 0, axis=1)
        failed[owner[hopeless]] = True
        done_o.append(owner[ok])
        done_f.append(faces[ok])
        done_p.append(patches[ok])
        done_c.append(best[ok])
        done_d.append(dots.lo[ok])
        np.add.at(count, owner[ok], 1)
        keep = ~ok
        owner, faces, patches = owner[keep], faces[keep], patches[keep]
        if p == 1:
            failed[owner] = True
        open_count = np.bincount(owner, minlength=B)
        failed |= count + 2 * open_count > CERTIFY_MAX_PATCHES
        keep = ~failed[owner]
        owner, faces, patches = owner[keep], faces[keep], patches[keep]
        if not owner.size:
            break
        # bisect each open patch along its widest side
        widths = patches[:, :, 1] - patches[:, :, 0]
        side = np.argmax(widths, axis=1)
        rows = np.arange(owner.size)
        mid = 0.5 * (patches[rows, side, 0] + patches[rows, side, 1])
        first, second = patches.copy(), patches.copy()
        first[rows, side, 1] = mid
        second[rows, side, 0] = mid
        owner = np.concatenate([owner, owner])
        faces = np.concatenate([faces, faces])
        patches = np.concatenate([first, second])
    proven = live & ~failed
    if not done_o:
        e = np.zeros(0, dtype=np.int64)
        return proven, e, e, np.zeros((0, max(p - 1, 0), 2)), e, np.zeros((0, G.shape[2]))
    o = np.concatenate(done_o)
    keep = proven[o]
    order = np.argsort(o[keep], kind="stable")
    pick = lambda parts: np.concatenate(parts)[keep][order]  # noqa: E731
    return proven, o[keep][order], pick(done_f), pick(done_p), pick(done_c), pick(done_d)


def _separators(G: Interval, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A point v per box with v . g_j < 0 for every column over the box,
    tried from CERTIFY_SEPARATOR_CANDIDATES directions (the 8 best at the
    box's centre); returns (found (B,) bool, v (B, p), NaN where none)."""
    B, p, _ = G.shape
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
    score = np.max(np.einsum("cp,bpm->bcm", candidates, Gc), axis=2)  # (B, C)
    order = np.argsort(score, axis=1)[:, :8]
    found = np.zeros(B, dtype=bool)
    v = np.full((B, p), np.nan)
    rows = np.arange(B)
    for k in range(order.shape[1]):
        i = order[:, k]
        try_now = live & ~found & (score[rows, i] < 0)
        if not try_now.any():
            continue
        cand = candidates[i[try_now]]
        ok = np.all(matmul(cand[:, None, :], G[try_now])[:, 0, :].hi < 0, axis=1)
        idx = np.flatnonzero(try_now)[ok]
        found[idx] = True
        v[idx] = cand[ok]
    return found, v


@dataclass(frozen=True)
class CertifiedBoxes:
    """Verdicts on a batch of K boxes, and their proofs, as flat arrays
    (what :func:`certify_boxes` returns and a certified map stores).

    Attributes:
        lower, upper: the boxes, natural coordinates [rad or m], (K, nv).
        verdict: YES, NO or MARGINAL per box (K,) int8 (cdpm's codes).
        reason: one line per box (K,) str: how it was decided, or why not.
        margin_lower: YES boxes: a lower bound of r_T over the box [the
            outputs' unit]; NaN for the others (K,).
        horizon, tension_budget: T [s] and budget [N] of those bounds.
        margin_unit: the outputs' common unit.
        patch_start: box k's direction patches are rows
            ``patch_start[k]:patch_start[k + 1]`` of the next three (K + 1,).
        faces, patches, columns: every YES box's patches (P,), (P, p - 1, 2),
            (P,) (see :class:`BoxCertificate`).
        separator: NO boxes' separators (K, p); NaN rows for the others.
    """

    lower: np.ndarray
    upper: np.ndarray
    verdict: np.ndarray
    reason: np.ndarray
    margin_lower: np.ndarray
    horizon: float
    tension_budget: float
    margin_unit: str
    patch_start: np.ndarray
    faces: np.ndarray
    patches: np.ndarray
    columns: np.ndarray
    separator: np.ndarray

    def __len__(self) -> int:
        return int(self.verdict.shape[0])

    def certificate(self, k: int) -> BoxCertificate:
        """Box k's :class:`BoxCertificate`."""
        a, b = int(self.patch_start[k]), int(self.patch_start[k + 1])
        verdict = int(self.verdict[k])
        return BoxCertificate(
            self.lower[k].copy(),
            self.upper[k].copy(),
            verdict,
            str(self.reason[k]),
            margin_lower=float(self.margin_lower[k]),
            horizon=self.horizon,
            tension_budget=self.tension_budget,
            faces=self.faces[a:b].copy(),
            patches=self.patches[a:b].copy(),
            columns=self.columns[a:b].copy(),
            separator=self.separator[k].copy() if verdict == NO else np.zeros(0),
            margin_unit=self.margin_unit,
        )

    def select(self, rows: Any) -> CertifiedBoxes:
        """The boxes picked by ``rows`` (a boolean mask or indices), in that
        order, with their proofs."""
        rows = np.arange(len(self))[rows]
        counts = np.diff(self.patch_start)[rows]
        new_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        patch_rows = np.repeat(self.patch_start[rows] - new_start[:-1], counts) + np.arange(
            new_start[-1]
        )
        return CertifiedBoxes(
            self.lower[rows],
            self.upper[rows],
            self.verdict[rows],
            self.reason[rows],
            self.margin_lower[rows],
            self.horizon,
            self.tension_budget,
            self.margin_unit,
            new_start,
            self.faces[patch_rows],
            self.patches[patch_rows],
            self.columns[patch_rows],
            self.separator[rows],
        )

    def verify(self, robot: Any) -> np.ndarray:
        """Re-check every box's proof from the model (:meth:`BoxCertificate.verify`),
        (K,) bool: False for MARGINAL boxes and for every proof that fails."""
        K = len(self)
        ok = np.zeros(K, dtype=bool)
        decided = np.isin(self.verdict, (YES, NO))
        case, _ = certified_case(robot)
        if not decided.any() or not case:
            return ok
        try:
            lo, hi = _checked_boxes(robot, self.lower, self.upper)
        except InputError:
            return ok
        if case == "loaded":  # no patches: the proof is recomputed
            from cdpm.certify.loaded import verify_loaded

            yes = np.flatnonzero(self.verdict == YES)
            if yes.size:
                ok[yes] = verify_loaded(robot, lo[yes], hi[yes]) & (self.margin_lower[yes] <= 0)
            return ok
        G, why, _ = _g_enclosure(robot, lo, hi)
        usable = decided & (why == "")
        p, m = G.shape[1], G.shape[2]
        no = usable & (self.verdict == NO)
        sep = np.asarray(self.separator, dtype=float)
        if sep.shape == (K, p) and no.any():
            v = sep[no]
            with np.errstate(invalid="ignore"):
                ok[no] = np.all(matmul(v[:, None, :], G[no])[:, 0, :].hi < 0, axis=1) & np.all(
                    np.isfinite(v), axis=1
                )
        yes = np.flatnonzero(usable & (self.verdict == YES))
        start = np.asarray(self.patch_start)
        if not yes.size or start.shape != (K + 1,) or np.any(np.diff(start) < 0):
            return ok
        faces, patches, cols = (np.asarray(x) for x in (self.faces, self.patches, self.columns))
        P = faces.shape[0]
        if start[-1] != P or patches.shape[:1] != (P,) or cols.shape != (P,) or start[0] != 0:
            return ok
        owner = np.repeat(np.arange(K), np.diff(start))
        rows = np.isin(owner, yes)
        if np.any((cols[rows] < 0) | (cols[rows] >= m)) or patches.shape[1:] != (p - 1, 2):
            return ok
        tiled = np.array(
            [
                _tile_faces(faces[start[k] : start[k + 1]], patches[start[k] : start[k + 1]], p)
                for k in yes
            ]
        )
        o, f, pt, c = owner[rows], faces[rows], patches[rows], cols[rows]
        dots = _patch_dots(f, pt, G[o])
        proves = dots.lo[np.arange(o.size), c] > 0
        all_prove = np.ones(K, dtype=bool)
        np.logical_and.at(all_prove, o, proves)
        bound = _margin_bounds(robot, o, f, pt, dots.lo, K, self.horizon, self.tension_budget)
        ok[yes] = tiled & all_prove[yes] & (self.margin_lower[yes] <= bound[yes])
        return ok


def concatenate_boxes(parts: list[CertifiedBoxes]) -> CertifiedBoxes:
    """One batch of the boxes of several (same robot and reach settings)."""
    first = parts[0]
    starts, offset = [np.zeros(1, dtype=np.int64)], 0
    for part in parts:
        starts.append(part.patch_start[1:] + offset)
        offset += int(part.patch_start[-1])
    cat = lambda name: np.concatenate([getattr(x, name) for x in parts])  # noqa: E731
    return CertifiedBoxes(
        cat("lower"),
        cat("upper"),
        cat("verdict"),
        cat("reason"),
        cat("margin_lower"),
        first.horizon,
        first.tension_budget,
        first.margin_unit,
        np.concatenate(starts),
        cat("faces"),
        cat("patches"),
        cat("columns"),
        cat("separator"),
    )


def _checked_boxes(robot: Any, lower: Any, upper: Any) -> tuple[np.ndarray, np.ndarray]:
    """The corners as (K, nv) arrays: finite, lower <= upper, within the
    joint limits; the first bad box is named with its coordinate."""
    nv = robot.nv
    try:
        lo = np.array(lower, dtype=float)
        hi = np.array(upper, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"boxes need lower and upper natural coordinates, {nv} numbers each"
        ) from None
    if lo.ndim != 2 or lo.shape != hi.shape or lo.shape[1] != nv:
        raise InputError(
            f"boxes need (K, {nv}) lower and upper natural coordinates; "
            f"got {lo.shape} and {hi.shape}"
        )
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise InputError("a box's corners must be finite numbers")
    swapped = lo > hi
    if swapped.any():
        k = int(np.flatnonzero(swapped.any(axis=1))[0])
        names = ", ".join(robot.coordinate_names[i] for i in np.flatnonzero(swapped[k]))
        raise InputError(f"the box has lower > upper for {names}: give each lower <= upper")
    low, high = coordinate_limits(robot.model)
    out = (lo < low) | (hi > high)
    if out.any():
        k, i = (int(x) for x in np.argwhere(out)[0])
        raise InputError(
            f"the box leaves the joint limits of {robot.coordinate_names[i]}: "
            f"[{lo[k, i]:.6g}, {hi[k, i]:.6g}] is not within [{low[i]:.6g}, {high[i]:.6g}]; "
            "give a box inside the URDF's limits"
        )
    return lo, hi


def certify_boxes(
    robot: Any,
    lower: Any,
    upper: Any,
    *,
    horizon: Any = None,
    tension_budget: Any = None,
) -> CertifiedBoxes:
    """Prove positive output controllability (POC) on each box of a batch,
    or its absence, or say why neither (module docstring); one vectorised
    pass over the batch.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` (or a spec path) with
            revolute, prismatic and free-flyer joints.
        lower, upper: the boxes' corners, natural coordinates (K, nv) [rad or m],
            within the URDF's joint limits.
        horizon, tension_budget: T [s] and budget [N] of the reach-margin
            bound (default: the model's, as :func:`cdpm.analyze_pose`), or a
            :class:`~cdpm.dynamics.reach.ReachSettings` as ``horizon``.

    Returns:
        :class:`CertifiedBoxes`.

    Raises:
        InputError: corners of the wrong shape, not finite, lower > upper,
            beyond the joint limits, or a joint type certified boxes do not
            support (named).
    """
    # loaded on first use: the model and the reach settings
    from cdpm.dynamics.reach import reach_settings, reach_unit
    from cdpm.model.robot import load_robot

    if not hasattr(robot, "spec"):
        robot = load_robot(robot)
    lo, hi = _checked_boxes(robot, lower, upper)
    reach = reach_settings(robot, horizon, tension_budget)
    T, F = reach.horizon, reach.tension_budget
    unit = reach_unit(robot.output_units)
    K, p = lo.shape[0], len(robot.output_names)
    verdict = np.full(K, MARGINAL, dtype=np.int8)
    margin = np.full(K, np.nan)
    separator = np.full((K, p), np.nan)
    empty = np.zeros(0, dtype=np.int64)
    no_patches = (empty, np.zeros((0, max(p - 1, 0), 2)), empty)
    case, structural = certified_case(robot)
    if case == "loaded" and K:
        from cdpm.certify.loaded import certify_loaded

        verdict, reason, margin = certify_loaded(robot, lo, hi, reach)
        return CertifiedBoxes(
            lo,
            hi,
            verdict.astype(np.int8),
            reason.astype(str),
            margin,
            T,
            F,
            unit,
            np.zeros(K + 1, dtype=np.int64),
            *no_patches,
            separator,
        )
    if structural or K == 0:
        box_kinematics(robot, lo[:1], hi[:1]) if K else None  # unsupported joints: an error
        reason = np.full(K, structural, dtype=object)
        return CertifiedBoxes(
            lo,
            hi,
            verdict,
            reason,
            margin,
            T,
            F,
            unit,
            np.zeros(K + 1, dtype=np.int64),
            *no_patches,
            separator,
        )
    G, reason, rank_may_drop = _g_enclosure(robot, lo, hi)
    live = reason == ""
    proven, owner, faces, patches, columns, dots_lo = _prove_yes(G, live)
    n_patches = np.bincount(owner, minlength=K)
    verdict[proven] = YES
    if proven.any():
        bound = _margin_bounds(robot, owner, faces, patches, dots_lo, K, T, F)
        margin[proven] = bound[proven]
        for k in np.flatnonzero(proven):
            reason[k] = (
                "every output direction has a cable that moves the outputs into it at every "
                f"pose of the box ({n_patches[k]} direction patches)"
            )
    found, v = _separators(G, live & ~proven)
    verdict[found] = NO
    separator[found] = v[found]
    reason[found] = "no cable moves the outputs along the separator v at any pose of the box"
    left = live & ~proven & ~found
    reason[left] = (
        "neither proven: the box may hold a NO set, or it is too wide for the enclosures "
        "(smaller boxes may decide it: a smaller least box, min_fraction)"
    )
    reason[left & rank_may_drop] = (
        "neither proven: the output Jacobian C_q may lose rank in the box (a singular pose "
        "of the outputs, where no cable moves them in some direction)"
    )
    start = np.concatenate([[0], np.cumsum(n_patches)]).astype(np.int64)
    return CertifiedBoxes(
        lo,
        hi,
        verdict,
        reason.astype(str),
        margin,
        T,
        F,
        unit,
        start,
        faces,
        patches,
        columns,
        separator,
    )


def certify_box(
    robot: Any,
    lower: Any,
    upper: Any,
    *,
    horizon: Any = None,
    tension_budget: Any = None,
) -> BoxCertificate:
    """Prove positive output controllability (POC) on a whole box of poses,
    or its absence, or say why neither (module docstring):
    :func:`certify_boxes` on a batch of one.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` (or a spec path) with
            revolute, prismatic and free-flyer joints.
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
    from cdpm.model.robot import load_robot

    if not hasattr(robot, "spec"):
        robot = load_robot(robot)
    lo, hi = _checked_box(robot, lower, upper)
    batch = certify_boxes(robot, lo[None], hi[None], horizon=horizon, tension_budget=tension_budget)
    return batch.certificate(0)
