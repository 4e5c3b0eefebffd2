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


def _load_scale(load: np.ndarray) -> np.ndarray:
    """max(1, |load|) per pose: the tolerance's scale without the tensions."""
    return np.maximum(1.0, np.linalg.norm(load, axis=1))


def statics_tolerance(LT: np.ndarray, load: np.ndarray, f: np.ndarray) -> np.ndarray:
    """STATICS_RTOL max(1 N, |load|, |L^T|_2 |f|) per pose [N or N m].

    Args:
        LT: L^T of each pose, shape (k, nv, m).
        load: the generalised force to balance, -G - w_ext, shape (k, nv).
        f: tensions [N], shape (k, m); non-finite rows count only |load|.
    """
    scale = _load_scale(load)
    f_norm = np.linalg.norm(f, axis=1)
    finite = np.isfinite(f_norm) & (f_norm > 0)
    if finite.any():
        lever = np.zeros(f.shape[0])
        lever[finite] = spectral_norms(LT[finite]) * f_norm[finite]
        scale = np.maximum(scale, lever)
    return STATICS_RTOL * scale


def residuals(LT: np.ndarray, load: np.ndarray, f: np.ndarray) -> np.ndarray:
    """|L^T f - load| per pose, shape (k,) [N or N m]."""
    return np.linalg.norm((LT @ f[..., None])[..., 0] - load, axis=1)


def holds(LT: np.ndarray, load: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Do tensions f (k, m) hold the poses (statics within tolerance)?

    The residual against :func:`statics_tolerance`; the spectral norms in
    it are computed only for the poses that bounds cannot decide: the
    tolerance is at least STATICS_RTOL max(1, |load|) and at most that with
    the Frobenius norm of L^T in place of the spectral one.
    """
    res = residuals(LT, load, f)
    low = STATICS_RTOL * _load_scale(load)
    with np.errstate(invalid="ignore", over="ignore"):
        frobenius = np.sqrt((LT * LT).sum(axis=(1, 2))) * np.linalg.norm(f, axis=1)
        high = np.maximum(low, STATICS_RTOL * np.where(np.isfinite(frobenius), frobenius, 0.0))
    out = res <= low
    unsure = np.flatnonzero(~out & (res <= high))
    if unsure.size:
        i = unsure
        out[i] = res[i] <= statics_tolerance(LT[i], load[i], f[i])
    return out


def classify(f: np.ndarray, fmin: np.ndarray, fmax: np.ndarray):
    """Which cables sit on a tension bound.

    A tension within STATICS_RTOL max(1, |f|) [N] of a bound sits on it; a
    pinned cable (f_min = f_max) is reported at its lower bound.

    Args:
        f: tensions [N], shape (..., m).
        fmin, fmax: the bounds [N], each (m,).

    Returns:
        (at_lower, at_upper, taut), boolean arrays shaped like f; ``taut``
        is f > 0.
    """
    scale = np.maximum(1.0, np.abs(f))
    at_lower = f <= fmin + STATICS_RTOL * scale
    at_upper = np.isfinite(fmax) & (f >= fmax - STATICS_RTOL * scale) & ~at_lower
    return at_lower, at_upper, f > 0


def input_signs(at_lower: np.ndarray, at_upper: np.ndarray) -> np.ndarray:
    """The sign of each cable's admissible tension change: +1 at its lower
    bound (it can only pull harder), -1 at its upper bound, 0 strictly
    inside (free); int, shaped like the masks (..., m)."""
    return np.where(at_lower, 1, np.where(at_upper, -1, 0))
