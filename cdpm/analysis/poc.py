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
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm, lapack

from cdpm.analysis import _modes
from cdpm.analysis._common import (
    ROW_ZERO_RTOL,
    Verdict,
    as_positive_vector,
    as_system,
    cluster,
    complement,
    fmt_array,
    html_table,
    numerical_rank,
    orth,
    qr_pivots,
    scaled_system,
    svd,
    svdvals,
    to_plain,
)
from cdpm.analysis.brammer import left_eigen_separator
from cdpm.analysis.certificate import POCCertificate
from cdpm.analysis.margin import (
    grid_points,
    margin_horizon,
    margin_horizons,
    sample_curve,
    sample_curves,
    signed_inradii,
    signed_inradius,
)
from cdpm.analysis.rank import output_reachable_basis, reachable_basis
from cdpm.analysis.span import (
    SPAN_TOL,
    ZERO_RTOL,
    independent_columns,
    span_core,
)
from cdpm.errors import InputError

#: singular values of C with unit rows at most this (relative) are zero
RANK_TOL = 1e-10

__all__ = ["POCResult", "positive_output_controllability"]


@dataclass(frozen=True)
class POCResult:
    """Verdict of positive output controllability with its proof.

    Attributes:
        verdict: YES, NO or MARGINAL (``bool(result)`` is True only for YES).
        method: the path that decided: ``"trivial"``, ``"mixed-cone"``,
            ``"nilpotent"``, ``"modal"``, ``"full-rank-brammer"``,
            ``"output-rank"``, ``"general"``, prefixed ``"mixed-cone+"`` when
            free inputs were projected out first.
        reason: one readable sentence.
        certificate: :class:`~cdpm.analysis.certificate.POCCertificate`;
            ``result.certificate.verify(A, B, C)`` re-checks it.
        horizon: the horizon of the sampled search [time] (the certificate's
            times when a path needed longer).
        margin: ``mu_T = min_{|v|=1} max_{t in [0,T], j} v^T W C e^{At} b_j s_j``
            (W = output_weight, s = input_scale; free inputs count with both
            signs) with ``T = margin_horizon``: the signed inradius about 0
            of the outputs g_j(t_k) sampled on a fixed grid of [0, T]
            (a lower bound of mu_T, exact for A^2 = 0), continuous in
            (A, B, C). Positive iff POC is seen within T; clipped to <= 0
            unless the verdict is YES. See docs/analysis.md.
        margin_bracket: (lower, upper) bounds of mu_T (the upper bound adds
            the grid spacing times a Lipschitz bound of g; for p >= 4 the
            lower one is the cross-polytope bound r1 / sqrt(p)).
        margin_horizon: T of the margin: ``horizon=`` if given, else a
            continuous function of A (:func:`cdpm.analysis.margin.margin_horizon`).
        output_rank: rank of [CB, CAB, ...]; output_controllable: == p.
        A, B, C, sign_constrained: the (validated copies of the) system.
    """

    verdict: Verdict
    method: str
    reason: str
    certificate: POCCertificate
    horizon: float
    A: np.ndarray = field(repr=False)
    B: np.ndarray = field(repr=False)
    C: np.ndarray = field(repr=False)
    sign_constrained: np.ndarray = field(repr=False)
    input_scale: np.ndarray | None = field(repr=False)
    output_weight: np.ndarray | None = field(repr=False)
    fixed_horizon: float | None = field(default=None, repr=False)

    def __bool__(self) -> bool:
        return self.verdict is Verdict.YES

    @functools.cached_property
    def output_rank(self) -> int:
        return output_reachable_basis(self.A, self.B, self.C).shape[1]

    @property
    def output_controllable(self) -> bool:
        return self.output_rank == self.C.shape[0]

    @functools.cached_property
    def margin_horizon(self) -> float:
        """Horizon of the margin [time]: the ``horizon=`` passed by the
        caller, else :func:`~cdpm.analysis.margin.margin_horizon` (a
        continuous function of the spectrum, |A|_2, CB and CAB)."""
        return self.fixed_horizon or margin_horizon(self.A, self.B, self.C)

    @functools.cached_property
    def margin_bracket(self) -> tuple[float, float]:
        return poc_margin(self)

    @property
    def margin(self) -> float:
        return self.margin_bracket[0]

    def as_dict(self) -> dict:
        return to_plain(
            {
                "verdict": self.verdict,
                "method": self.method,
                "reason": self.reason,
                "margin": self.margin,
                "margin_bracket": list(self.margin_bracket),
                "horizon": self.horizon,
                "output_rank": self.output_rank,
                "output_controllable": self.output_controllable,
                "p": self.C.shape[0],
                "sign_constrained": self.sign_constrained,
                "certificate": self.certificate.as_dict(),
            }
        )

    def _certificate_lines(self) -> list[str]:
        c = self.certificate
        if c.kind == "positive-span":
            lines = [f"  {c.times.size} output vectors g_j(t) positively span R^{self.C.shape[0]}:"]
            for t, j, s, w in zip(c.times, c.inputs, c.signs, c.weights, strict=True):
                sign = "-" if s < 0 else "+"
                lines.append(f"    {sign}g_{j}(t={t:.4g}) weight {w:.4g}")
            return lines
        if c.kind == "modal":
            lines = ["  modal certificate (stiffness eigenvalues kappa of K):"]
            for md in c.proof["modes"]:
                used = ", ".join(map(str, md["inputs"]))
                what = "have full rank in it"
                if md["definite"]:
                    what = "positively span its eigenspace"
                lines.append(
                    f"    kappa {md['kappa']:.4g} (x{md['multiplicity']}): inputs {used} {what}"
                )
            return lines
        if c.kind == "separator":
            return [
                f"  separating v = {fmt_array(c.separator)} "
                f"(v.g_j(t) <= 0 for all t >= 0; {c.proof.get('path')} proof)"
            ]
        return []

    def __str__(self) -> str:
        head = (
            f"positive output controllability: {self.verdict} ({self.method}; "
            f"margin {self.margin + 0.0:.4g} on [0, {self.margin_horizon:.4g}])"
        )
        return "\n".join([head, f"  {self.reason}", *self._certificate_lines()])

    def _repr_html_(self) -> str:
        return html_table(
            f"Positive output controllability: {self.verdict}",
            [
                ("method", self.method),
                ("reason", self.reason),
                ("margin", f"{self.margin + 0.0:.4g} (horizon {self.margin_horizon:.4g})"),
                ("certificate", "\n".join(self._certificate_lines())),
            ],
        )


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
        tol: angle-like tolerance of the span decisions.

    Returns:
        :class:`POCResult`.

    Raises:
        InputError: shapes, non-finite values or a bad mask.
    """
    A, B, C, mask = as_system(A, B, C, sign_constrained)
    if horizon is not None and not (math.isfinite(horizon) and horizon > 0):
        raise InputError(f"horizon must be a positive finite time, got {horizon!r}")
    if input_scale is not None:
        input_scale = as_positive_vector("input_scale", input_scale, B.shape[1], "m (columns of B)")
    if output_weight is not None:
        output_weight = as_positive_vector(
            "output_weight", output_weight, C.shape[0], "p (rows of C)"
        )
    return _poc(A, B, C, mask, horizon, input_scale, output_weight, tol)


def _poc(A, B, C, mask, horizon=None, input_scale=None, output_weight=None, tol=SPAN_TOL):
    """:func:`positive_output_controllability` without validation.

    For callers that evaluate many poses and have already validated float
    arrays of consistent shapes (A (n,n), B (n,m), C (p,n), bool mask (m,)).
    The arrays must not be mutated afterwards (the result keeps references).
    """
    out = None
    if C.shape[0] == 1 and mask.all():
        out = _scalar_nilpotent(A, B, C, mask, horizon)
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
        out = _modal_yes_first(A, B, C, mask, rn, horizon, tol)
        if out is not None:
            return out
    v = _output_rank_defect(A, B, C, rn)
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
                cert = _lift_yes(A, B, C, mask, None, Fpairs)
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
    sub = _Reduced(A, B[:, cons], Cr, cons, N, Fpairs, mask, C, B, rn)
    for path in (_nilpotent, _modal, _brammer, _general):
        out = path(sub, horizon, tol)
        if out is not None:
            verdict, method, reason, cert, T = out
            return verdict, prefix + method, reason, cert, T
    raise AssertionError("the general path always decides")  # pragma: no cover


def _modal_yes_first(A, B, C, mask, rn, horizon, tol):
    """The modal path's YES before the output-rank check, for a mechanical
    system with every input constrained and a full, invertible pose output.

    A modal YES implies the output rank: with Cq invertible the rank is
    that of [Bv, K Bv, ...], which is h when every eigenspace of K gets
    modal input rows of full rank (PBH) - part of the modal test. Anything
    but YES returns None and the usual order (output rank first) decides.
    """
    h = _modal_structure(A, B, C)
    if h is None or C.shape[0] != h or rn.min() <= ROW_ZERO_RTOL * rn.max():
        return None
    s = svdvals(C[:, :h] / rn[:, None])
    if not s[-1] > RANK_TOL * s[0]:
        return None
    sub = _Reduced(A, B, C, np.arange(B.shape[1]), None, None, mask, C, B, rn)
    out = _modal(sub, horizon, tol, h)
    if out is None or out[0] is not Verdict.YES:
        return None
    return out


@dataclass
class _Reduced:
    """The reduced problem POC(A, Bp, Cr) and what is needed to lift back."""

    A: np.ndarray
    Bp: np.ndarray  # constrained columns of B
    Cr: np.ndarray  # N^T C (or C)
    cons: np.ndarray  # indices of the constrained inputs in B
    N: np.ndarray | None
    Fpairs: tuple | None
    mask: np.ndarray
    C: np.ndarray
    B: np.ndarray
    rn: np.ndarray  # row norms of C: Cr = N^T (C / rn) when reduced
    square_zero: bool = False
    modal_ev: object = None  # closed-form evaluator of an undamped mechanical system
    modal_T: float | None = None  # its default horizon

    def lift(self, v_red: np.ndarray) -> np.ndarray:
        v = v_red if self.N is None else (self.N @ v_red) / self.rn
        return v / np.linalg.norm(v)

    def yes(self, times, jloc, weights, vectors=None):
        """YES certificate from reduced pairs (t, local j) with weights such
        that sum w_k N^T g_k = 0; ``vectors`` (p, K) may give the full
        outputs g_k when already known (no free-input projection)."""
        pairs = (
            np.asarray(times, float),
            self.cons[np.asarray(jloc, int)],
            np.asarray(weights, float),
        )
        if self.N is not None:
            vectors = None
        return _lift_yes(
            self.A, self.B, self.C, self.mask, pairs, self.Fpairs, self.square_zero, vectors
        )

    def no(self, v_red, proof):
        return POCCertificate("separator", self.mask, separator=self.lift(v_red), proof=proof)


def _g(A, B, C, t, j, square_zero=False):
    """C e^{At} b_j for the certificate (small number of pairs); exact
    polynomial C (b_j + t A b_j) when A^2 = 0."""
    if square_zero:
        b = B[:, j]
        return C @ (b + t * (A @ b))
    return C @ (expm(A * t) @ B[:, j])


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
    U = S / np.where(norms > 1e-9 * big, norms, np.inf) if big > 0 else np.zeros_like(S)
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
    if r.size < p or not r[p - 1] > 1e-6 * r[0]:
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


def _lift_yes(A, B, C, mask, pairs, Fpairs, square_zero=False, vectors=None):
    """Assemble a YES certificate in the full output space.

    ``pairs`` = (times, inputs, weights) of constrained inputs whose reduced
    outputs combine to 0; their full outputs then combine into the free
    reachable subspace, which the free pairs (used with both signs) cancel.
    """
    p = C.shape[0]
    if Fpairs is None and vectors is not None:
        # no free inputs and the outputs known: plain arrays
        times, inputs, weights = pairs
        return POCCertificate(
            "positive-span",
            mask,
            times=times,
            inputs=np.asarray(inputs, dtype=int),
            signs=np.ones(times.size),
            vectors=vectors,
            weights=weights,
            proof={"path": "sampled-pairs"},
        )
    ts, js, ss, vs, ws = [], [], [], [], []
    total = np.zeros(p)
    if pairs is not None:
        for i, (t, j, w) in enumerate(zip(*pairs, strict=True)):
            g = _g(A, B, C, t, j, square_zero) if vectors is None else vectors[:, i]
            ts.append(t), js.append(j), ss.append(1.0), vs.append(g), ws.append(w)
            total += w * g
    if Fpairs is not None:
        ft, fj, F = Fpairs
        c = np.linalg.lstsq(F, -total, rcond=None)[0] if pairs is not None else np.zeros(ft.size)
        for i in range(ft.size):
            for sign in (1.0, -1.0):
                # a_i - b_i = c_i with a_i, b_i >= 1
                wt = max(sign * c[i], 0.0) + 1.0
                ts.append(ft[i]), js.append(fj[i]), ss.append(sign), vs.append(F[:, i])
                ws.append(wt)
    return POCCertificate(
        "positive-span",
        mask,
        times=np.array(ts),
        inputs=np.array(js, dtype=int),
        signs=np.array(ss),
        vectors=np.stack(vs, axis=1),
        weights=np.array(ws),
        proof={"path": "sampled-pairs"},
    )


# --------------------------------------------------------------------------
# nilpotent: A^2 = 0, g_j(t) = C b_j + t C A b_j


def _is_square_zero(A: np.ndarray) -> bool:
    """A^2 = 0 up to round-off, entrywise relative to |A| @ |A| (scale-free)."""
    return bool(_square_zero(A[None])[0])


def _square_zero(A: np.ndarray) -> np.ndarray:
    """:func:`_is_square_zero` of the matrices A (k, n, n), shape (k,)."""
    AA = A @ A
    small = np.abs(AA) <= 1e-12 * (np.abs(A) @ np.abs(A))
    return ~np.any(AA, axis=(1, 2)) | np.all(small, axis=(1, 2))


_REASON_RANK = (
    "not output controllable: some output direction v has v.C A^k B = 0 for every k "
    "(rank C [B AB ...] < p)"
)


def _output_rank_defect(A, B, C, rn):
    """A unit v with v^T C A^k B = 0 for all k (rank C[B AB ...] < p), or None.

    First the rank of C with unit rows (a stretched arm: tip x and z rows
    parallel), then a sufficient test on [CB, CAB], then the Krylov basis.
    """
    p, n = C.shape
    if np.any(rn <= ROW_ZERO_RTOL * rn.max()):
        # a zero or round-off row: that output is never reached
        v = np.zeros(p)
        v[int(np.argmin(rn))] = 1.0
        return v
    Cw = C / rn[:, None]
    bn = np.linalg.norm(B, axis=0)
    Bn = B[:, bn > 0] / bn[bn > 0]
    if Bn.shape[1] and p <= n:
        # the sufficient test first (rank [CB, CAB] = p implies rank C = p)
        a = float(np.abs(A).max())
        X = Cw @ Bn
        X = np.hstack([X, Cw @ (A @ Bn) / a]) if a > 0 else X
        sx = svdvals(X)
        if sx.size >= p and sx[p - 1] > 1e-8 * sx[0]:
            return None
    if p > n or (s := svdvals(Cw))[-1] <= RANK_TOL * s[0]:
        U, _, _ = svd(Cw, full_matrices=True)
        return _unit(U[:, -1] / rn)
    if Bn.shape[1] == 0:
        return _unit(svd(Cw, full_matrices=True)[0][:, -1] / rn)
    Y = output_reachable_basis(A, B, C)
    if Y.shape[1] == p:
        return None
    return _unit(complement(Y, p)[:, 0])


def _unit(v):
    return v / np.linalg.norm(v)


_REASON_NIL_YES = "A^2 = 0 and the columns of [CB, CAB] positively span the output space"
_REASON_NIL_NO = (
    "A^2 = 0 and a vector v has v.CB <= 0 and v.CAB <= 0 for every sign-constrained input"
)


def _scalar_nilpotent(A, B, C, mask, horizon):
    """p = 1, all inputs constrained, A^2 = 0 (the paper's case): a sign test
    on CB and CAB in plain Python floats; the same answer as the generic
    nilpotent path, with no LP, no expm and few array operations."""
    if A.shape[0] == 0 or not _is_square_zero(A):
        return None
    c = C[0]
    x0 = (c @ B).tolist()
    x1 = ((c @ A) @ B).tolist()
    a = float(np.abs(A).max())
    tau = 1.0 / a if a > 0 else 1.0
    T = horizon or tau
    y1 = [x * tau for x in x1]
    big = max(max(map(abs, x0)), max(map(abs, y1)))
    thr = 1e-11 * big
    pos = neg = None  # (value, t, j) of the largest positive / negative point
    for j, (u0, u1) in enumerate(zip(x0, y1, strict=True)):
        for u, t in ((u0, 0.0), (u1, None)):
            if abs(u) <= thr:
                continue
            if t is None:  # a late point g_j(t) = x0 + t x1 has the sign of x1
                t = max(tau, 2 * abs(x0[j]) / abs(x1[j]))
                u = x0[j] + t * x1[j]
            if u > 0 and (pos is None or u > pos[0]):
                pos = (u, t, j)
            elif u < 0 and (neg is None or u < neg[0]):
                neg = (u, t, j)
    if pos is None or neg is None:
        v = np.array([1.0 if pos is None else -1.0])
        proof = {
            "path": "nilpotent",
            "horizon": T,
            "vTCB": [v[0] * x for x in x0],
            "vTCAB": [v[0] * x for x in x1],
        }
        cert = POCCertificate("separator", mask, separator=v, proof=proof)
        return Verdict.NO, "nilpotent", _REASON_NIL_NO, cert, T
    cert = POCCertificate(
        "positive-span",
        mask,
        times=np.array([pos[1], neg[1]]),
        inputs=np.array([pos[2], neg[2]]),
        signs=np.ones(2),
        vectors=np.array([[pos[0], neg[0]]]),
        weights=np.array([-neg[0], pos[0]]),
        proof={"path": "sampled-pairs"},
    )
    return Verdict.YES, "nilpotent", _REASON_NIL_YES, cert, max(T, pos[1], neg[1])


def _nilpotent(sub: _Reduced, horizon, tol):
    A = sub.A
    if not _is_square_zero(A):
        return None
    sub.square_zero = True
    Cr, Bp = sub.Cr, sub.Bp
    P0 = Cr @ Bp
    P1 = Cr @ (A @ Bp)
    # time unit: balances |CB| against |CAB| without changing the verdict
    a = np.abs(A).max()
    tau = 1.0 / a if a > 0 else 1.0
    T = horizon or tau
    m = Bp.shape[1]
    S = np.hstack([P0, P1 * tau])
    yes, _, _, idx, w, v = span_core(S, tol)
    if not yes:
        vr = v
        proof = {
            "path": "nilpotent",
            "horizon": T,
            "vTCB": (vr @ P0).tolist(),
            "vTCAB": (vr @ P1).tolist(),
        }
        return (
            Verdict.NO,
            "nilpotent",
            "A^2 = 0 and a vector v has v.CB <= 0 and v.CAB <= 0 for every sign-constrained input",
            sub.no(vr, proof),
            T,
        )
    r = Cr.shape[0]
    if r == 1:
        times, jl, weights = _nilpotent_pairs_sign(P0[0], P1[0], idx, m, tau)
    else:
        found = _nilpotent_pairs(P0, P1, tau, tol)
        if found is None:
            return _marginal(
                "nilpotent",
                "the positive span of [CB, CAB] is within the tolerance of its boundary",
                sub,
                T,
            )
        times, jl, weights = found
    return (
        Verdict.YES,
        "nilpotent",
        "A^2 = 0 and the columns of [CB, CAB] positively span the output space",
        sub.yes(times, jl, weights),
        max(T, max(times)),
    )


def _nilpotent_pairs_sign(x0, x1, idx, m, tau):
    """p = 1: a positive and a negative curve point g_j(t) = x0_j + t x1_j."""
    pts = []
    for k in idx:
        j = int(k % m)
        if k < m:
            pts.append((0.0, j, x0[j]))
        else:
            t = max(tau, 2 * abs(x0[j]) / abs(x1[j]))
            pts.append((t, j, x0[j] + t * x1[j]))
    (t0, j0, g0), (t1, j1, g1) = pts
    return [t0, t1], [j0, j1], [abs(g1), abs(g0)]


def _nilpotent_pairs(P0, P1, tau, tol):
    """p >= 2: weights >= 1 on every nonzero column (one NNLS), then pairs
    (0, j) and (t_j, j) reproducing alpha_j CB_j + beta_j CAB_j exactly."""
    from scipy.optimize import nnls

    m = P0.shape[1]
    S = np.hstack([P0, P1 * tau])
    norms = np.linalg.norm(S, axis=0)
    nz = norms > 1e-11 * norms.max()
    U = S[:, nz] / norms[nz]
    mu, res = nnls(U, -U.sum(axis=1), maxiter=100 * U.shape[1])
    if res > 1e-10 * max(1.0, np.linalg.norm(U.sum(axis=1))):
        return None
    wfull = np.zeros(2 * m)
    wfull[nz] = (1.0 + mu) / norms[nz]
    alpha, beta = wfull[:m], wfull[m:] * tau  # weights on CB_j and on CAB_j
    times, jl, weights = [], [], []
    for j in range(m):
        if alpha[j] > 0 and beta[j] > 0:
            tj = 2 * beta[j] / alpha[j]
            times += [0.0, tj]
            jl += [j, j]
            weights += [alpha[j] / 2, alpha[j] / 2]
        elif alpha[j] > 0:
            times.append(0.0), jl.append(j), weights.append(alpha[j])
        elif beta[j] > 0:  # CB_j = 0: g_j(tau) = tau CAB_j
            times.append(tau), jl.append(j), weights.append(beta[j] / tau)
    return times, jl, weights


# --------------------------------------------------------------------------
# mechanical modal: A = [[0, I], [K, 0]], B = [0; Bv], C = [Cq, 0]


def _modal_structure(A, Bp, Cr):
    n = A.shape[0]
    if n % 2 or n == 0:
        return None
    h = n // 2
    if Bp[:h].any() or Cr[:, h:].any():
        return None
    # exact zero / identity blocks (the usual case) need no tolerance
    if A[:h, :h].any() or A[h:, h:].any() or not np.array_equal(A[:h, h:], np.eye(h)):
        ref = np.abs(A).max()
        if ref == 0:
            return None
        zero = 1e-12 * ref
        if (
            np.abs(A[:h, :h]).max() > zero
            or np.abs(A[h:, h:]).max() > zero
            or np.abs(A[:h, h:] - np.eye(h)).max() > 1e-12
        ):
            return None
    return h


def _real_eig(K):
    """(kappa, U) of a K with real eigenvalues (LAPACK geev, right vectors
    only), or None when some eigenvalue is complex beyond round-off."""
    wr, wi, _, vr, info = lapack.dgeev(K, compute_vl=0)
    if info != 0:  # pragma: no cover - LAPACK failure
        return None
    sK = float(np.abs(wr).max()) if wr.size else 0.0
    if wi.any():
        # conjugate pairs come packed as (Re v, Im v): take numpy's complex
        # vectors and keep their real parts when the pair is round-off
        kap, U = np.linalg.eig(K)
        sK = float(np.abs(kap).max())
        if sK == 0 or np.abs(kap.imag).max() > 1e-9 * sK:
            return None
        return kap.real, U.real, sK
    if sK == 0:
        return None
    return wr, vr, sK


def _modal(sub: _Reduced, horizon, tol, h=None):
    A, Bp, Cr = sub.A, sub.Bp, sub.Cr
    h = h or _modal_structure(A, Bp, Cr)
    if h is None:
        return None
    K = A[h:, :h]
    Cq, Bv = Cr[:, :h], Bp[h:]
    eig = _real_eig(K)
    if eig is None:
        return None
    kap, U, sK = eig
    try:
        Uinv = np.linalg.inv(U)
    except np.linalg.LinAlgError:
        return None
    # |U|_F |U^-1|_F bounds the condition number from above: no SVD needed
    cond = math.sqrt(float(np.vdot(U, U)) * float(np.vdot(Uinv, Uinv)))
    if not np.isfinite(cond) or cond > 1e8:
        return None
    beta = Uinv @ Bv
    # g(t) in closed form (sin / t / sinh): the general path samples with it
    sub.modal_ev = _modes.ModalEvaluator(kap, Cq @ U, beta, 1e-9 * sK)
    sub.modal_T = _modal_horizon(kap)
    if Cq.shape[0] == h:
        full = True  # square Cq, invertible (output rank checked): the full pose
    else:
        Q = orth(Cq.T)
        if Q.shape[1] < Cq.shape[0]:
            return None  # Cq rank deficient: the general path gives the rank certificate
        R = K.T @ Q
        if np.linalg.norm(R - Q @ (Q.T @ R)) > 1e-9 * np.linalg.norm(K):
            return None  # output rows not an invariant subspace: not exact
        full = Q.shape[1] == h
    bscale = np.linalg.norm(beta, axis=0) + 1e-300
    T = horizon or sub.modal_T
    simple = bool(np.all(np.diff(np.sort(kap)) > 1e-8 * sK))  # = no cluster of 2 or more
    if full and simple and _modal_rows_ok(kap, beta, bscale, sK):
        groups = []  # full pose, simple eigenvalues: every mode passed at once
    else:
        groups = cluster(kap, 1e-8 * sK)
    for group in groups:
        k = float(np.mean(kap[group]))
        # modal coordinates seen by the outputs (all of them for a full pose):
        # range(U_g^T Q). U has unit columns and Q orthonormal ones, so the
        # tolerance is absolute: an invisible mode gives round-off (1e-16)
        # that must not be normalised into a visible direction
        Ra = np.eye(group.size) if full else _visible(U[:, group].T @ Q)
        if Ra.shape[1] == 0:
            continue
        Z = Ra.T @ beta[group]
        Z[:, np.linalg.norm(Z, axis=0) <= 1e-10 * bscale] = 0.0
        definite = k >= -1e-9 * sK
        if definite:
            yes, _, _, _, _, c = span_core(Z, tol)
        else:
            Uz, s, _ = np.linalg.svd(Z, full_matrices=True)
            yes = numerical_rank(s, 1e-9) == Z.shape[0]
            c = None if yes else Uz[:, -1]
        if yes:
            continue
        w = Uinv[group].T @ (Ra @ c)  # left eigenvector of K: w^T K = k w^T
        vr = np.linalg.lstsq(Cq.T, w, rcond=None)[0]
        proof = {
            "path": "modal",
            "kappa": k,
            "horizon": T,
            "w": w.tolist(),
            "wTBv": (w @ Bv).tolist(),
        }
        kind = "sign-definite" if definite else "oscillatory"
        return (
            Verdict.NO,
            "modal",
            f"the {kind} mode with stiffness eigenvalue {k:.4g} cannot be driven "
            "in every direction by the sign-constrained inputs",
            sub.no(vr, proof),
            T,
        )
    reason = (
        "every sign-definite mode is positively spanned and every oscillatory mode has full rank"
    )
    found = _sample_search(sub, T, _ModalScaled(sub.modal_ev))
    if found[0] == "yes":
        return Verdict.YES, "modal", reason, found[1], T
    cert = _modal_certificate(sub, kap, beta, bscale, sK, tol) if full else None
    if cert is None:
        return _marginal(
            "modal",
            "the exact test says yes but no sampled certificate clears the tolerance",
            sub,
            T,
        )
    return (
        Verdict.YES,
        "modal",
        reason + " (modal certificate: no sampled pairs resolve the slow modes next to the "
        "fastest growing one in double precision)",
        cert,
        T,
    )


def _modal_certificate(sub, kap, beta, bscale, sK, tol):
    """The exact modal test as a certificate (full pose, no free input
    projected out): per cluster of stiffness eigenvalues kappa, input
    indices and, for a sign-definite one, strictly positive weights with
    ``w^T Bv[:, inputs] @ weights = 0`` for every left eigenvector w of
    kappa (and rank = multiplicity); for an oscillatory one, inputs whose
    modal rows have full rank. ``certificate.verify`` recomputes the left
    eigenspaces as null spaces of ``K^T - kappa I`` (no eigen-solver).
    Returns None when it cannot be built (then the answer is MARGINAL)."""
    if sub.N is not None:
        return None
    modes = []
    for group in cluster(kap, 1e-8 * sK):
        k = float(np.mean(kap[group]))
        Z = beta[group].copy()
        Z[:, np.linalg.norm(Z, axis=0) <= 1e-10 * bscale] = 0.0
        norms = np.linalg.norm(Z, axis=0)
        if k >= -1e-9 * sK:
            yes, _, _, idx, w, _ = span_core(Z, tol)
            if not yes:
                return None
            idx = np.asarray(idx)
            weights = np.asarray(w, dtype=float) / norms[idx]
        else:
            nz = np.flatnonzero(norms > 0)
            if nz.size < group.size:
                return None
            idx = nz[independent_columns(Z[:, nz] / norms[nz], group.size)]
            weights = np.zeros(0)
        modes.append(
            {
                "kappa": k,
                "multiplicity": int(group.size),
                "definite": bool(k >= -1e-9 * sK),
                "inputs": sub.cons[idx].tolist(),
                "weights": weights.tolist(),
            }
        )
    return POCCertificate("modal", sub.mask, proof={"path": "modal-span", "modes": modes})


def _modal_rows_ok(kap, beta, bscale, sK) -> bool:
    """Vectorised form of the per-mode test when every mode is its own group:
    a sign-definite mode's input row has both signs, an oscillatory one is
    nonzero (the same thresholds as the loop: 1e-10 of the input's size,
    then the sign test's 1e-11 of the row's largest entry)."""
    Z = np.where(np.abs(beta) <= 1e-10 * bscale, 0.0, beta)
    hi, lo = Z.max(axis=1), Z.min(axis=1)
    big = np.maximum(hi, -lo)
    thr = ZERO_RTOL * big
    both = (hi > thr) & (lo < -thr)
    return bool(np.all(np.where(kap >= -1e-9 * sK, both, big > 0)))


def _visible(M: np.ndarray) -> np.ndarray:
    """Orthonormal basis of range(M) with an absolute tolerance (M of unit scale)."""
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, s > 1e-8]


def _modal_horizon(kap):
    osc = np.sqrt(-kap[kap < 0])
    rates = np.sqrt(kap[kap > 0])
    T = 0.0
    if osc.size:
        T = max(T, 3 * 2 * math.pi / osc.min())
    if rates.size:
        T = max(T, 5.0 / rates.min())
    return T if T > 0 else 10.0 / math.sqrt(np.abs(kap).max())


# --------------------------------------------------------------------------
# full-rank output: POC(A, B, C) with C invertible = Brammer on (A, B)


def _brammer(sub: _Reduced, horizon, tol):
    A, Bp, Cr = sub.A, sub.Bp, sub.Cr
    n = A.shape[0]
    if Cr.shape[0] != n or np.linalg.cond(Cr) > 1e10:
        return None
    if reachable_basis(A, Bp).shape[1] < n:
        return None  # let the general path give the output-rank certificate
    mask = np.ones(Bp.shape[1], dtype=bool)
    w, lam, _ = left_eigen_separator(A, Bp, mask, tol)
    As = scaled_system(A, Bp, Cr)
    T = horizon or _modes.default_horizon(np.linalg.eigvals(As[0])) / As[6]
    if w is None:
        return _sampled_yes(
            sub,
            T,
            "full-rank-brammer",
            "C is invertible, (A, B) is controllable and no real "
            "eigenvector of A^T separates the inputs (Brammer)",
        )
    vr = np.linalg.solve(Cr.T, w)
    proof = {
        "path": "brammer",
        "eigenvalue": lam,
        "horizon": T,
        "w": w.tolist(),
        "wTB": (w @ Bp).tolist(),
    }
    return (
        Verdict.NO,
        "full-rank-brammer",
        f"C is invertible and a real eigenvector of A^T (eigenvalue {lam:.4g}) "
        "separates the inputs (Brammer)",
        sub.no(vr, proof),
        T,
    )


# --------------------------------------------------------------------------
# general: sampled exchange search with certificates


def _sampled_yes(sub, T, method, reason, sc=None):
    """YES certificate for an exact path: sample, then refine if needed."""
    found = _sample_search(sub, T, sc)
    if found[0] == "yes":
        return Verdict.YES, method, reason, found[1], T
    return _marginal(
        method, "the exact test says yes but no sampled certificate clears the tolerance", sub, T
    )


class _Scaled:
    """Scaled reduced system with its evaluator (times in units 1/rho)."""

    def __init__(self, sub: _Reduced):
        As, Bs, Cs, _, col, row, rho = scaled_system(sub.A, sub.Bp, sub.Cr)
        self.As, self.Bs, self.Cs, self.col, self.row, self.rho = As, Bs, Cs, col, row, rho
        self.ev = _modes.Evaluator(As, Bs, Cs)
        lam = self.ev.eigvals if As.size else np.zeros(1)
        spread = float(lam.real.max() - lam.real.min())
        self.t_max = 27.0 / spread if spread > 1e-12 else np.inf

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


class _ModalScaled(_Scaled):
    """The modal evaluator in original units (no scaling needed: span
    decisions normalise each output vector).

    Sampling stops where the fastest growing mode has grown by ``1e8``
    (``sinh(w t) / w``, ``w t = ln 1e8``): beyond that a slower mode's part
    of g_j(t) is below the round-off of ``expm(A t)`` in the certificate's
    re-check, and the late columns all point along the growing mode anyway.
    """

    #: log of the largest growth of a sampled response
    LOG_GROWTH = math.log(1e8)

    def columns(self, ts):
        """As :meth:`_Scaled.columns`; no overflow check is needed (times
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


def _sample_search(sub, T, sc=None, extra=None):
    """Positive span over samples; returns ("yes", cert) or ("no", v_s, S, ts, m).

    The grids cover [0, min(T, t_max)]: the part of the horizon where every
    mode is still resolved next to the fastest growing one (a certificate
    needs the slow modes' sign changes, which late samples no longer show).
    """
    sc = sc or _Scaled(sub)
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


def _marginal(method, reason, sub, T, proof=None):
    cert = POCCertificate("none", sub.mask, proof=proof or {"reason": reason})
    return Verdict.MARGINAL, method, reason, cert, T


def _general(sub: _Reduced, horizon, tol):
    # output rank of the reduced system (implied by the full system's rank,
    # re-checked here: cheap [CB, CAB] test first)
    v = None
    if sub.N is not None or sub.cons.size < sub.B.shape[1]:
        # (with every input constrained and nothing projected out this is
        # the full system's check, already passed)
        v = _output_rank_defect(sub.A, sub.Bp, sub.Cr, np.linalg.norm(sub.Cr, axis=1))
    T0 = horizon
    if v is not None:
        T = T0 or 1.0
        return (
            Verdict.NO,
            "output-rank",
            "not output controllable by the sign-constrained inputs in the directions "
            "the free inputs miss",
            sub.no(v, {"path": "output-rank", "horizon": T}),
            T,
        )
    if sub.modal_ev is not None:
        # undamped mechanical: sample the closed form first (no eigen-solve)
        T = T0 or sub.modal_T
        found = _sample_search(sub, T, _ModalScaled(sub.modal_ev))
        if found[0] == "yes":
            return Verdict.YES, "general", _REASON_GENERAL_YES, found[1], T
    sc = _Scaled(sub)
    Ts = T0 * sc.rho if T0 else _modes.default_horizon(sc.ev.eigvals)
    T = Ts / sc.rho
    extra = None
    last = "no separator found"
    for _ in range(6):
        found = _sample_search(sub, T, sc, extra)
        if found[0] == "yes":
            return Verdict.YES, "general", _REASON_GENERAL_YES, found[1], T
        _, v, S, ts, m = found
        sep = _separator(S, v)
        proofs, viol = [], []
        ok = True
        for j in range(m):
            good, data, bad = _modes.prove_nonpositive(sc.ev, sep, j, Ts)
            proofs.append(data)
            if not good:
                ok = False
                last = data.get("reason", "proof failed")
                viol += bad
        if ok:
            v_red = sep * sc.row
            Tp = max([d.get("grid_end", Ts) for d in proofs] + [Ts]) / sc.rho
            proof = {
                "path": "general",
                "horizon": Tp,
                "scaled_time_unit": 1 / sc.rho,
                "inputs": to_plain(proofs),
            }
            return (
                Verdict.NO,
                "general",
                "a separating v has v.g_j(t) <= 0 for all t >= 0, proven by Taylor, "
                "sampled and tail bounds",
                sub.no(v_red, proof),
                Tp,
            )
        if not viol:
            break
        extra = np.array(viol) if extra is None else np.concatenate([extra, viol])
    return _marginal(
        "general",
        f"neither certificate clears the tolerance ({last})",
        sub,
        T,
        {"reason": last, "candidate_separator": (sub.lift(sep * sc.row)).tolist()},
    )


_REASON_GENERAL_YES = "finitely many sampled output vectors positively span the output space"


def _separator(S, v):
    """Max-margin separator of the normalised samples (min-norm point), or v."""
    from cdpm.analysis.span import min_norm_separator

    norms = np.linalg.norm(S, axis=0)
    keep = norms > 0  # round-off columns were set to 0 by _Scaled.columns
    found = min_norm_separator(S[:, keep] / norms[keep])
    return v if found is None else found[0]


# --------------------------------------------------------------------------
# margin


def poc_margin(res: POCResult) -> tuple[float, float]:
    """(lower, upper) bounds of mu_T on [0, ``res.margin_horizon``] (see
    :mod:`cdpm.analysis.margin`); clipped to <= 0 unless the verdict is YES."""
    A, B, C, mask = res.A, res.B, res.C, res.sign_constrained
    p = C.shape[0]
    if p == 0:
        return math.inf, math.inf
    Bw = B if res.input_scale is None else B * res.input_scale
    Cw = C if res.output_weight is None else C * res.output_weight[:, None]
    T = res.margin_horizon
    square_zero = _is_square_zero(A)
    K = 2 if square_zero else grid_points(p)
    G, lip = sample_curve(A, Bw, Cw, T, K, square_zero)
    mu, hi = _sampled_inradius(G, mask, K)
    # the curve between grid points is within lip * h / 2 of the samples
    hi = max(hi, mu) + lip * T / (K - 1) / 2
    if res.verdict is not Verdict.YES:
        mu, hi = min(mu, 0.0), min(hi, 0.0)
    return float(mu), float(hi)


def _sampled_inradius(G: np.ndarray, mask: np.ndarray, K: int) -> tuple[float, float]:
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
    square_zero = _square_zero(A)
    curved = np.flatnonzero(~square_zero)
    K = grid_points(p)
    G, _ = sample_curves(A[curved], B[curved], C[curved], T[curved], K)
    patterns, group = np.unique(mask[curved], axis=0, return_inverse=True)
    for g, pattern in enumerate(patterns):
        sel = np.flatnonzero(group.reshape(-1) == g)
        cols = np.tile(pattern, K)
        Gs = G[sel]
        out[curved[sel]] = signed_inradii(Gs[:, :, cols], Gs[:, :, ~cols])
    for i in np.flatnonzero(square_zero):
        g, _ = sample_curve(A[i], B[i], C[i], T[i], 2, True)
        out[i] = _sampled_inradius(g, mask[i], 2)[0]
    return np.where(yes, out, np.minimum(out, 0.0))
