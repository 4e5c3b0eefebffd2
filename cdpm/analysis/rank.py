"""Kalman controllability and output controllability ranks.

Ranks are computed on a balanced, column/row-normalised copy of the system
from an orthonormal Krylov basis (block Arnoldi), never from raw powers
A^k B, so badly scaled systems (entries 1e-3 next to 1e3) keep their rank.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpm.analysis._common import (
    as_system,
    krylov_basis,
    numerical_rank,
    scaled_system,
)
from cdpm.numerics import RANK_RTOL
from cdpm.printing import html_table, to_plain

__all__ = [
    "ControllabilityResult",
    "OutputControllabilityResult",
    "controllability",
    "output_controllability",
]


@dataclass(frozen=True)
class ControllabilityResult:
    """Kalman test ``rank [B AB ... A^{n-1}B] = n``.

    Attributes:
        rank: dimension of the reachable subspace.
        n: number of states.
        controllable: ``rank == n``.
        reachable_basis: orthonormal basis of the reachable subspace, (n, rank).
    """

    rank: int
    n: int
    controllable: bool
    reachable_basis: np.ndarray

    def __bool__(self) -> bool:
        return self.controllable

    def as_dict(self) -> dict:
        return to_plain({"rank": self.rank, "n": self.n, "controllable": self.controllable})

    def __str__(self) -> str:
        word = "controllable" if self.controllable else "not controllable"
        return f"Kalman rank {self.rank} of n={self.n}: {word}"

    def _repr_html_(self) -> str:
        return html_table(
            "Controllability",
            [("rank", f"{self.rank} / {self.n}"), ("controllable", str(self.controllable))],
        )


@dataclass(frozen=True)
class OutputControllabilityResult:
    """Output controllability ``rank [CB CAB ... CA^{n-1}B] = p``.

    Attributes:
        rank: dimension of the output reachable subspace.
        p: number of outputs.
        controllable: ``rank == p``.
        output_basis: orthonormal basis of the output reachable subspace, (p, rank).
    """

    rank: int
    p: int
    controllable: bool
    output_basis: np.ndarray

    def __bool__(self) -> bool:
        return self.controllable

    def as_dict(self) -> dict:
        return to_plain({"rank": self.rank, "p": self.p, "controllable": self.controllable})

    def __str__(self) -> str:
        word = "output controllable" if self.controllable else "not output controllable"
        return f"output rank {self.rank} of p={self.p}: {word}"

    def _repr_html_(self) -> str:
        return html_table(
            "Output controllability",
            [("rank", f"{self.rank} / {self.p}"), ("controllable", str(self.controllable))],
        )


def reachable_basis(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Orthonormal basis (original coordinates) of span[B, AB, ...]."""
    As, Bs, _, d, _, _, _ = scaled_system(A, B, None)
    Q = krylov_basis(As, Bs)
    if Q.shape[1] == 0:
        return Q
    X = Q * d[:, None]
    U, s, _ = np.linalg.svd(X / np.linalg.norm(X, axis=0), full_matrices=False)
    return U[:, : numerical_rank(s, RANK_RTOL)]


def output_reachable_basis(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Orthonormal basis (p, r) of C times the reachable subspace of (A, B)."""
    p = C.shape[0]
    if B.shape[1] == 0 or p == 0:
        return np.zeros((p, 0))
    As, Bs, Cs, _, _, row, _ = scaled_system(A, B, C)
    Q = krylov_basis(As, Bs)
    Y = Cs @ Q
    if Y.size == 0:
        return np.zeros((p, 0))
    U, s, _ = np.linalg.svd(Y, full_matrices=True)
    ref = float(np.linalg.norm(Cs, 2))
    r = int(np.count_nonzero(s > RANK_RTOL * max(ref, 1e-300)))
    # undo the output row scaling: range(Cs Q) = diag(row) range(C Q)
    Y0 = U[:, :r] / row[:, None]
    if r == 0:
        return np.zeros((p, 0))
    U0, _, _ = np.linalg.svd(Y0, full_matrices=False)
    return U0[:, :r]


def controllability(A, B) -> ControllabilityResult:
    """Kalman controllability of (A, B).

    Args:
        A: state matrix, shape (n, n).
        B: input matrix, shape (n, m).
    """
    A, B, _ = as_system(A, B)
    Q = reachable_basis(A, B)
    n = A.shape[0]
    return ControllabilityResult(Q.shape[1], n, Q.shape[1] == n, Q)


def output_controllability(A, B, C) -> OutputControllabilityResult:
    """Output controllability of (A, B, C): ``rank C [B AB ...] = p``.

    Necessary for positive output controllability.

    Args:
        A: (n, n); B: (n, m); C: output matrix, shape (p, n).
    """
    A, B, C, _ = as_system(A, B, C)
    Y = output_reachable_basis(A, B, C)
    p = C.shape[0]
    return OutputControllabilityResult(Y.shape[1], p, Y.shape[1] == p, Y)
