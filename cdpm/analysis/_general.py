"""The Brammer-based and the general POC paths.

- ``full-rank-brammer``: with the reduced C square and invertible, POC is
  positive controllability of (A, B): Brammer's test decides, sampled
  pairs certify a YES.
- ``general``: a sampled exchange search for a positive-span certificate,
  else a separating v with a proof (Taylor / sampled / tail bounds of
  :func:`cdpm.analysis._modes.prove_nonpositive`), else MARGINAL.
"""

from __future__ import annotations

import numpy as np

from cdpm.analysis import _modes
from cdpm.analysis._common import Verdict, scaled_system
from cdpm.analysis._reduced import Reduced, marginal, output_rank_defect
from cdpm.analysis._sampled import ModalScaled, Scaled, sample_search, sampled_yes, separator
from cdpm.analysis.brammer import left_eigen_separator
from cdpm.analysis.rank import reachable_basis
from cdpm.numerics import INVERTIBLE_COND_MAX
from cdpm.printing import to_plain

_REASON_GENERAL_YES = "finitely many sampled output vectors positively span the output space"


_REASON_ILL_CONDITIONED = (
    "sampled output vectors positively span the output space in scaled coordinates, but "
    "the certificate does not survive its re-check in the output's own units (the vectors "
    "are nearly parallel there, e.g. late samples of a fast growing mode)"
)


def _checked_yes(sub: Reduced, cert, T):
    """YES with a sampled certificate only when the certificate passes its
    own re-check on the full system (as a user's ``verify`` would); else
    MARGINAL: a YES must come with a certificate anyone can re-check."""
    if cert.verify(sub.A, sub.B, sub.C):
        return Verdict.YES, "general", _REASON_GENERAL_YES, cert, T
    return marginal("general", _REASON_ILL_CONDITIONED, sub, T)


def brammer_path(sub: Reduced, horizon, tol):
    A, Bp, Cr = sub.A, sub.Bp, sub.Cr
    n = A.shape[0]
    if Cr.shape[0] != n or np.linalg.cond(Cr) > INVERTIBLE_COND_MAX:
        return None
    if reachable_basis(A, Bp).shape[1] < n:
        return None  # let the general path give the output-rank certificate
    mask = np.ones(Bp.shape[1], dtype=bool)
    w, lam, _ = left_eigen_separator(A, Bp, mask, tol)
    As = scaled_system(A, Bp, Cr)
    T = horizon or _modes.default_horizon(np.linalg.eigvals(As[0])) / As[6]
    if w is None:
        return sampled_yes(
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


def general_path(sub: Reduced, horizon, tol):
    # output rank of the reduced system (implied by the full system's rank,
    # re-checked here: cheap [CB, CAB] test first)
    v = None
    if sub.N is not None or sub.cons.size < sub.B.shape[1]:
        # (with every input constrained and nothing projected out this is
        # the full system's check, already passed)
        v = output_rank_defect(sub.A, sub.Bp, sub.Cr, np.linalg.norm(sub.Cr, axis=1))
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
        found = sample_search(sub, T, ModalScaled(sub.modal_ev))
        if found[0] == "yes":
            return _checked_yes(sub, found[1], T)
    sc = Scaled(sub)
    Ts = T0 * sc.rho if T0 else _modes.default_horizon(sc.ev.eigvals)
    T = Ts / sc.rho
    extra = None
    last = "no separator found"
    for _ in range(6):
        found = sample_search(sub, T, sc, extra)
        if found[0] == "yes":
            return _checked_yes(sub, found[1], T)
        _, v, S, ts, m = found
        sep = separator(S, v)
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
    return marginal(
        "general",
        f"neither certificate clears the tolerance ({last})",
        sub,
        T,
        {"reason": last, "candidate_separator": (sub.lift(sep * sc.row)).tolist()},
    )
