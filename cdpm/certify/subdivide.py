"""Cells of a grid certified box by box, undecided boxes bisected level by
level (:func:`certify_cells`): the engine of
:func:`cdpm.certify.map.certify_map`.

Each pass certifies every pending box at once
(:func:`cdpm.certify.box.certify_boxes`, in batches of :data:`BATCH`); a
box left undecided is bisected across its widest side (measured in units
of its axis' initial cell width) while that side is wider than
``min_fraction``; what is still undecided then stays MARGINAL. A robot
outside the certified case is MARGINAL everywhere at once, with the reason.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cdpm.certify.box import CertifiedBoxes, certified_case, certify_boxes, concatenate_boxes
from cdpm.verdicts import MARGINAL

__all__ = ["BATCH", "certify_cells"]

#: boxes certified in one vectorised pass (bounds the memory of a pass)
BATCH = 4096


def certify_cells(
    robot: Any,
    natural: np.ndarray,
    index: list[int],
    lower: np.ndarray,
    upper: np.ndarray,
    widths: np.ndarray,
    min_fraction: float,
    reach: Any,
) -> tuple[CertifiedBoxes, np.ndarray]:
    """Certify cells, bisecting undecided boxes level by level.

    Args:
        robot: the robot.
        natural: the base pose, natural coordinates (nv,).
        index: the mapped coordinates' positions in ``natural`` (d,).
        lower, upper: the cells over the mapped coordinates (N, d).
        widths: each axis' initial cell width (d,), the unit of a box's
            relative width.
        min_fraction: least relative width of a box that is still bisected
            further.
        reach: the reach settings of the margin bounds.

    Returns:
        (boxes, cell): the final boxes over all natural coordinates, and for
        each the row of ``lower`` it was cut from (K,).
    """
    structural = certified_case(robot)[1]
    pend_lo = np.asarray(lower, dtype=float)
    pend_hi = np.asarray(upper, dtype=float)
    pend_cell = np.arange(pend_lo.shape[0])
    parts, cells = [], []
    while pend_lo.shape[0]:
        full_lo = np.tile(natural, (pend_lo.shape[0], 1))
        full_hi = full_lo.copy()
        full_lo[:, index] = pend_lo
        full_hi[:, index] = pend_hi
        results = [
            certify_boxes(robot, full_lo[s : s + BATCH], full_hi[s : s + BATCH], horizon=reach)
            for s in range(0, full_lo.shape[0], BATCH)
        ]
        got = concatenate_boxes(results)
        relative = (pend_hi - pend_lo) / widths
        split = (
            (got.verdict == MARGINAL)
            & (not structural)
            & (relative.max(axis=1) > min_fraction * (1 + 1e-9))
        )
        parts.append(got.select(~split))
        cells.append(pend_cell[~split])
        lo, hi, c = pend_lo[split], pend_hi[split], pend_cell[split]
        k = np.argmax(relative[split], axis=1)
        rows = np.arange(k.size)
        mid = 0.5 * (lo[rows, k] + hi[rows, k])
        first_hi, second_lo = hi.copy(), lo.copy()
        first_hi[rows, k] = mid
        second_lo[rows, k] = mid
        pend_lo = np.concatenate([lo, second_lo])
        pend_hi = np.concatenate([first_hi, hi])
        pend_cell = np.concatenate([c, c])
    boxes = concatenate_boxes(parts)
    cell = np.concatenate(cells) if cells else np.zeros(0, dtype=np.int64)
    order = np.argsort(cell, kind="stable")
    return boxes.select(order), cell[order]
