"""The nilpotent POC path: A^2 = 0, so g_j(t) = C b_j + t C A b_j.

POC then holds iff the columns of [CB, CAB] positively span the output
space (a mechanical system at zero tension, the paper's example): one span
decision, and certificate pairs (t, j) that reproduce the positive
combination exactly on the straight-line outputs.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from cdpm.analysis._common import Verdict, is_square_zero
from cdpm.analysis._reduced import Reduced, marginal
from cdpm.analysis.certificate import POCCertificate
from cdpm.analysis.exits import nilpotent_sign
from cdpm.analysis.span import span_core
from cdpm.numerics import NNLS_RES_RTOL, ZERO_RTOL

_REASON_NIL_YES = "A^2 = 0 and the columns of [CB, CAB] positively span the output space"
_REASON_NIL_NO = (
    "A^2 = 0 and a vector v has v.CB <= 0 and v.CAB <= 0 for every sign-constrained input"
)


def scalar_nilpotent(A, B, C, mask, horizon):
    """p = 1, all inputs constrained, A^2 = 0 (the paper's case): a sign test
    on CB and CAB in plain Python floats; the same answer as the generic
    nilpotent path, with no LP, no expm and few array operations."""
    if A.shape[0] == 0 or not is_square_zero(A):
        return None
    c = C[0]
    x0 = (c @ B).tolist()
    x1 = ((c @ A) @ B).tolist()
    a = float(np.abs(A).max())
    tau = 1.0 / a if a > 0 else 1.0
    T = horizon or tau
    y1 = [x * tau for x in x1]
    big = max(max(map(abs, x0)), max(map(abs, y1)))
    thr = ZERO_RTOL * big
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
    # the decision is the batched exit's sign test (one rule for maps and
    # the analyser); the loop above only picks the certificate's points
    if not nilpotent_sign(np.array([x0]), np.array([y1]))[0]:
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


def nilpotent_path(sub: Reduced, horizon, tol):
    A = sub.A
    if not is_square_zero(A):
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
            return marginal(
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

    m = P0.shape[1]
    S = np.hstack([P0, P1 * tau])
    norms = np.linalg.norm(S, axis=0)
    nz = norms > ZERO_RTOL * norms.max()
    U = S[:, nz] / norms[nz]
    mu, res = nnls(U, -U.sum(axis=1), maxiter=100 * U.shape[1])
    if res > NNLS_RES_RTOL * max(1.0, np.linalg.norm(U.sum(axis=1))):
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
