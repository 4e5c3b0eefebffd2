"""Enclosures of the inverses of interval matrices (Neumann series around
the inverse of the midpoint), for every matrix of a batch, and of a
symmetric matrix function's inverse over boxes of poses: the one home of
these bounds for :mod:`cdpm.certify.box` (mass matrices at zero load) and
:mod:`cdpm.certify.loaded` (mass and KKT matrices under load).

Every bound is rounded upward (:func:`up_bound`), so an enclosure holds
every inverse, round-off included.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cdpm.certify.interval import Interval, matmul
from cdpm.numerics import CERTIFY_NEUMANN_MAX

__all__ = ["inverse_enclosures", "inverse_over_box", "up_bound", "norm_upper"]

_EPS = float(np.finfo(float).eps)


def up_bound(x: np.ndarray, n: int) -> np.ndarray:
    """Sums or products of n nonnegative float terms x, rounded up: their
    round-off is at most about n eps times x (each term's relative error
    adds up), which this factor covers."""
    return np.nextafter(x * (1.0 + 2.0 * (n + 2) * _EPS), np.inf)


def norm_upper(x: np.ndarray, axes: Any) -> np.ndarray:
    """An upper bound of the 2-norm (Frobenius) of magnitudes x over ``axes``
    (the factor covers the sum's round-off)."""
    return np.sqrt(np.sum(x * x, axis=axes)) * (1 + 1e-12)


def inverse_enclosures(M: Interval, weighted: bool = True) -> tuple[Interval, np.ndarray]:
    """Enclosures of M^-1 for every matrix in each interval matrix of a
    batch M (B, n, n), and per matrix the reason there is none ("").

    The Neumann series: X the inverse of M's midpoint, E = I - M X,
    ``M^-1 = X sum_k E^k``. *Plain*: when the row sums of |E| stay below
    delta < 1, ``sum_k |E|^k <= I + |E| + |E|^2 J / (1 - delta)`` (J all
    ones). *Weighted* (``weighted=True``, also): convergence judged in the
    norm that Perron's vector v of |E| weighs: when ``|E| v <= delta v``
    (v > 0, delta < 1), entry by entry
    ``(|E|^k)_ij <= delta^k v_i / v_j``, so ``sum_k |E|^k <= S`` with
    ``S_ij = v_i / (v_j (1 - delta))``, and ``|M^-1 - X| <= |X E| (I +
    |E| + |E|^2 S)``. A matrix whose large and small
    entries vary alike over the box (a mass matrix of heavy and light
    links) passes where the row sums of |E| (the plain bound) exceed 1."""
    mid = M.midpoint
    B, n = mid.shape[0], mid.shape[-1]
    reason = np.full(B, "", dtype=object)
    finite = np.all(np.isfinite(M.lo) & np.isfinite(M.hi), axis=(1, 2))
    reason[~finite] = "is not finite in the box"
    eye = np.eye(n)
    safe = np.where(finite[:, None, None], mid, eye)
    with np.errstate(all="ignore"):
        cond = np.linalg.cond(safe)
    singular = finite & ~(cond < 1.0 / _EPS)
    reason[singular] = "is singular in the box"
    bad = ~finite | singular
    X = np.linalg.inv(np.where(bad[:, None, None], eye, safe))
    Mx = Interval._raw(
        np.where(bad[:, None, None], eye, M.lo), np.where(bad[:, None, None], eye, M.hi)
    )
    E = Interval(eye) - matmul(Mx, X)
    A = E.magnitude  # (B, n, n), >= 0
    # Perron's vector of A (a positive vector near it: any positive v is valid)
    with np.errstate(all="ignore"):
        vals, vecs = np.linalg.eig(np.where(np.isfinite(A), A, 0.0))
    top = np.argmax(vals.real, axis=1)
    v = np.abs(vecs[np.arange(B), :, top].real)
    v = v / np.maximum(v.max(axis=1, keepdims=True), 1e-300)
    v = np.maximum(v, 1e-6)
    growth = 1.0 + 4.0 * (n + 2) * _EPS  # the rounding of A v and of the ratio
    with np.errstate(all="ignore"):
        delta_v = np.max((A @ v[..., None])[..., 0] / v, axis=1) * growth
    delta_row = np.max(A.sum(axis=-1), axis=-1) * growth  # the plain bound
    if not weighted:
        delta_v = np.full(B, np.inf)
    delta = np.minimum(delta_v, delta_row)
    loose = ~bad & ~(delta < CERTIFY_NEUMANN_MAX)
    for b in np.flatnonzero(loose):
        reason[b] = (
            f"may be singular or varies too much over the box (Neumann bound {delta[b]:.3g}, "
            f"needs < {CERTIFY_NEUMANN_MAX:g})"
        )
    A = np.where((bad | loose)[:, None, None], 0.0, A)
    E2 = up_bound(A @ A, n)
    XE = matmul(X, E).magnitude
    R = np.full((B, n, n), np.inf)
    # sum_k |E|^k <= I + |E| + |E|^2 S: S = J / (1 - delta_row) (plain) or
    # S_ij = v_i / (v_j (1 - delta_v)) (Perron), whichever bound is smaller
    for d, ratio in ((delta_row, np.ones((B, n, n))), (delta_v, v[:, :, None] / v[:, None, :])):
        use = ~bad & (d < CERTIFY_NEUMANN_MAX)
        tail = (Interval(1.0) - Interval(np.where(use, d, 0.0))).reciprocal().hi
        S = ratio * (tail * growth)[:, None, None]
        series = up_bound(eye + A + up_bound(E2 @ S, n), 3)
        bound = up_bound(XE @ series, n)
        R = np.where(use[:, None, None], np.minimum(R, bound), R)
    R = np.where((bad | loose)[:, None, None], 0.0, R)
    return Interval(X) + Interval(-R, R), reason


def inverse_over_box(
    box: Interval, centre: Interval, grad: Interval, radius: np.ndarray
) -> tuple[Interval, np.ndarray]:
    """Enclosures of M(q)^-1 over each box of a batch for a symmetric
    M(q), from its enclosure over the box (B, n, n), its value at the centre
    and its derivatives' enclosures (B, k, n, n) (mean-value form,
    half-widths ``radius`` (B, k)), and per box the reason there is none.

    Two bounds, intersected: the entrywise Neumann bounds on the interval
    matrix (:func:`inverse_enclosures`), and a norm bound in the centre's
    own scaling, which keeps the signs the entrywise one loses. With
    ``M_c = Q diag(lambda) Q^T`` (the centre's midpoint), ``W = Q
    |diag(lambda)|^-1/2`` and ``S = sign(diag(lambda))``, for every
    invertible W ``M^-1 = W N^-1 W^T`` with ``N = W^T M W = S - F``; on the
    box ``|F|_2 <= delta = |S - W^T M_c W|_F + sum_k h_k (|W^T mid(D_k)
    W|_2 + ||W|^T rad(D_k) |W||_F)`` (D_k in dM/dq_k's enclosure), and when
    delta < 1, ``N^-1 = S + S F (I - S F)^-1 S`` with that last term of
    norm at most delta / (1 - delta): entry (i, j) of ``M^-1 - W S W^T``
    is at most ``|w_i| |w_j| delta / (1 - delta)`` (w_i the rows of W)."""
    inv, reason = inverse_enclosures(box)
    n = centre.shape[-1]
    finite = np.all(np.isfinite(centre.lo) & np.isfinite(centre.hi), axis=(1, 2)) & np.all(
        np.isfinite(grad.lo) & np.isfinite(grad.hi), axis=(1, 2, 3)
    )
    eye = np.eye(n)
    mid = np.where(finite[:, None, None], centre.midpoint, eye)
    lam, Q = np.linalg.eigh(0.5 * (mid + np.swapaxes(mid, 1, 2)))
    size = np.abs(lam).max(axis=1)
    good = finite & (np.abs(lam).min(axis=1) > 1e3 * n * _EPS * size)
    lam = np.where(good[:, None], lam, 1.0)
    W = Q / np.sqrt(np.abs(lam))[:, None, :]
    S = np.sign(lam)
    absW = np.abs(W)
    WT = np.swapaxes(W, 1, 2)
    Nc = matmul(WT, matmul(centre, W))  # W^T M_c W, rounded outward
    F_c = Interval(np.eye(n) * S[:, :, None]) - Nc
    gmid = np.where(good[:, None, None, None], grad.midpoint, 0.0)
    grad_rad = np.where(good[:, None, None, None], np.maximum(grad.hi - gmid, gmid - grad.lo), 0.0)
    with np.errstate(all="ignore"):
        scaled = WT[:, None] @ gmid @ W[:, None]  # (B, k, n, n)
        spectral = np.linalg.norm(scaled, 2, axis=(-2, -1)) * (1 + 1e-10) + 8 * n * _EPS * (
            norm_upper(np.abs(WT[:, None]) @ np.abs(gmid) @ absW[:, None], (-2, -1))
        )
        spread = norm_upper(
            up_bound(np.swapaxes(absW, 1, 2)[:, None] @ grad_rad @ absW[:, None], n), (-2, -1)
        )
        delta = up_bound(
            norm_upper(F_c.magnitude, (1, 2)) + up_bound((radius * (spectral + spread)).sum(1), n),
            2,
        )
    use = good & (delta < CERTIFY_NEUMANN_MAX)
    with np.errstate(all="ignore"):
        tail = (
            Interval(np.where(use, delta, 0.0))
            / (Interval(1.0) - Interval(np.where(use, delta, 0.0)))
        ).hi
        rows = norm_upper(W, 2)  # (B, n)
        R = up_bound(rows[:, :, None] * rows[:, None, :] * tail[:, None, None], 3)
    centre_inv = matmul(W * S[:, None, :], WT)
    norm_inv = centre_inv + Interval(-R, R)
    valid = reason == ""
    lo = np.where(use[:, None, None], norm_inv.lo, inv.lo)
    hi = np.where(use[:, None, None], norm_inv.hi, inv.hi)
    both = use & valid
    lo = np.where(both[:, None, None], np.maximum(lo, inv.lo), lo)
    hi = np.where(both[:, None, None], np.minimum(hi, inv.hi), hi)
    reason = np.where(use, "", reason)
    return Interval._raw(lo, hi), reason
