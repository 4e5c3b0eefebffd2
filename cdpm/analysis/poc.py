"""Positive output controllability (POC) of an LTI system, with certificates.

Paper Theorem 1: (A, B, C) with inputs u_j >= 0 (sign-constrained j) and
u_j free (other j) is POC iff no nonzero v in R^p has v^T g_j(t) <= 0 for
all t >= 0 and constrained j, and v^T g_j(t) = 0 for free j, where
g_j(t) = C e^{At} b_j.

Decision pipeline (each step reported in ``POCResult.method``):

1. ``mixed-cone``: project the outputs onto the complement N of the output
   reachable subspace of the free inputs; POC(A, B, C) = POC(A, B+, N^T C).
   If N = {0} the answer is YES.
2. Exact fast paths on the reduced system: ``nilpotent`` (A^2 = 0),
   ``modal`` (A = [[0, I], [K, 0]], real diagonalisable K, position output,
   velocity input), ``full-rank-brammer`` (reduced C square invertible).
3. ``general``: sampled exchange search for a positive-span certificate,
   else a separating v with a proof (Taylor / sampled / tail bounds), else
   MARGINAL.

Layout: this module holds the public entry and the pipeline (free-input
samples, the output-rank check, the reduction); the paths live in
:mod:`~cdpm.analysis._nilpotent`, :mod:`~cdpm.analysis._modal` and
:mod:`~cdpm.analysis._general` (with the sampled search of
:mod:`~cdpm.analysis._sampled`), on the reduced problem of
:mod:`~cdpm.analysis._reduced`; the result type is
:class:`cdpm.analysis.poc_result.POCResult` and the margins are computed in
:mod:`~cdpm.analysis._poc_margin`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from cdpm.analysis._common import (
    Verdict,
    as_positive_vector,
    as_system,
    complement,
    orth,
    qr_pivots,
    scaled_system,
)
from cdpm.analysis._general import brammer_path, general_path
from cdpm.analysis._modal import modal_path, modal_yes_first
from cdpm.analysis._nilpotent import nilpotent_path, scalar_nilpotent
from cdpm.analysis._poc_margin import poc_margins as poc_margins
from cdpm.analysis._reduced import Reduced, lift_yes, output_rank_defect
from cdpm.analysis.certificate import POCCertificate
from cdpm.analysis.margin import log_growth_allowed, longest_horizon
from cdpm.analysis.poc_result import POCResult
from cdpm.analysis.poc_result import poc_margin as poc_margin
from cdpm.analysis.rank import output_reachable_basis
from cdpm.analysis.span import independent_columns
from cdpm.errors import InputError, check_tol, positive_number, round_down
from cdpm.numerics import (
    FREE_SAMPLE_ZERO_RTOL,
    FREE_SPAN_RATIO,
    HORIZON_BOUND_RTOL,
    HORIZON_GIVEN_MAX_UNITS,
    HORIZON_MAX_UNITS,
    ROW_ZERO_RTOL,
    SPAN_TOL,
)

# poc_margin, poc_margins and POCResult are re-exported: other code (cdpm.maps,
# cdpm.analysis.batch, tests) imports them, and _poc, from this module
__all__ = ["POCResult", "positive_output_controllability"]


def positive_output_controllability(
    A,
    B,
    C,
    sign_constrained=None,
    *,
    horizon: float | None = None,
    input_scale=None,
    output_weight=None,
    tol: float = SPAN_TOL,
) -> POCResult:
    """Decide positive output controllability (paper Theorem 1).

    Args:
        A: state matrix, shape (n, n).
        B: input matrix, shape (n, m).
        C: output matrix, shape (p, n).
        sign_constrained: bool mask (m,); True (default for all) = u_j >= 0
            (slack cable), False = free in sign (taut cable).
        horizon: time horizon T [time unit of A] for the sampled search and
            the margin; default: the search's from the spectrum and the
            margin's from :func:`cdpm.analysis.margin.margin_horizon` (see
            docs/analysis.md). Pass a fixed value to compare margins on one T.
        input_scale: positive (m,) input scales for the margin (e.g. tension
            bounds [N]); default ones.
        output_weight: positive (p,) output weights for the margin; default ones.
        tol: angle-like tolerance of the span decisions, in (0, 1) [rad].

    Returns:
        :class:`POCResult`.

    Raises:
        InputError: shapes, non-finite values or a bad mask.
    """
    if C is None:
        raise InputError(
            "C (the output matrix, shape (p, n)) is required; pass np.eye(n) for the whole state"
        )
    A, B, C, mask = as_system(A, B, C, sign_constrained)
    tol = check_tol(tol)
    if horizon is not None:
        message = f"horizon must be a positive finite time, got {horizon!r}"
        horizon = positive_number(horizon, message)
        _check_margin_horizon(A, C.shape[0], horizon)
    if input_scale is not None:
        input_scale = as_positive_vector("input_scale", input_scale, B.shape[1], "m (columns of B)")
    if output_weight is not None:
        output_weight = as_positive_vector(
            "output_weight", output_weight, C.shape[0], "p (rows of C)"
        )
    return _poc(A, B, C, mask, horizon, input_scale, output_weight, tol)


def _check_margin_horizon(A: np.ndarray, p: int, horizon: float) -> None:
    """Refuse a horizon over which the system's responses grow beyond
    what the margin resolves (the margin would be NaN, through overflow)."""
    units, longest, rate = longest_horizon(A, p)
    slack = 1.0 + HORIZON_BOUND_RTOL
    if horizon > units * slack and units <= longest:
        raise InputError(
            f"horizon {horizon:g} is too long for this system: at most {round_down(units):g}, "
            f"{HORIZON_GIVEN_MAX_UNITS:g} of its time units (1 / max(|A^2|^(1/2), "
            "|A|^(1/2))), beyond which its sampled responses overflow; give a shorter "
            f"horizon, or none (the default horizon is at most {HORIZON_MAX_UNITS:g} of these "
            "units)"
        )
    if horizon > longest * slack:
        raise InputError(
            f"horizon {horizon:g} is too long for this system: its fastest-growing mode "
            f"(Re lambda = {rate:.4g}) grows by a factor of e^{rate * horizon:.4g} within it, "
            f"and the margin resolves growths of at most {math.exp(log_growth_allowed(p)):.0e} "
            f"with {p} output(s); give a horizon of at most {round_down(longest):g}, or none "
            "(the default horizon stays within that bound)"
        )


def _poc(A, B, C, mask, horizon=None, input_scale=None, output_weight=None, tol=SPAN_TOL):
    """:func:`positive_output_controllability` without validation.

    For callers that evaluate many poses and have already validated float
    arrays of consistent shapes (A (n,n), B (n,m), C (p,n), bool mask (m,)).
    The arrays must not be mutated afterwards (the result keeps references).
    """
    out = None
    if C.shape[0] == 1 and mask.all():
        out = scalar_nilpotent(A, B, C, mask, horizon)
    if out is None:
        out = _decide(A, B, C, mask, horizon, tol)
    verdict, method, reason, cert, T = out
    return POCResult(
        verdict, method, reason, cert, T, A, B, C, mask, input_scale, output_weight, horizon
    )


# --------------------------------------------------------------------------
# the pipeline


def _decide(A, B, C, mask, horizon, tol):
    p, n = C.shape
    if p == 0:
        cert = POCCertificate("positive-span", mask, proof={"path": "trivial"})
        return Verdict.YES, "trivial", "the output space is R^0", cert, horizon or 1.0
    # output rank first: POC needs rank C [B AB ...] = p (every input, free
    # or not); after this check the reduced outputs N^T C below are never
    # round-off that a row scaling would blow up into a direction
    rn = np.linalg.norm(C, axis=1)
    free = ~mask
    if free.any() and rn.min() > ROW_ZERO_RTOL * rn.max():
        # most taut poses: a few early samples of the free inputs already
        # reach every output direction (this implies the output rank)
        cert = _free_inputs_span(A, B, C, mask)
        if cert is not None:
            T = horizon or float(cert.times.max())
            return Verdict.YES, "mixed-cone", _REASON_FREE_SPAN, cert, T
    elif not free.any():
        out = modal_yes_first(A, B, C, mask, rn, horizon, tol)
        if out is not None:
            return out
    v = output_rank_defect(A, B, C, rn)
    if v is not None:
        T = horizon or 1.0
        cert = POCCertificate(
            "separator", mask, separator=v, proof={"path": "output-rank", "horizon": T}
        )
        return Verdict.NO, "output-rank", _REASON_RANK, cert, T
    prefix = ""
    N = None
    Fpairs = None
    if free.any():
        F = output_reachable_basis(A, B[:, free], C)
        if F.shape[1]:
            prefix = "mixed-cone+"
            # complement in row-normalised output coordinates (Cw = C / rn)
            N = complement(orth(F / rn[:, None]), p)
            Fpairs = _free_pairs(A, B, C, np.flatnonzero(free), F.shape[1], horizon)
            if N.shape[1] == 0:
                cert = lift_yes(A, B, C, mask, None, Fpairs)
                T = horizon or float(max(Fpairs[0].max(), 1e-300))
                return Verdict.YES, "mixed-cone", _REASON_FREE_SPAN, cert, T
    Cr = C if N is None else N.T @ (C / rn[:, None])
    cons = np.flatnonzero(mask)
    if cons.size == 0:
        v = N[:, 0]
        T = horizon or 1.0
        cert = POCCertificate(
            "separator", mask, separator=v, proof={"path": "output-rank", "horizon": T}
        )
        return (
            Verdict.NO,
            "output-rank",
            "no sign-constrained input and the free inputs miss an output direction",
            cert,
            T,
        )
    sub = Reduced(A, B[:, cons], Cr, cons, N, Fpairs, mask, C, B, rn)
    for path in (nilpotent_path, modal_path, brammer_path, general_path):
        out = path(sub, horizon, tol)
        if out is not None:
            verdict, method, reason, cert, T = out
            return verdict, prefix + method, reason, cert, T
    raise AssertionError("the general path always decides")  # pragma: no cover


_REASON_RANK = (
    "not output controllable: some output direction v has v.C A^k B = 0 for every k "
    "(rank C [B AB ...] < p)"
)


_REASON_FREE_SPAN = "the free inputs alone reach every output direction"


def _free_samples(A, B, C, free, N, step):
    """Unit-column samples of the free inputs' outputs at t_k = k step / |A|
    (k = 1..N, balanced and scaled system): returns (U (p, N f), S, times,
    col, row) with S the raw scaled columns (column k f + j = g_{free[j]}(t_k)
    scaled) and U = S with unit columns, round-off columns (below 1e-9 of
    the longest) set to 0 so they are never normalised into directions
    (all of U is 0 when S is 0 or not finite)."""
    As, Bs, Cs, _, col, row, rho = scaled_system(A, B[:, free], C)
    # step x(t + h) = e^{As h} x(t): one small expm, no eigen-solve
    E = expm(As * step)
    p = C.shape[0]
    X, G = Bs, np.empty((N, p, free.size))
    for i in range(N):
        X = E @ X
        G[i] = Cs @ X
    S = G.transpose(1, 0, 2).reshape(p, -1)
    norms = np.sqrt(np.einsum("ij,ij->j", S, S))
    big = norms.max() if np.all(np.isfinite(norms)) else np.nan
    U = (
        S / np.where(norms > FREE_SAMPLE_ZERO_RTOL * big, norms, np.inf)
        if big > 0
        else np.zeros_like(S)
    )
    return U, S, np.arange(1, N + 1) * step / rho, col, row


def _free_inputs_span(A, B, C, mask):
    """YES certificate from free inputs alone, or None: p samples
    g_f(t_k) (7 times t_k in (0, 8/|A|_F]) that are robustly independent
    (pivoted QR, |R_pp| > 1e-6 |R_11| on unit columns), each used with both
    signs and unit weights. (|A|_F overestimates the spectral radius by up
    to sqrt(n): shorter times see only the first Krylov directions.)"""
    free = np.flatnonzero(~mask)
    p = C.shape[0]
    if free.size * 7 < p:
        return None
    U, S, times, col, row = _free_samples(A, B, C, free, 7, 8.0 / 7)
    piv, r = qr_pivots(U)
    if r.size < p or not r[p - 1] > FREE_SPAN_RATIO * r[0]:
        return None
    k = piv[:p]
    jl = k % free.size
    vecs = S[:, k] / row[:, None] / col[jl]  # scaled g_s = row * g * col_j
    return POCCertificate(
        "positive-span",
        mask,
        times=np.repeat(times[k // free.size], 2),
        inputs=np.repeat(free[jl], 2),
        signs=np.tile([1.0, -1.0], p),
        vectors=np.repeat(vecs, 2, axis=1),
        weights=np.ones(2 * p),
        proof={"path": "sampled-pairs"},
    )


def _free_pairs(A, B, C, free, r, horizon):
    """(t, j) pairs of free inputs whose outputs span their reachable subspace."""
    # early nonzero times suffice to span the free reachable subspace
    # (|As| = 1); g(0) = C b is often exactly 0 (velocity inputs)
    N = max(2 * A.shape[0], 7)
    U, S, times, col, row = _free_samples(A, B, C, free, N, 2.0 / N)
    k = independent_columns(U, r)
    jl = k % free.size
    # scaled g_s = row * g * col_j (see scaled_system)
    return times[k // free.size], free[jl], S[:, k] / row[:, None] / col[jl]
