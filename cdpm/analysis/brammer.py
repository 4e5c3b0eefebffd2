"""Positive (state) controllability: Brammer's theorem with a mixed cone.

Brammer (1972), "Controllability in linear autonomous systems with positive
controllers", SIAM J. Control 10(2):339-353; the seed paper's Proposition 1.
With input cone U = {u : u_j >= 0 for sign-constrained j, u_j free otherwise},
(A, B) is positive controllable iff

1. rank [B AB ... A^{n-1}B] = n (Kalman), and
2. no real eigenvector v of A^T has v^T B u <= 0 for all u in U, i.e.
   v^T b_j <= 0 for constrained j and v^T b_j = 0 for free j.

For a repeated real eigenvalue the eigenvectors form a subspace E; condition
2 is then a cone question on E (does some nonzero v in E separate?), decided
with :func:`cdpm.analysis.span.span_core` on the vectors E^T b_j, not by
testing individual numerical eigenvectors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpm.analysis._common import (
    Verdict,
    as_system,
    cluster,
    complement,
    fmt_array,
    null_space,
    scaled_system,
)
from cdpm.analysis.rank import reachable_basis
from cdpm.analysis.span import span_core
from cdpm.numerics import (
    EIG_ATOL,
    NULL_SPACE_RTOL,
    REAL_EIG_RTOL,
    RECHECK_TOL,
    RECHECK_WITNESS_ROUNDOFF_RTOL,
    SPAN_TOL,
    ZERO_ATOL,
)
from cdpm.printing import html_table, to_plain

__all__ = ["PositiveControllabilityResult", "positive_controllability"]

# EIG_ATOL: eigenvalues of the normalised A (|A| = 1) closer than it are one
# cluster, and imaginary parts below it count as real (a Jordan block splits
# by ~sqrt(eps)); ZERO_ATOL: an eigenvector computed to ~1e-9 sees an
# orthogonal unit input column as a product of that size


@dataclass(frozen=True)
class PositiveControllabilityResult:
    """Brammer's test of positive controllability.

    Attributes:
        verdict: YES or NO.
        kalman_rank: rank of the Kalman matrix; n: number of states.
        method: ``"kalman-rank"`` (rank < n decided NO) or ``"brammer"``.
        witness: when NO and a real witness exists, a unit real eigenvector v
            of A^T with v^T b_j <= 0 (constrained j) and v^T b_j = 0 (free j)
            (paper Remark 11); else None.
        witness_eigenvalue: its eigenvalue (A^T v = lambda v).
        witness_products: ``v^T B``, shape (m,) (paper eq 30).
        checked_eigenvalues: the real eigenvalues (clusters) examined, with
            the dimension of their eigenspaces.
        reason: one readable sentence.
    """

    verdict: Verdict
    kalman_rank: int
    n: int
    method: str
    reason: str
    witness: np.ndarray | None = None
    witness_eigenvalue: float | None = None
    witness_products: np.ndarray | None = None
    checked_eigenvalues: tuple = ()

    def __bool__(self) -> bool:
        return self.verdict is Verdict.YES

    def verify(self, A, B, sign_constrained=None, tol: float = RECHECK_TOL) -> bool:
        """Re-check a NO witness directly (eigen-residual and signs); for YES
        re-check the Kalman rank only (condition 2 is the decision itself)."""
        A, B, mask = as_system(A, B, sign_constrained=sign_constrained)
        if self.verdict is Verdict.YES:
            return reachable_basis(A, B).shape[1] == A.shape[0]
        if self.witness is None:
            return reachable_basis(A, B).shape[1] < A.shape[0]
        v = np.asarray(self.witness, dtype=float)
        lam = float(self.witness_eigenvalue)
        scale = np.abs(v) @ np.abs(A) + abs(lam) * np.abs(v) + 1e-300
        allow = tol * np.linalg.norm(scale) + RECHECK_WITNESS_ROUNDOFF_RTOL * scale
        if np.any(np.abs(v @ A - lam * v) > allow):
            return False
        prod = v @ B
        ref = np.linalg.norm(v) * np.linalg.norm(B, axis=0) + 1e-300
        ok_c = np.all(prod[mask] <= tol * ref[mask])
        ok_f = np.all(np.abs(prod[~mask]) <= tol * ref[~mask])
        return bool(ok_c and ok_f and np.linalg.norm(v) > 0)

    def as_dict(self) -> dict:
        return to_plain(
            {
                "verdict": self.verdict,
                "kalman_rank": self.kalman_rank,
                "n": self.n,
                "method": self.method,
                "reason": self.reason,
                "witness": self.witness,
                "witness_eigenvalue": self.witness_eigenvalue,
                "witness_products": self.witness_products,
                "checked_eigenvalues": [list(c) for c in self.checked_eigenvalues],
            }
        )

    def __str__(self) -> str:
        lines = [
            f"positive controllability: {self.verdict} ({self.method}; "
            f"Kalman rank {self.kalman_rank}/{self.n})",
            f"  {self.reason}",
        ]
        if self.witness is not None:
            lines.append(
                f"  witness v = {fmt_array(self.witness)} (A^T v = {self.witness_eigenvalue:.4g} v)"
            )
            lines.append(f"  v^T B = {fmt_array(self.witness_products)}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        rows = [
            ("method", self.method),
            ("Kalman rank", f"{self.kalman_rank}/{self.n}"),
            ("reason", self.reason),
        ]
        if self.witness is not None:
            rows += [
                ("witness v", fmt_array(self.witness)),
                ("v^T B", fmt_array(self.witness_products)),
            ]
        return html_table(f"Positive controllability: {self.verdict}", rows)


def positive_controllability(A, B, sign_constrained=None) -> PositiveControllabilityResult:
    """Brammer's test (paper Prop. 1) with sign-constrained and free inputs.

    Args:
        A: state matrix, shape (n, n).
        B: input matrix, shape (n, m).
        sign_constrained: bool mask (m,); True (default) = input u_j >= 0,
            False = free in sign.

    Returns:
        :class:`PositiveControllabilityResult`; for NO the witness eigenvector.
    """
    A, B, mask = as_system(A, B, sign_constrained=sign_constrained)
    return _positive_controllability(A, B, mask)


def _positive_controllability(A, B, mask, tol: float = SPAN_TOL):
    n = A.shape[0]
    Q = reachable_basis(A, B)
    rank = Q.shape[1]
    if rank < n:
        v, lam = _uncontrollable_real_eigenvector(A, Q)
        reason = f"the Kalman rank is {rank} < n = {n}"
        if v is None:
            return PositiveControllabilityResult(Verdict.NO, rank, n, "kalman-rank", reason)
        return PositiveControllabilityResult(
            Verdict.NO, rank, n, "kalman-rank", reason, v, lam, v @ B
        )
    found = left_eigen_separator(A, B, mask, tol)
    checked = found[-1]
    if found[0] is None:
        return PositiveControllabilityResult(
            Verdict.YES,
            rank,
            n,
            "brammer",
            "Kalman rank n and no real eigenvector of A^T separates the input cone",
            checked_eigenvalues=checked,
        )
    v, lam, _ = found
    return PositiveControllabilityResult(
        Verdict.NO,
        rank,
        n,
        "brammer",
        f"a real eigenvector v of A^T (eigenvalue {lam:.4g}) has v^T B u <= 0 on the input cone",
        v,
        lam,
        v @ B,
        checked,
    )


def left_eigen_separator(A: np.ndarray, B: np.ndarray, mask: np.ndarray, tol: float = SPAN_TOL):
    """Search the real left eigenspaces of A for v != 0 with v^T b_j <= 0
    (constrained j) and v^T b_j = 0 (free j).

    Returns:
        (v, lambda, checked): v a unit vector in original coordinates (None
        when no eigenspace separates), its eigenvalue and the list of
        (eigenvalue, eigenspace dimension) examined.
    """
    As, Bs, _, d, _, _, rho = scaled_system(A, B, None)
    lam = np.linalg.eigvals(As)
    real = lam[np.abs(lam.imag) <= EIG_ATOL].real
    checked = []
    for group in cluster(real, EIG_ATOL):
        mu = float(np.mean(real[group]))
        E = null_space(As.T - mu * np.eye(As.shape[0]), rtol=max(10 * EIG_ATOL, NULL_SPACE_RTOL))
        checked.append((mu * rho, E.shape[1]))
        if E.shape[1] == 0:
            continue
        # Bs has unit columns and E orthonormal columns: the products are
        # measured against 1, so round-off (1e-16) is zero, not a direction
        Z = E.T @ Bs
        Nf = null_space(Z[:, ~mask].T, atol=ZERO_ATOL) if (~mask).any() else np.eye(E.shape[1])
        if Nf.shape[1] == 0:
            continue
        Y = Nf.T @ Z[:, mask]
        Y[:, np.linalg.norm(Y, axis=0) <= ZERO_ATOL] = 0.0
        if not Y.any():
            c = np.eye(Nf.shape[1])[:, 0]  # v^T b_j = 0 for every input
        else:
            yes, _, _, _, _, c = span_core(Y, tol)
            if yes:
                continue
        v = (E @ (Nf @ c)) / d
        v = v / np.linalg.norm(v)
        return v, mu * rho, checked
    return None, None, checked


def _uncontrollable_real_eigenvector(A: np.ndarray, Q: np.ndarray):
    """A real left eigenvector of A orthogonal to the reachable subspace
    (PBH), if the uncontrollable part has a real eigenvalue; v^T B = 0."""
    P = complement(Q, A.shape[0])
    M = P.T @ A.T @ P
    w, V = np.linalg.eig(M)
    scale = max(np.abs(w).max(), 1e-300)
    real = np.flatnonzero(np.abs(w.imag) <= REAL_EIG_RTOL * scale)
    if real.size == 0:
        return None, None
    i = real[0]
    v = P @ V[:, i].real
    return v / np.linalg.norm(v), float(w[i].real)
