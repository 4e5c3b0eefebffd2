"""The modal POC path: an undamped mechanical system.

A = [[0, I], [K, 0]], B = [0; Bv], C = [Cq, 0] with K real diagonalisable
(K = U diag(kappa) U^-1): g(t) = Cq U diag(s_k(t)) U^-1 Bv with
s_k(t) = sin(w t)/w (kappa = -w^2 < 0, oscillatory), t (kappa = 0) or
sinh(w t)/w (kappa = w^2 > 0). POC of a pose output (and of outputs that
span a K^T-invariant subspace) is then decided mode by mode: the modal
input rows of a sign-definite mode (kappa >= 0) must positively span its
eigenspace, those of an oscillatory one must have full rank.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from cdpm.analysis import _modes
from cdpm.analysis._common import Verdict, cluster, numerical_rank, orth, svdvals
from cdpm.analysis._reduced import Reduced, marginal
from cdpm.analysis._sampled import ModalScaled, sample_search
from cdpm.analysis.certificate import POCCertificate
from cdpm.analysis.span import independent_columns, span_core
from cdpm.numerics import (
    INVARIANT_RTOL,
    KAPPA_CLUSTER_RTOL,
    KAPPA_ZERO_RTOL,
    MECHANICAL_BLOCK_RTOL,
    MODAL_PATH_COND_MAX,
    MODAL_ROW_ZERO_RTOL,
    RANK_RTOL,
    REAL_EIG_RTOL,
    ROW_ZERO_RTOL,
    SPAN_RANK_RTOL,
    VISIBLE_ATOL,
    ZERO_RTOL,
)


def modal_yes_first(A, B, C, mask, rn, horizon, tol):
    """The modal path's YES before the output-rank check, for a mechanical
    system with every input constrained and a full, invertible pose output.

    A modal YES implies the output rank: with Cq invertible the rank is
    that of [Bv, K Bv, ...], which is h when every eigenspace of K gets
    modal input rows of full rank (PBH) - part of the modal test. Anything
    but YES returns None and the usual order (output rank first) decides.
    """
    h = modal_structure(A, B, C)
    if h is None or C.shape[0] != h or rn.min() <= ROW_ZERO_RTOL * rn.max():
        return None
    s = svdvals(C[:, :h] / rn[:, None])
    if not s[-1] > RANK_RTOL * s[0]:
        return None
    sub = Reduced(A, B, C, np.arange(B.shape[1]), None, None, mask, C, B, rn)
    out = modal_path(sub, horizon, tol, h)
    if out is None or out[0] is not Verdict.YES:
        return None
    return out


def modal_structure(A, Bp, Cr):
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
        zero = MECHANICAL_BLOCK_RTOL * ref
        if (
            np.abs(A[:h, :h]).max() > zero
            or np.abs(A[h:, h:]).max() > zero
            or np.abs(A[:h, h:] - np.eye(h)).max() > MECHANICAL_BLOCK_RTOL
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
        if sK == 0 or np.abs(kap.imag).max() > REAL_EIG_RTOL * sK:
            return None
        return kap.real, U.real, sK
    if sK == 0:
        return None
    return wr, vr, sK


def modal_path(sub: Reduced, horizon, tol, h=None):
    A, Bp, Cr = sub.A, sub.Bp, sub.Cr
    h = h or modal_structure(A, Bp, Cr)
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
    if not np.isfinite(cond) or cond > MODAL_PATH_COND_MAX:
        return None
    beta = Uinv @ Bv
    # g(t) in closed form (sin / t / sinh): the general path samples with it
    sub.modal_ev = _modes.ModalEvaluator(kap, Cq @ U, beta, KAPPA_ZERO_RTOL * sK)
    sub.modal_T = _modal_horizon(kap)
    if Cq.shape[0] == h:
        full = True  # square Cq, invertible (output rank checked): the full pose
    else:
        Q = orth(Cq.T)
        if Q.shape[1] < Cq.shape[0]:
            return None  # Cq rank deficient: the general path gives the rank certificate
        R = K.T @ Q
        if np.linalg.norm(R - Q @ (Q.T @ R)) > INVARIANT_RTOL * np.linalg.norm(K):
            return None  # output rows not an invariant subspace: not exact
        full = Q.shape[1] == h
    bscale = np.linalg.norm(beta, axis=0) + 1e-300
    T = horizon or sub.modal_T
    # simple = no cluster of 2 or more
    simple = bool(np.all(np.diff(np.sort(kap)) > KAPPA_CLUSTER_RTOL * sK))
    if full and simple and _modal_rows_ok(kap, beta, bscale, sK):
        groups = []  # full pose, simple eigenvalues: every mode passed at once
    else:
        groups = cluster(kap, KAPPA_CLUSTER_RTOL * sK)
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
        Z[:, np.linalg.norm(Z, axis=0) <= MODAL_ROW_ZERO_RTOL * bscale] = 0.0
        definite = k >= -KAPPA_ZERO_RTOL * sK
        if definite:
            yes, _, _, _, _, c = span_core(Z, tol)
        else:
            Uz, s, _ = np.linalg.svd(Z, full_matrices=True)
            yes = numerical_rank(s, SPAN_RANK_RTOL) == Z.shape[0]
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
    found = sample_search(sub, T, ModalScaled(sub.modal_ev))
    if found[0] == "yes":
        return Verdict.YES, "modal", reason, found[1], T
    cert = _modal_certificate(sub, kap, beta, bscale, sK, tol) if full else None
    if cert is None:
        return marginal(
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
    for group in cluster(kap, KAPPA_CLUSTER_RTOL * sK):
        k = float(np.mean(kap[group]))
        Z = beta[group].copy()
        Z[:, np.linalg.norm(Z, axis=0) <= MODAL_ROW_ZERO_RTOL * bscale] = 0.0
        norms = np.linalg.norm(Z, axis=0)
        if k >= -KAPPA_ZERO_RTOL * sK:
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
                "definite": bool(k >= -KAPPA_ZERO_RTOL * sK),
                "inputs": sub.cons[idx].tolist(),
                "weights": weights.tolist(),
            }
        )
    return POCCertificate("modal", sub.mask, proof={"path": "modal-span", "modes": modes})


def _modal_rows_ok(kap, beta, bscale, sK) -> bool:
    """Vectorised form of the per-mode test when every mode is its own group:
    a sign-definite mode's input row has both signs, an oscillatory one is
    nonzero (the same thresholds as the loop: MODAL_ROW_ZERO_RTOL of the input's
    size, then the sign test's ZERO_RTOL of the row's largest entry)."""
    Z = np.where(np.abs(beta) <= MODAL_ROW_ZERO_RTOL * bscale, 0.0, beta)
    hi, lo = Z.max(axis=1), Z.min(axis=1)
    big = np.maximum(hi, -lo)
    thr = ZERO_RTOL * big
    both = (hi > thr) & (lo < -thr)
    return bool(np.all(np.where(kap >= -KAPPA_ZERO_RTOL * sK, both, big > 0)))


def _visible(M: np.ndarray) -> np.ndarray:
    """Orthonormal basis of range(M) with an absolute tolerance (M of unit scale)."""
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, s > VISIBLE_ATOL]


def _modal_horizon(kap):
    osc = np.sqrt(-kap[kap < 0])
    rates = np.sqrt(kap[kap > 0])
    T = 0.0
    if osc.size:
        T = max(T, 3 * 2 * math.pi / osc.min())
    if rates.size:
        T = max(T, 5.0 / rates.min())
    return T if T > 0 else 10.0 / math.sqrt(np.abs(kap).max())
