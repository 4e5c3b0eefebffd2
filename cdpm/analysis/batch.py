"""Batched analysis: the decisions of many systems at once.

:func:`analyse_systems` decides, for N linear systems ``(A, B, C, mask)``
with a pose axis first, positive output controllability (with its margin),
output controllability and positive (Brammer) controllability; a map runs
it on every chunk and :func:`cdpm.analyze_pose` on a batch of one. It
first runs the vectorised exits of :mod:`cdpm.analysis.exits`, each deciding the systems it can
beyond doubt, and hands every system they leave open to the per-system
analyser (:func:`cdpm.positive_output_controllability` and friends), so
both entry points decide with one procedure and one set of thresholds
(:mod:`cdpm.numerics`).

Exits:

- ``nilpotent``: the seed paper's case, ``A = [[0, I], [0, 0]]``,
  ``B = [0; Bv]``, ``C = [Cq, 0]`` with every input sign-constrained. Then
  ``CB = 0`` and ``C e^{At} B = t Cq Bv``, so POC is a sign test (p = 1)
  or an angular-gap test (p = 2) on the columns of ``Cq Bv`` (docs/analysis.md
  section 3), output controllability is rank ``Cq Bv = p`` and Brammer's
  test asks whether the columns of Bv positively span R^nv.
- ``mixed-cone``: the free (taut) inputs alone reach every output
  direction (batched Krylov rank), so POC holds.
- ``rank``: rank [CB, CAB, ...] = p beyond doubt; and the free inputs alone
  make (A, B) controllable, so Brammer's obstruction cannot exist.

Systems within a small band of an exit's threshold are left open: the
per-system analyser computes the same quantities in another order, and a
band of a few round-off units keeps the two from deciding differently.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpm.analysis.brammer import _positive_controllability
from cdpm.analysis.exits import (
    free_controllable,
    nilpotent_mechanical,
    nilpotent_poc,
    output_controllable,
    output_rank_full,
    span_codes,
    times,
)
from cdpm.analysis.poc import _poc, poc_margins
from cdpm.analysis.span import span_result
from cdpm.errors import CdpmError
from cdpm.numerics import BRAMMER_DEFER, RANK_RATIO, SPAN_TOL, WRENCH_DEFER_BAND
from cdpm.verdicts import NO, NOT_ANALYSED, YES, verdict_code

__all__ = [
    "SystemVerdicts",
    "analyse_systems",
    "positively_spanning",
]


@dataclass(frozen=True)
class SystemVerdicts:
    """Verdict codes (:mod:`cdpm.verdicts`) of N systems.

    Attributes:
        poc: positive output controllability, int8 (N,).
        poc_margin: the POC margin (``POCResult.margin``), (N,); NaN when
            not asked for or not analysed.
        output_controllable: int8 (N,).
        positive_controllable: Brammer's test, int8 (N,).
        failed: the per-system analyser raised on these systems, bool (N,).
    """

    poc: np.ndarray
    poc_margin: np.ndarray
    output_controllable: np.ndarray
    positive_controllable: np.ndarray
    failed: np.ndarray


def positively_spanning(vectors: np.ndarray, tol: float = SPAN_TOL) -> np.ndarray:
    """Wrench-closure-like test of many vector sets: do the columns of each
    (d, m) matrix of ``vectors`` (k, d, m) positively span R^d?

    d <= 2: the angular and sign exits (:func:`~cdpm.analysis.exits.span_codes`);
    d >= 3: deep certificates, a strictly positive null vector or a strict
    separator of the unit columns with every entry at least ``RANK_RATIO``
    times its norm (:mod:`cdpm.analysis._span_batch`, compiled). The sets
    they leave open (within the defer band of an exit, near the boundary,
    nearly rank deficient, or whose cone holds a line) get the verdict of
    the analyser's :func:`~cdpm.analysis.positively_spans`.

    Returns:
        int8 codes (k,): YES, NO, or MARGINAL where the analyser's
        certificate does not re-check.
    """

    if vectors.shape[1] <= 2:
        band = (tol - WRENCH_DEFER_BAND, tol + WRENCH_DEFER_BAND)
        codes, todo = span_codes(np.moveaxis(vectors, 0, -1), band, tol)
    else:
        from cdpm.analysis._span_batch import span_certificates  # numba: loaded on use

        codes = span_certificates(vectors, RANK_RATIO, 1.0 / RANK_RATIO, tol)
        todo = codes < 0
    for i in np.flatnonzero(todo):
        codes[i] = verdict_code(span_result(vectors[i], tol).verdict)
    return codes


def analyse_systems(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    mask: np.ndarray,
    *,
    margin: bool = True,
    tol: float = SPAN_TOL,
) -> SystemVerdicts:
    """POC (and its margin), output controllability and Brammer's test of
    N systems: the exits (module docstring), then the per-system analyser
    for the systems they leave open.

    Args:
        A: (N, n, n); B: (N, n, m), the input cone (every sign-constrained
            input u >= 0); C: (N, p, n); mask: (N, m) bool, True for
            sign-constrained inputs. Finite, consistent shapes (unchecked).
        margin: compute ``poc_margin`` (else NaN).
        tol: angle-like tolerance of the span decisions.

    Returns:
        :class:`SystemVerdicts`.
    """
    k, n = A.shape[0], A.shape[1]
    poc = np.full(k, NOT_ANALYSED, dtype=np.int8)
    oc = np.full(k, NOT_ANALYSED, dtype=np.int8)
    pc = np.full(k, NOT_ANALYSED, dtype=np.int8)
    mg = np.full(k, np.nan)
    failed = np.zeros(k, dtype=bool)
    open_poc = np.zeros(k, dtype=bool)
    if C.shape[1] == 0:  # no output: POC and output controllability hold trivially
        poc[:], oc[:], mg[:] = YES, YES, np.inf
        pc[:] = free_controllable(A, B, mask)
        _per_system(A, B, C, mask, open_poc, poc, mg, oc, pc, failed, tol)
        return SystemVerdicts(poc, mg if margin else np.full(k, np.nan), oc, pc, failed)
    nil = nilpotent_mechanical(A, B, C, mask) if k else np.zeros(0, dtype=bool)
    if nil.any():
        idx = slice(None) if nil.all() else np.flatnonzero(nil)  # a view when all
        nv = n // 2
        Cq = np.ascontiguousarray(np.moveaxis(C[idx, :, :nv], 0, -1))  # (p, nv, k)
        Bv = np.ascontiguousarray(np.moveaxis(B[idx, nv:], 0, -1))  # (nv, m, k)
        CAB = times(Cq, Bv)
        codes, values, todo = nilpotent_poc(CAB, tol)
        oc_codes, todo_oc = output_rank_full(CAB, Cq, Bv)
        # Brammer: the left eigenvectors of A are (0, w), so the obstruction
        # is a w with w.Bv <= 0 for every column
        pc_codes, todo_pc = span_codes(Bv, BRAMMER_DEFER, tol)
        todo |= todo_oc | todo_pc
        keep = ~todo
        at = np.flatnonzero(nil)
        poc[at[keep]], mg[at[keep]] = codes[keep], values[keep]
        oc[at[keep]], pc[at[keep]] = oc_codes[keep], pc_codes[keep]
        open_poc[at[todo]] = True
    gen = np.flatnonzero(~nil)
    if gen.size:
        Ag, Bg, Cg, mk = A[gen], B[gen], C[gen], mask[gen]
        pc[gen] = free_controllable(Ag, Bg, mk)
        mixed = output_controllable(Ag, Bg * ~mk[:, None, :], Cg) == YES
        poc[gen[mixed]] = YES
        oc_g = np.full(gen.size, YES, dtype=np.int8)
        oc_g[~mixed] = output_controllable(Ag[~mixed], Bg[~mixed], Cg[~mixed])
        oc[gen] = oc_g
        if margin and C.shape[1] and mixed.any():
            mg[gen[mixed]] = poc_margins(Ag[mixed], Bg[mixed], Cg[mixed], mk[mixed], True)
        open_poc[gen[~mixed]] = True
    _per_system(A, B, C, mask, open_poc, poc, mg, oc, pc, failed, tol)
    if not margin:
        mg[:] = np.nan
    return SystemVerdicts(poc, mg, oc, pc, failed)


def _per_system(A, B, C, mask, open_poc, poc, mg, oc, pc, failed, tol) -> None:
    """The per-system analyser for what the exits left open (in place)."""

    for i in np.flatnonzero(open_poc | (pc == NOT_ANALYSED)):
        try:
            if open_poc[i]:
                res = _poc(A[i], B[i], C[i], mask[i], tol=tol)
                poc[i] = verdict_code(res.verdict)
                mg[i] = float(res.margin)
                if oc[i] == NOT_ANALYSED:
                    oc[i] = YES if res.output_controllable else NO
            if pc[i] == NOT_ANALYSED:
                pc[i] = verdict_code(_positive_controllability(A[i], B[i], mask[i], tol).verdict)
        except (CdpmError, np.linalg.LinAlgError):
            failed[i] = True
            poc[i] = pc[i] = oc[i] = NOT_ANALYSED
            mg[i] = np.nan
