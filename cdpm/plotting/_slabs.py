"""Slabs of a sampled map of more than two axes: the samples whose third
coordinate lies in one interval, drawn in a panel of their own (a map plot
of all of them at once would draw every value of the third coordinate over
the others)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["MIN_SLAB_SAMPLES", "SampleSlab", "sample_slabs", "slabs_text"]

#: fewest samples a slab is cut for on average: a panel of fewer shows
#: little of the map's shape
MIN_SLAB_SAMPLES = 300


@dataclass(frozen=True)
class SampleSlab:
    """The samples one panel draws.

    Attributes:
        mask: which samples (n,) bool.
        axis: the coordinate cut into slabs, or None (every sample).
        low, high: the slab's interval of ``axis`` [its unit]; the last
            slab includes ``high``.
        last: this is the last slab (closed at ``high``).
        unit: the unit of ``axis`` (``"rad"``, ``"m"`` or ``""``).
        decimals: decimals the title gives the interval's ends (two
            significant digits of a slab's width).
    """

    mask: np.ndarray
    axis: str | None = None
    low: float = float("nan")
    high: float = float("nan")
    last: bool = True
    unit: str = ""
    decimals: int = 3

    @classmethod
    def everything(cls, ds) -> SampleSlab:
        """Every sample of the map ``ds``."""
        return cls(np.ones(ds.sizes["sample"], dtype=bool))

    def near(self, path) -> np.ndarray | None:
        """Which poses of ``path`` lie in the slab (k,) bool, drawn solid;
        None when there is no slab or the path does not give its axis."""
        if self.axis is None or self.axis not in path:
            return None
        v = np.asarray(path[self.axis], dtype=float)
        return (v >= self.low) & ((v <= self.high) if self.last else (v < self.high))

    def title(self) -> str:
        """The panel title's line on the slab (``""`` for every sample)."""
        if self.axis is None:
            return ""
        unit = f" {self.unit}" if self.unit else ""
        close = "]" if self.last else ")"
        low, high = (round(v, self.decimals) + 0.0 for v in (self.low, self.high))
        d = self.decimals
        return (
            f"\n({self.axis} in [{low:.{d}f}, {high:.{d}f}{close}{unit}: "
            f"{int(self.mask.sum())} samples)"
        )


def sample_slabs(ds, axis: str, max_slabs: int) -> list[SampleSlab]:
    """The samples of ``ds`` cut along ``axis`` into slabs of equal width
    over its sampled range: at most ``max_slabs``, and about
    MIN_SLAB_SAMPLES samples each at least (one slab for fewer)."""
    values = np.asarray(ds[axis].values, dtype=float).reshape(-1)
    unit = ds[axis].attrs.get("units", "")
    finite = values[np.isfinite(values)]
    low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    n = min(int(max_slabs), max(1, values.size // MIN_SLAB_SAMPLES))
    if not high > low:
        n = 1
    edges = np.linspace(low, high, n + 1)
    decimals = max(0, 1 - math.floor(math.log10((high - low) / n))) if high > low else 3
    slabs = []
    for k in range(n):
        last = k == n - 1
        upper = values <= edges[k + 1] if last else values < edges[k + 1]
        slabs.append(
            SampleSlab(
                (values >= edges[k]) & upper, axis, edges[k], edges[k + 1], last, unit, decimals
            )
        )
    return slabs


def slabs_text(axes: Sequence[str], n: int) -> str:
    """The figure title's line on what the slabs show: ``axes`` are the
    sampled coordinates from the third on, the first cut into ``n`` slabs."""
    text = (
        f"{axes[0]} cut into {n} slabs of equal width, one a panel"
        if n > 1
        else f"{axes[0]}: every sample in one panel (too few samples to cut)"
    )
    if len(axes) > 1:
        text += f"; {', '.join(axes[1:])} projected (every value drawn)"
    return text
