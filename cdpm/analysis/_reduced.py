"""The reduced POC problem shared by the decision paths, and its certificates.

With free inputs projected out (:mod:`cdpm.analysis.poc`, step 1) a path
decides POC(A, B+, N^T C); :class:`Reduced` carries that problem and lifts
its answers back to the full output space: a separator ``v = N v_red``
(rows rescaled), or a YES certificate whose constrained pairs combine into
the free inputs' reachable subspace and are cancelled there by free pairs
used with both signs. Also the output-rank test (POC needs
``rank C [B AB ...] = p``) with its separating direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from cdpm.analysis._common import Verdict, complement, svd, svdvals
from cdpm.analysis.certificate import POCCertificate
from cdpm.analysis.rank import output_reachable_basis
from cdpm.numerics import OUTPUT_RANK_QUICK_RATIO, RANK_RTOL, ROW_ZERO_RTOL


@dataclass
class Reduced:
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
        return lift_yes(
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


def lift_yes(A, B, C, mask, pairs, Fpairs, square_zero=False, vectors=None):
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


def marginal(method, reason, sub: Reduced, T, proof=None):
    """The MARGINAL outcome (verdict, method, reason, certificate, horizon)."""
    cert = POCCertificate("none", sub.mask, proof=proof or {"reason": reason})
    return Verdict.MARGINAL, method, reason, cert, T


def output_rank_defect(A, B, C, rn):
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
        if sx.size >= p and sx[p - 1] > OUTPUT_RANK_QUICK_RATIO * sx[0]:
            return None
    if p > n or (s := svdvals(Cw))[-1] <= RANK_RTOL * s[0]:
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
