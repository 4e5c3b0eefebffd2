"""Certified maps: cells of a grid subdivided until each piece is proven
POC YES or NO on the whole piece, or reaches a least size
(:func:`certify_map`), and certified regions: face-adjacent YES boxes.

Each cell of the initial grid (``axes`` maps coordinates to cell edges; the
other coordinates stay at the base pose, as in maps) goes to
:func:`cdpm.certify.box.certify_box`. A cell left undecided is bisected
across its widest side (measured in units of its axis' initial cell
width), down to ``min_fraction`` of the initial cell width; what is still
undecided then stays MARGINAL. A robot outside the certified case (under
load, damped, a pinned cable) is MARGINAL everywhere at once, with the
reason.

Certified YES boxes that share a face (a closed face of positive area;
an axis spanning a full turn [-pi, pi] wraps) form certified regions:
every pose of a region is POC, and the region is connected, so the seed
paper's Lemma 1 applies to it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cdpm.certify.box import BoxCertificate, CertifiedBoxes
from cdpm.certify.subdivide import certify_cells
from cdpm.errors import InputError
from cdpm.verdicts import MARGINAL, NO, YES

__all__ = ["CertifiedMap", "certify_map"]

#: default least box width, as a fraction of its axis' initial cell width
MIN_FRACTION = 1.0 / 16


@dataclass(frozen=True)
class CertifiedMap:
    """Boxes of poses, each with a proven verdict or undecided.

    Attributes:
        coordinates: the mapped coordinates, in the axes' order (d of them).
        base: natural coordinates (nv,) of the coordinates not mapped.
        lower, upper: each box's corners over the mapped coordinates (K, d).
        verdict: YES, NO or MARGINAL per box (K,) int8 (cdpm's codes).
        margin_lower: YES boxes: a lower bound of r_T on the box; else NaN (K,).
        wraps: per mapped coordinate, whether its axis spans a full turn
            [-pi, pi] (its two ends are one face).
        boxes: the boxes over all natural coordinates with their proofs
            (:class:`~cdpm.certify.box.CertifiedBoxes`, K of them).
        cell: the initial cell each box was cut from (K,), cells numbered
            in C order over the axes' cells.
        edges: the axes' cell edges, one array per mapped coordinate.
        min_fraction: the least box width, as a fraction of its axis'
            initial cell width.
    """

    coordinates: tuple[str, ...]
    base: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    verdict: np.ndarray
    margin_lower: np.ndarray
    wraps: tuple[bool, ...]
    boxes: CertifiedBoxes
    cell: np.ndarray
    edges: tuple[np.ndarray, ...]
    min_fraction: float

    @property
    def certificates(self) -> tuple[BoxCertificate, ...]:
        """Each box's :class:`~cdpm.certify.box.BoxCertificate` (built on demand)."""
        return tuple(self.boxes.certificate(k) for k in range(len(self.boxes)))

    @property
    def volumes(self) -> np.ndarray:
        """Each box's volume over the mapped coordinates (K,)."""
        return np.prod(self.upper - self.lower, axis=1)

    def fractions(self) -> dict[str, float]:
        """The fraction of the mapped volume proven YES, proven NO and
        undecided (keys ``yes``, ``no``, ``undecided``)."""
        v = self.volumes
        total = float(v.sum())
        return {
            name: float(v[self.verdict == code].sum() / total) if total > 0 else 0.0
            for name, code in (("yes", YES), ("no", NO), ("undecided", MARGINAL))
        }

    def regions(self) -> np.ndarray:
        """Certified regions: a label per box (K,), 1, 2, ... by decreasing
        volume for YES boxes joined through shared faces, 0 for the others."""
        # scipy: loaded on first use
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        yes = np.flatnonzero(self.verdict == YES)
        labels = np.zeros(self.verdict.shape[0], dtype=np.int64)
        if yes.size == 0:
            return labels
        a, b = _face_pairs(self.lower[yes], self.upper[yes], self.wraps)
        graph = coo_matrix((np.ones(a.size), (a, b)), shape=(yes.size, yes.size))
        _, comp = connected_components(graph, directed=False)
        volume = np.bincount(comp, weights=self.volumes[yes])
        order = np.argsort(-volume, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(1, order.size + 1)
        labels[yes] = rank[comp]
        return labels

    def verify(self, robot: Any) -> bool:
        """Re-check every YES and NO box's certificate from the model (one
        vectorised pass, :meth:`~cdpm.certify.box.CertifiedBoxes.verify`)."""
        decided = np.isin(self.verdict, (YES, NO))
        if not np.array_equal(self.boxes.verdict, self.verdict):
            return False
        return bool(np.all(self.boxes.verify(robot)[decided]))

    def __str__(self) -> str:
        f = self.fractions()
        n_regions = int(self.regions().max(initial=0))
        return (
            f"certified map over {', '.join(self.coordinates)}: {self.verdict.size} boxes; "
            f"proven YES {100 * f['yes']:.1f}%, proven NO {100 * f['no']:.1f}%, "
            f"undecided {100 * f['undecided']:.1f}% of the volume; "
            f"{n_regions} certified region(s)"
        )


def _face_pairs(lo: np.ndarray, hi: np.ndarray, wraps: tuple[bool, ...]):
    """Index pairs (a, b) of boxes sharing a face of positive area: equal
    along one axis (hi of a = lo of b, or across a wrapping axis' ends), and
    overlapping with positive length along every other axis."""
    K, d = lo.shape
    pairs_a, pairs_b = [], []
    for axis in range(d):
        his = {}
        for i, value in enumerate(hi[:, axis]):
            his.setdefault(float(value), []).append(i)
        touching = []
        for j, value in enumerate(lo[:, axis]):
            for i in his.get(float(value), ()):
                touching.append((i, j))
        if wraps[axis]:
            top = np.flatnonzero(np.isclose(hi[:, axis], np.pi, rtol=0, atol=1e-12))
            bottom = np.flatnonzero(np.isclose(lo[:, axis], -np.pi, rtol=0, atol=1e-12))
            touching += [(i, j) for i in top for j in bottom]
        if not touching:
            continue
        i, j = np.array(touching).T
        others = [k for k in range(d) if k != axis]
        overlap = np.ones(i.size, dtype=bool)
        for k in others:
            overlap &= np.minimum(hi[i, k], hi[j, k]) > np.maximum(lo[i, k], lo[j, k])
        pairs_a.append(i[overlap])
        pairs_b.append(j[overlap])
    if not pairs_a:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    return np.concatenate(pairs_a), np.concatenate(pairs_b)


def _axes(robot: Any, axes: Mapping[str, Any]) -> tuple[list[int], list[np.ndarray]]:
    names = list(robot.coordinate_names)
    if not isinstance(axes, Mapping) or not axes:
        raise InputError(
            "axes must map coordinate names to increasing cell edges, e.g. "
            "{'q1': np.linspace(-np.pi, np.pi, 62)}"
        )
    index, edges = [], []
    for name, values in axes.items():
        if name not in names:
            raise InputError(f"unknown coordinate {name!r}; the robot has {', '.join(names)}")
        try:
            e = np.array(values, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"the edges of {name} must be numbers") from None
        if e.size < 2 or not np.all(np.isfinite(e)) or not np.all(np.diff(e) > 0):
            raise InputError(f"the edges of {name} must be at least two finite, increasing numbers")
        index.append(names.index(name))
        edges.append(e)
    if len(set(index)) != len(index):
        raise InputError("a coordinate is given twice in axes")
    return index, edges


def certify_map(
    robot: Any,
    axes: Mapping[str, Any],
    base: Any = None,
    *,
    min_fraction: float = MIN_FRACTION,
    horizon: Any = None,
    tension_budget: Any = None,
) -> CertifiedMap:
    """Certify every cell of a grid, subdividing undecided ones (module
    docstring).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` or a spec path.
        axes: coordinate name -> increasing cell edges [rad or m] (n + 1
            edges make n cells), within the joint limits.
        base: the pose of the coordinates not mapped (a pose name or
            natural coordinates; default the spec's first named pose).
        min_fraction: least box width, as a fraction of its axis' initial
            cell width (default 1/16: four bisections per axis).
        horizon, tension_budget: of the reach-margin bound, as
            :func:`~cdpm.certify.box.certify_box`.

    Returns:
        :class:`CertifiedMap`.

    Raises:
        InputError: bad axes or base, cells beyond the joint limits, or a
            joint type certified boxes do not support.
    """
    # loaded on first use
    from cdpm.dynamics.reach import reach_settings
    from cdpm.model.robot import load_robot

    if not hasattr(robot, "spec"):
        robot = load_robot(robot)
    index, edges = _axes(robot, axes)
    if not (isinstance(min_fraction, (int, float)) and 0 < min_fraction <= 1):
        raise InputError("min_fraction must be a number in (0, 1]")
    if base is None:  # the spec's first named pose, else the neutral configuration
        q = next(iter(robot.poses.values())) if robot.poses else robot.neutral()
    else:
        q = robot.as_q(base)
    natural = np.asarray(robot.to_natural(q), dtype=float)
    widths = np.array([float(np.min(np.diff(e))) for e in edges])
    wraps = tuple(
        bool(np.isclose(e[0], -np.pi, atol=1e-12) and np.isclose(e[-1], np.pi, atol=1e-12))
        for e in edges
    )
    grids = np.meshgrid(*[np.arange(e.size - 1) for e in edges], indexing="ij")
    cells = np.stack([g.reshape(-1) for g in grids], axis=1)
    queue_lo = np.stack([e[cells[:, i]] for i, e in enumerate(edges)], axis=1)
    queue_hi = np.stack([e[cells[:, i] + 1] for i, e in enumerate(edges)], axis=1)
    # the reach settings once for every box (the default horizon may need
    # a linearisation of the robot)
    reach = reach_settings(robot, horizon, tension_budget)
    boxes, cell = certify_cells(
        robot, natural, index, queue_lo, queue_hi, widths, min_fraction, reach
    )
    names = tuple(robot.coordinate_names[i] for i in index)
    return CertifiedMap(
        names,
        natural,
        boxes.lower[:, index],
        boxes.upper[:, index],
        boxes.verdict.copy(),
        boxes.margin_lower.copy(),
        wraps,
        boxes,
        cell,
        tuple(edges),
        float(min_fraction),
    )
