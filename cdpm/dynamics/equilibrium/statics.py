"""Statics of many poses at once: residuals, the tolerance that says they
hold, and which cables sit on a tension bound.

Every function takes a pose axis first; the per-pose API calls them on a
batch of one, so a map and :func:`cdpm.equilibrium_tension` judge alike.
"""

from __future__ import annotations

import numpy as np

from cdpm.numerics import STATICS_RTOL

__all__ = [
    "spectral_norms",
    "statics_tolerance",
    "residuals",
    "holds",
    "classify",
    "input_signs",
]


def spectral_norms(LT: np.ndarray) -> np.ndarray:
    """Largest singular value of each (nv, m) matrix of LT (k, nv, m)."""
    if LT.shape[0] == 0 or 0 in LT.shape[1:]:
        return np.zeros(LT.shape[0])
    return np.linalg.svd(LT, compute_uv=False)[:, 0]


def statics_tolerance(LT: np.ndarray, load: np.ndarray, f: np.ndarray, force: float) -> np.ndarray:
    """STATICS_RTOL max(|load|, |L^T|_2 max(force, |f|)) per pose [N or N m].

    The scale is the generalised force that tensions of the problem's own
    size exert: the robot's force scale (``force``, its weight: no absolute
    newton) or the tensions themselves when larger, or the load when that is
    larger still. Scaling every mass or every length of a robot scales the
    tolerance with its statics, so no verdict changes.

    Args:
        LT: L^T of each pose, shape (k, nv, m).
        load: the generalised force to balance, -G - w_ext, shape (k, nv).
        f: tensions [N], shape (k, m) (m may be 0: no tensions); non-finite
            rows count only the load and ``force``.
        force: the robot's force scale [N]
            (:attr:`cdpm.model.robot.CableRobot.force_scale`).
    """
    f_norm = np.linalg.norm(f, axis=1) if f.shape[1] else np.zeros(f.shape[0])
    tensions = np.where(np.isfinite(f_norm), np.maximum(f_norm, force), force)
    lever = np.zeros(LT.shape[0])
    pulls = tensions > 0
    if pulls.any():
        lever[pulls] = spectral_norms(LT[pulls]) * tensions[pulls]
    return STATICS_RTOL * np.maximum(np.linalg.norm(load, axis=1), lever)


def residuals(LT: np.ndarray, load: np.ndarray, f: np.ndarray) -> np.ndarray:
    """|L^T f - load| per pose, shape (k,) [N or N m]."""
    return np.linalg.norm((LT @ f[..., None])[..., 0] - load, axis=1)


def holds(LT: np.ndarray, load: np.ndarray, f: np.ndarray, force: float) -> np.ndarray:
    """Do tensions f (k, m) hold the poses (statics within tolerance)?

    The residual against :func:`statics_tolerance` (``force``: the robot's
    force scale [N]); the spectral norms in it are computed only for the
    poses that bounds cannot decide: |L^T|_F / sqrt(min(nv, m)) <= |L^T|_2
    <= |L^T|_F.
    """
    res = residuals(LT, load, f)
    load_norm = np.linalg.norm(load, axis=1)
    with np.errstate(invalid="ignore", over="ignore"):
        f_norm = np.linalg.norm(f, axis=1)
        tensions = np.where(np.isfinite(f_norm), np.maximum(f_norm, force), force)
        frobenius = np.sqrt((LT * LT).sum(axis=(1, 2)))
        frobenius = np.where(np.isfinite(frobenius), frobenius, 0.0)
        rank = max(1, min(LT.shape[1], LT.shape[2]))
        low = STATICS_RTOL * np.maximum(load_norm, frobenius / np.sqrt(rank) * tensions)
        high = STATICS_RTOL * np.maximum(load_norm, frobenius * tensions)
    out = res <= low
    unsure = np.flatnonzero(~out & (res <= high))
    if unsure.size:
        i = unsure
        out[i] = res[i] <= statics_tolerance(LT[i], load[i], f[i], force)
    return out


def classify(f: np.ndarray, fmin: np.ndarray, fmax: np.ndarray, force: float):
    """Which cables sit on a tension bound.

    A tension within STATICS_RTOL max(force, |f|) [N] of a bound sits on
    it; a pinned cable (f_min = f_max) is reported at its lower bound.

    Args:
        f: tensions [N], shape (..., m).
        fmin, fmax: the bounds [N], each (m,).
        force: the robot's force scale [N]
            (:attr:`cdpm.model.robot.CableRobot.force_scale`).

    Returns:
        (at_lower, at_upper, taut), boolean arrays shaped like f; ``taut``
        is f > 0.
    """
    scale = np.maximum(force, np.abs(f))
    at_lower = f <= fmin + STATICS_RTOL * scale
    at_upper = np.isfinite(fmax) & (f >= fmax - STATICS_RTOL * scale) & ~at_lower
    return at_lower, at_upper, f > 0


def input_signs(at_lower: np.ndarray, at_upper: np.ndarray) -> np.ndarray:
    """The sign of each cable's admissible tension change: +1 at its lower
    bound (it can only pull harder), -1 at its upper bound, 0 strictly
    inside (free); int, shaped like the masks (..., m)."""
    return np.where(at_lower, 1, np.where(at_upper, -1, 0))
