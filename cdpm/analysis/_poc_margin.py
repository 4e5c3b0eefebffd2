"""The POC margin of one system and of many at once (see :mod:`cdpm.analysis.margin`).

:func:`margin_bracket` is ``POCResult.margin_bracket``; :func:`poc_margins`
gives the same lower bounds for k systems together (the horizons and curve
samples batched, the hulls vectorised for p <= 2).
"""

from __future__ import annotations

import math

import numpy as np

from cdpm.analysis._common import is_square_zero, square_zero
from cdpm.analysis.margin import (
    grid_points,
    margin_horizons,
    sample_curve,
    sample_curves,
    signed_inradii,
    signed_inradius,
)


def margin_bracket(A, B, C, mask, input_scale, output_weight, T, yes) -> tuple[float, float]:
    """(lower, upper) bounds of mu_T on [0, T] (see :mod:`cdpm.analysis.margin`);
    clipped to <= 0 unless ``yes`` (the verdict is YES).

    Args:
        A, B, C: the system, (n, n), (n, m), (p, n); mask: (m,) bool, True
            for sign-constrained inputs.
        input_scale: (m,) or None; output_weight: (p,) or None.
        T: the margin horizon [time].
        yes: the verdict is YES.
    """
    p = C.shape[0]
    if p == 0:
        return math.inf, math.inf
    Bw = B if input_scale is None else B * input_scale
    Cw = C if output_weight is None else C * output_weight[:, None]
    nilpotent = is_square_zero(A)
    K = 2 if nilpotent else grid_points(p)
    G, lip = sample_curve(A, Bw, Cw, T, K, nilpotent)
    mu, hi = sampled_inradius(G, mask, K)
    # the curve between grid points is within lip * h / 2 of the samples
    hi = max(hi, mu) + lip * T / (K - 1) / 2
    if not yes:
        mu, hi = min(mu, 0.0), min(hi, 0.0)
    return float(mu), float(hi)


def sampled_inradius(G: np.ndarray, mask: np.ndarray, K: int) -> tuple[float, float]:
    """signed_inradius of curve samples G (p, K m) (column k m + j = g_j(t_k)),
    the free inputs (mask False) with both signs."""
    if mask.all():
        return signed_inradius(G)
    cols = np.tile(mask, K)
    return signed_inradius(G[:, cols], G[:, ~cols])


def poc_margins(A, B, C, mask, yes) -> np.ndarray:
    """The margins (``POCResult.margin``) of k systems at once, with the
    default horizon, unit input scales and output weights.

    Equal to ``positive_output_controllability(A[i], B[i], C[i],
    mask[i]).margin`` given its verdict (``yes[i]``: the margin is clipped
    to <= 0 otherwise), computed for all systems together (the hulls one
    system at a time for p >= 3).

    Args:
        A: (k, n, n); B: (k, n, m); C: (k, p, n), p >= 1; mask: (k, m) bool,
        True for sign-constrained inputs; yes: (k,) bool, the verdicts.

    Returns:
        Margins, shape (k,).
    """
    k, p = A.shape[0], C.shape[1]
    out = np.empty(k)
    if k == 0:
        return out
    T = margin_horizons(A, B, C)
    nilpotent = square_zero(A)
    curved = np.flatnonzero(~nilpotent)
    K = grid_points(p)
    G, _ = sample_curves(A[curved], B[curved], C[curved], T[curved], K)
    patterns, group = np.unique(mask[curved], axis=0, return_inverse=True)
    for g, pattern in enumerate(patterns):
        sel = np.flatnonzero(group.reshape(-1) == g)
        cols = np.tile(pattern, K)
        Gs = G[sel]
        out[curved[sel]] = signed_inradii(Gs[:, :, cols], Gs[:, :, ~cols])
    for i in np.flatnonzero(nilpotent):
        g, _ = sample_curve(A[i], B[i], C[i], T[i], 2, True)
        out[i] = sampled_inradius(g, mask[i], 2)[0]
    return np.where(yes, out, np.minimum(out, 0.0))
