"""Sampled search for a positive-span certificate of POC.

The outputs g_j(t) of the reduced system are sampled on growing time grids
(cheapest first) until finitely many of them positively span the output
space (a YES certificate), else the last samples and a candidate separator
go back to the caller. Used by the modal, Brammer and general paths.
"""

from __future__ import annotations

import numpy as np

from cdpm.analysis import _modes
from cdpm.analysis._common import Verdict, scaled_system
from cdpm.analysis._reduced import Reduced, marginal
from cdpm.analysis._span_hull import min_norm_separator
from cdpm.analysis.span import span_core
from cdpm.numerics import LOG_DYNAMIC_RANGE, MODAL_LOG_GROWTH, SPAN_TOL, SPREAD_MIN, ZERO_RTOL


def sampled_yes(sub: Reduced, T, method, reason, sc=None):
    """YES certificate for an exact path: sample, then refine if needed."""
    found = sample_search(sub, T, sc)
    if found[0] == "yes":
        return Verdict.YES, method, reason, found[1], T
    return marginal(
        method, "the exact test says yes but no sampled certificate clears the tolerance", sub, T
    )


class Scaled:
    """Scaled reduced system with its evaluator (times in units 1/rho)."""

    def __init__(self, sub: Reduced):
        As, Bs, Cs, _, col, row, rho = scaled_system(sub.A, sub.Bp, sub.Cr)
        self.As, self.Bs, self.Cs, self.col, self.row, self.rho = As, Bs, Cs, col, row, rho
        self.ev = _modes.Evaluator(As, Bs, Cs)
        lam = self.ev.eigvals if As.size else np.zeros(1)
        spread = float(lam.real.max() - lam.real.min())
        self.t_max = LOG_DYNAMIC_RANGE / spread if spread > SPREAD_MIN else np.inf

    def columns(self, ts):
        """Sample columns (r, N*m), column k*m + j = g_j(ts[k]); times whose
        responses overflow are dropped (returned ``ts`` is filtered).

        A column is round-off, and set to exactly 0, when it is below
        ``ZERO_RTOL`` times its own round-off scale (the modal sum of
        magnitudes that produced it), never relative to the largest column:
        a growing mode makes late columns dwarf early ones by many orders of
        magnitude, yet the early ones are exact directions.
        """
        # past a modal dynamic range of e^27 (~1e12) double precision no
        # longer resolves the slower directions: sample up to there only
        ts = ts[ts <= self.t_max]
        with np.errstate(over="ignore", invalid="ignore"):
            G, scale = self.ev.with_scale(ts)  # (N, r, m), (N, m)
        ok = np.isfinite(G).all(axis=(1, 2)) & (np.abs(G).max(axis=(1, 2)) < 1e150)
        if not ok.all():
            G, ts, scale = G[ok], ts[ok], scale[ok]
        N, r, m = G.shape
        S = G.transpose(1, 0, 2).reshape(r, N * m)
        small = np.linalg.norm(S, axis=0) <= ZERO_RTOL * scale.reshape(-1)
        if small.any():
            S[:, small] = 0.0
        return S, m, ts


class ModalScaled(Scaled):
    """The modal evaluator in original units (no scaling needed: span
    decisions normalise each output vector).

    Sampling stops where the fastest growing mode has grown by ``1e8``
    (``sinh(w t) / w``, ``w t = ln 1e8``): beyond that a slower mode's part
    of g_j(t) is below the round-off of ``expm(A t)`` in the certificate's
    re-check, and the late columns all point along the growing mode anyway.
    """

    #: log of the largest growth of a sampled response
    LOG_GROWTH = MODAL_LOG_GROWTH

    def columns(self, ts):
        """As :meth:`Scaled.columns`; no overflow check is needed (times
        stop at ``t_max``, where the responses have grown by 1e8)."""
        ts = ts[ts <= self.t_max]
        S, scale = self.ev.columns(ts)
        small = np.sqrt(np.einsum("ij,ij->j", S, S)) <= ZERO_RTOL * scale
        if small.any():
            S[:, small] = 0.0
        return S, self.ev.beta.shape[1], ts

    def __init__(self, ev):
        self.ev = ev
        self.rho = 1.0
        grow = ev.w[ev.grow]
        self.t_max = self.LOG_GROWTH / grow.max() if grow.size else np.inf
        m = ev.beta.shape[1]
        self.col, self.row = np.ones(m), np.ones(ev.CqU.shape[0])


#: the first, cheapest sample times on [0, 1] (most YES answers need no more)
_FIRST = np.arange(1, 8) / 7.0


def sample_search(sub: Reduced, T, sc=None, extra=None):
    """Positive span over samples; returns ("yes", cert) or ("no", v_s, S, ts, m).

    The grids cover [0, min(T, t_max)]: the part of the horizon where every
    mode is still resolved next to the fastest growing one (a certificate
    needs the slow modes' sign changes, which late samples no longer show).
    """
    sc = sc or Scaled(sub)
    Ts = min(T * sc.rho, sc.t_max)
    # three stages, cheapest first: most YES answers need only a few times
    grids = [Ts * _FIRST, _modes.coarse_times(Ts), None]
    if extra is not None:
        grids = grids[1:]
    ts = None
    for grid in grids:
        if grid is None:
            grid = _modes.fine_times(Ts, sc.ev.eigvals)
        if ts is None and extra is None:
            ts = grid  # sorted and unique
        else:
            parts = [grid] if ts is None else [ts, grid]
            ts = np.unique(np.concatenate(parts if extra is None else [*parts, extra]))
        S, m, ts = sc.columns(ts)
        # columns were cleaned per vector: only exact zeros are zero here
        yes, _, _, idx, w, v = span_core(S, SPAN_TOL, zero_rtol=0.0)
        if yes:
            return "yes", _cert_from_columns(sub, sc, S, ts, m, idx, w)
    return "no", v, S, ts, m


def _cert_from_columns(sub, sc, S, ts, m, idx, w):
    idx = np.asarray(idx)
    k, j = idx // m, idx % m
    # span_core's weights refer to unit columns; S holds the raw ones
    raw = S[:, idx].T  # (K, r)
    wr = np.asarray(w) / np.linalg.norm(raw, axis=1)  # weights on raw scaled columns
    vectors = raw.T / sc.row[:, None] / sc.col[j]  # the outputs in original units
    # raw scaled g_s = row * g * col_j, so sum wr g_s = 0 <=> sum (wr col_j) g = 0
    return sub.yes(ts[k] / sc.rho, j, wr * sc.col[j], vectors)


def separator(S, v):
    """Max-margin separator of the normalised samples (min-norm point), or v."""
    norms = np.linalg.norm(S, axis=0)
    keep = norms > 0  # round-off columns were set to 0 by Scaled.columns
    found = min_norm_separator(S[:, keep] / norms[keep])
    return v if found is None else found[0]
