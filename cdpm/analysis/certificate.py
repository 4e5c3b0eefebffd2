"""Certificates of positive output controllability and their re-check.

:meth:`POCCertificate.verify` never reuses the search that produced a
certificate: it recomputes ``g_j(t) = C e^{At} b_j`` with
:func:`scipy.linalg.expm`, redoes the positive-span test by direct linear
algebra (:func:`cdpm.analysis.span.check_positive_combination`), and for a
separator re-evaluates ``v^T g_j(t)`` on its own dense grid plus the
path-specific algebraic facts (nilpotency, eigenvector residuals, Taylor
signs, the tail bound from a fresh eigen-decomposition). A modal YES
certificate is re-checked on left eigenspaces recomputed as null spaces of
``K^T - kappa I`` (SVD, no eigen-solver).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from cdpm.analysis._common import as_system, krylov_basis, scaled_system
from cdpm.analysis.span import check_positive_combination
from cdpm.numerics import (
    INVERTIBLE_COND_MAX,
    KAPPA_ZERO_RTOL,
    POC_RECHECK_TOL,
    RECHECK_DOMINANT_ATOL,
    RECHECK_EIG_RTOL,
    RECHECK_EXPM_ROUNDOFF_RTOL,
    RECHECK_MECHANICAL_RTOL,
    RECHECK_MODAL_RANK_RTOL,
    RECHECK_MODE_RTOL,
    RECHECK_REAL_ATOL,
    RECHECK_SQUARE_ZERO_RTOL,
    RECHECK_TAYLOR_ATOL,
    RECHECK_VECTOR_RTOL,
)
from cdpm.printing import to_plain

__all__ = ["POCCertificate"]


@dataclass(frozen=True)
class POCCertificate:
    """Proof of a positive output controllability verdict.

    Attributes:
        kind: ``"positive-span"`` (YES), ``"modal"`` (YES by the exact
            mechanical modal test, when no sampled pairs resolve it: see
            ``proof["modes"]``), ``"separator"`` (NO) or ``"none"``
            (MARGINAL: nothing proven).
        times: (K,) times t_k [s or the system's time unit] of the YES pairs.
        inputs: (K,) input indices j_k.
        signs: (K,) +1, or -1 for a free input used with negative sign.
        vectors: (p, K) output vectors g_{j_k}(t_k) = C e^{A t_k} b_{j_k}.
        weights: (K,) strictly positive weights with
            ``sum_k weights[k] * signs[k] * vectors[:, k] = 0``; the signed
            vectors have rank p, so they positively span R^p (Theorem 1).
        separator: (p,) unit v with v^T g_j(t) <= 0 for all t >= 0 and every
            sign-constrained j, and v^T g_j(t) = 0 for free j.
        proof: path-specific proof data (plain numbers), see docs/analysis.md.
        sign_constrained: the input mask the certificate refers to.
    """

    kind: str
    sign_constrained: np.ndarray
    times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    inputs: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    signs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    vectors: np.ndarray | None = None
    weights: np.ndarray | None = None
    separator: np.ndarray | None = None
    proof: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return to_plain(
            {
                "kind": self.kind,
                "times": self.times,
                "inputs": self.inputs,
                "signs": self.signs,
                "vectors": self.vectors,
                "weights": self.weights,
                "separator": self.separator,
                "proof": self.proof,
                "sign_constrained": self.sign_constrained,
            }
        )

    def verify(self, A, B, C, tol: float = POC_RECHECK_TOL) -> bool:
        """Re-check this certificate against (A, B, C) independently.

        Args:
            A, B, C: the system, shapes (n, n), (n, m), (p, n).
            tol: relative tolerance of the re-check.

        Returns:
            True when the certificate proves its verdict; False otherwise
            (always False for ``kind == "none"``).
        """
        A, B, C, mask = as_system(A, B, C, self.sign_constrained)
        if self.kind == "positive-span":
            return _verify_span(self, A, B, C, mask, tol)
        if self.kind == "separator":
            return _verify_separator(self, A, B, C, mask, tol)
        if self.kind == "modal":
            return _verify_modal_span(self, A, B, C, mask, tol)
        return False


def _verify_span(cert, A, B, C, mask, tol) -> bool:
    p = C.shape[0]
    if p == 0:
        return True
    t = np.asarray(cert.times, dtype=float)
    j = np.asarray(cert.inputs, dtype=int)
    s = np.asarray(cert.signs, dtype=float)
    if t.size == 0 or np.any(t < 0) or np.any((s < 0) & mask[j]):
        return False
    G = np.stack([C @ (expm(A * ti) @ B[:, ji]) for ti, ji in zip(t, j, strict=True)], axis=1)
    ref = np.linalg.norm(G, axis=0) + 1e-300
    if np.any(np.linalg.norm(G - cert.vectors, axis=0) > RECHECK_VECTOR_RTOL * ref):
        return False
    return check_positive_combination(G * s, np.asarray(cert.weights, dtype=float), tol)


def _verify_separator(cert, A, B, C, mask, tol) -> bool:
    v = np.asarray(cert.separator, dtype=float)
    if v.shape != (C.shape[0],) or np.linalg.norm(v) == 0:
        return False
    v = v / np.linalg.norm(v)
    proof = cert.proof
    horizon = float(proof.get("horizon", 1.0))
    if not _dense_grid_ok(A, B, C, mask, v, horizon, proof.get("check_times", []), tol):
        return False
    if (~mask).any() and not _krylov_orthogonal(A, B[:, ~mask], C, v, tol):
        return False
    path = proof.get("path")
    if path == "output-rank":
        return _krylov_orthogonal(A, B, C, v, tol)
    if path == "nilpotent":
        AA = np.abs(A @ A) <= RECHECK_SQUARE_ZERO_RTOL * (np.abs(A) @ np.abs(A)) + 1e-300
        w = v @ C
        c0, c1 = w @ B, w @ A @ B
        bn = np.linalg.norm(B, axis=0)
        r0 = np.linalg.norm(w) * bn + 1e-300
        r1 = np.linalg.norm(w) * np.linalg.norm(A, 2) * bn + 1e-300
        return bool(
            AA.all() and np.all(c0[mask] <= tol * r0[mask]) and np.all(c1[mask] <= tol * r1[mask])
        )
    if path == "modal":
        return _verify_modal(A, B, C, mask, v, proof, tol)
    if path == "brammer":
        w = v @ C
        lam = float(proof["eigenvalue"])
        res = np.linalg.norm(w @ A - lam * w)
        ref = np.linalg.norm(np.abs(w) @ np.abs(A)) + abs(lam) * np.linalg.norm(w)
        prod = w @ B
        pref = np.abs(w) @ np.abs(B) + 1e-300
        return bool(res <= tol * ref and np.all(prod[mask] <= tol * pref[mask]))
    if path == "general":
        return _verify_general(A, B, C, mask, v, proof, tol)
    return False


def _dense_grid_ok(A, B, C, mask, v, horizon, extra, tol) -> bool:
    """v^T g_j(t) <= 0 (constrained) / = 0 (free) on a dense grid by
    stepping with expm(A h): 600 points on [0, T], then 0.5 T steps to 20 T."""
    n = A.shape[0]
    growth = float(np.linalg.eigvals(A).real.max()) if n else 0.0
    if growth > 0:
        # past e^{300} the double-precision check means nothing: stop there
        horizon = min(horizon, 300.0 / growth / 20.0)
    h = horizon / 600
    Eh = expm(A * h)
    X = np.eye(n)
    w = v @ C
    wn = np.linalg.norm(w)
    # round-off scale of w^T X b_j: |v| |C| |X| |b_j| (|v| = 1)
    bn = np.linalg.norm(C) * np.linalg.norm(B, axis=0)
    vals, allow = [], []

    def record(X):
        Y = X @ B
        vals.append(w @ Y)
        # relative to |g_j| plus the round-off of X = e^{At} itself: a slow
        # direction next to a fast-growing one is known only to eps |X| |b_j|
        roundoff = RECHECK_EXPM_ROUNDOFF_RTOL * np.linalg.norm(X) * bn
        allow.append(tol * wn * np.linalg.norm(Y, axis=0) + roundoff)

    for _ in range(601):
        record(X)
        X = Eh @ X
    for t in list(horizon * np.arange(1.5, 20.5, 0.5)) + [float(x) for x in extra]:
        record(expm(A * t))
    vals, allow = np.array(vals), np.array(allow) + 1e-300
    return bool(
        np.all(vals[:, mask] <= allow[:, mask])
        and np.all(np.abs(vals[:, ~mask]) <= allow[:, ~mask])
    )


def _krylov_orthogonal(A, Bsel, C, v, tol) -> bool:
    """v^T C A^k Bsel = 0 for all k (so v^T C e^{At} Bsel = 0 for all t)."""
    if Bsel.shape[1] == 0:
        return True
    As, Bs, Cs, _, _, row, _ = scaled_system(A, Bsel, C)
    Q = krylov_basis(As, Bs)
    u = v / row
    u = u / np.linalg.norm(u)
    return bool(np.all(np.abs(u @ Cs @ Q) <= tol))


def _verify_modal(A, B, C, mask, v, proof, tol) -> bool:
    blocks = _mechanical_blocks(A, B, C, mask)
    if blocks is None:
        return False
    h, K, Cq, _ = blocks
    w = v @ Cq
    kappa = float(proof["kappa"])
    res = np.linalg.norm(w @ K - kappa * w)
    if res > tol * (np.linalg.norm(np.abs(w) @ np.abs(K)) + abs(kappa) * np.linalg.norm(w)):
        return False
    prod = w @ B[h:]
    pref = np.abs(w) @ np.abs(B[h:]) + 1e-300
    if kappa >= -tol * np.abs(K).max():
        return bool(np.all(prod[mask] <= tol * pref[mask]))
    return bool(np.all(np.abs(prod[mask]) <= tol * pref[mask]))


def _verify_general(A, B, C, mask, v, proof, tol) -> bool:
    """Taylor signs at 0 by matrix powers and the tail bound from a fresh
    eigen-decomposition; the grid part is covered by the dense expm grid."""
    As, Bs, Cs, _, _, row, rho = scaled_system(A, B, C)
    u = v / row
    u = u / np.linalg.norm(u)
    w = u @ Cs
    n = A.shape[0]
    lam, V = np.linalg.eig(As)
    cond = np.linalg.cond(V)
    if not np.isfinite(cond) or cond > INVERTIBLE_COND_MAX:
        return False
    WB = np.linalg.solve(V, Bs)
    wV = w @ V
    Tp = float(proof["horizon"]) * rho
    for j in np.flatnonzero(mask):
        x = Bs[:, j].copy()
        coeff = []
        for _ in range(n):
            coeff.append(w @ x)
            x = As @ x
        coeff = np.array(coeff)
        lead = np.flatnonzero(np.abs(coeff) > RECHECK_TAYLOR_ATOL)
        if lead.size and coeff[lead[0]] > 0:
            return False
        kap = wV * WB[:, j]
        mag = np.abs(kap)
        sig = mag > RECHECK_MODE_RTOL * max(mag.sum(), 1e-300)
        if not sig.any():
            continue
        alpha = lam.real[sig].max()
        dom = sig & (lam.real >= alpha - RECHECK_DOMINANT_ATOL)
        real = np.abs(lam.imag) <= RECHECK_REAL_ATOL
        lead_bound = np.sum(kap[dom & real].real) + np.sum(mag[dom & ~real])
        rest = sig & ~dom
        tail = lead_bound + np.sum(mag[rest] * np.exp((lam.real[rest] - alpha) * Tp * 20))
        if tail >= 0:
            return False
    return True


def _mechanical_blocks(A, B, C, mask):
    """(h, K, Cq, Bv) when A = [[0, I], [K, 0]], C = [Cq, 0] and the
    constrained inputs act on velocities only (B[:h] = 0); else None."""
    n = A.shape[0]
    h = n // 2
    if n == 0 or n % 2:
        return None
    ref = np.abs(A).max() + 1e-300
    zero = RECHECK_MECHANICAL_RTOL * ref
    if np.abs(A[:h, :h]).max() > zero or np.abs(A[h:, h:]).max() > zero:
        return None
    if np.abs(A[:h, h:] - np.eye(h)).max() > RECHECK_MECHANICAL_RTOL or np.abs(C[:, h:]).max() > 0:
        return None
    if np.abs(B[:h][:, mask]).max(initial=0.0) > 0:
        return None
    return h, A[h:, :h], C[:, :h], B[h:]


def _verify_modal_span(cert, A, B, C, mask, tol) -> bool:
    """The exact modal test, re-checked without an eigen-solver.

    With a full-pose output (Cq square, invertible) POC holds iff for each
    eigenvalue kappa of K (real, K diagonalisable) the products w^T Bv with
    the left eigenvectors w positively span (kappa >= 0) or have full rank
    (kappa < 0). Each claimed kappa's left eigenspace is recomputed as the
    null space of K^T - kappa I (SVD); their dimensions must add up to h,
    which proves K diagonalisable with exactly these eigenvalues.
    """
    blocks = _mechanical_blocks(A, B, C, mask)
    modes = cert.proof.get("modes") if isinstance(cert.proof, dict) else None
    if blocks is None or not modes:
        return False
    h, K, Cq, Bv = blocks
    if Cq.shape[0] != h or np.linalg.cond(Cq) > INVERTIBLE_COND_MAX:
        return False
    sK = float(np.linalg.norm(K, 2)) + 1e-300
    total = 0
    kappas = []
    for md in modes:
        kappa = float(md["kappa"])
        d = int(md["multiplicity"])
        inputs = np.asarray(md["inputs"], dtype=int)
        if d < 1 or inputs.size == 0 or np.any(inputs < 0) or np.any(inputs >= B.shape[1]):
            return False
        if not mask[inputs].all():
            return False
        _, s, Vt = np.linalg.svd(K.T - kappa * np.eye(h))
        W = Vt[h - d :].T  # (h, d): the d smallest singular directions
        if s[h - d] > RECHECK_EIG_RTOL * sK or (d < h and s[h - d - 1] <= RECHECK_EIG_RTOL * sK):
            return False  # kappa is not an eigenvalue of geometric multiplicity d
        total += d
        kappas.append(kappa)
        Z = W.T @ Bv[:, inputs]
        definite = kappa >= -KAPPA_ZERO_RTOL * sK
        if definite != bool(md["definite"]):
            return False
        if definite:
            if not check_positive_combination(Z, np.asarray(md["weights"], dtype=float), tol):
                return False
        else:
            norms = np.linalg.norm(Z, axis=0)
            if np.any(norms == 0):
                return False
            sz = np.linalg.svd(Z / norms, compute_uv=False)
            if sz.size < d or sz[d - 1] <= RECHECK_MODAL_RANK_RTOL * sz[0]:
                return False
    # distinct eigenvalues whose eigenspaces fill R^h: K is diagonalisable
    # and has no other eigenvalue
    ks = np.sort(kappas)
    return bool(total == h and np.all(np.diff(ks) > RECHECK_EIG_RTOL * sK))
