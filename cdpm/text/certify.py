"""The text and strict-JSON data of a certified map
(:class:`cdpm.certify.map.CertifiedMap`): how much of the mapped volume is
proven YES, proven NO or undecided, the certified regions, and why boxes
stayed undecided."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cdpm.verdicts import MARGINAL, NO, YES

__all__ = ["certified_json", "certified_lines"]

#: undecided reasons listed, by decreasing volume
MAX_REASONS = 3


def certified_json(cmap: Any, seconds: float | None = None) -> dict:
    """A certified map's summary as JSON-able data: the coordinates and
    their cells, the boxes by verdict, the volume fractions, the certified
    regions (count and the largest's share of the mapped volume), the
    undecided boxes' reasons (by volume), and the spec and store it comes
    from; ``seconds``: the run's wall time."""
    f = cmap.fractions()
    labels = cmap.regions()
    volumes = cmap.volumes
    total = float(volumes.sum())
    n_regions = int(labels.max(initial=0))
    largest = float(volumes[labels == 1].sum() / total) if n_regions and total > 0 else 0.0
    undecided = cmap.verdict == MARGINAL
    reasons: dict[str, float] = {}
    for reason, v in zip(np.asarray(cmap.boxes.reason)[undecided], volumes[undecided], strict=True):
        reasons[str(reason)] = reasons.get(str(reason), 0.0) + float(v)
    listed = sorted(reasons.items(), key=lambda kv: -kv[1])
    provenance = dict(cmap.provenance)
    return {
        "spec": provenance.get("spec"),
        "store": provenance.get("store"),
        "coordinates": list(cmap.coordinates),
        "units": list(cmap.units),
        "cells": [int(e.size - 1) for e in cmap.edges],
        "ranges": [[float(e[0]), float(e[-1])] for e in cmap.edges],
        "min_fraction": float(cmap.min_fraction),
        "boxes": int(cmap.verdict.size),
        "boxes_by_verdict": {
            "yes": int((cmap.verdict == YES).sum()),
            "no": int((cmap.verdict == NO).sum()),
            "undecided": int(undecided.sum()),
        },
        "fractions": f,
        "regions": n_regions,
        "largest_region_fraction": largest,
        "undecided_reasons": [
            {"reason": r, "fraction": v / total if total > 0 else 0.0} for r, v in listed
        ],
        "reach_horizon": float(cmap.boxes.horizon),
        "tension_budget": float(cmap.boxes.tension_budget),
        "seconds": seconds,
    }


def certified_lines(summary: dict) -> list[str]:
    """The lines ``cdpm certify`` prints of :func:`certified_json`'s data."""
    f = summary["fractions"]
    cells = " x ".join(str(n) for n in summary["cells"])
    name = summary["spec"].rsplit("/", 1)[-1] if summary["spec"] else "the robot"
    lines = [
        f"{name}: certified map over {', '.join(summary['coordinates'])} ({cells} cells, "
        f"least box {_least_box(summary['min_fraction']):.4g} of a cell's width): "
        f"{summary['boxes']} boxes",
        f"proven YES {100 * f['yes']:.2f}% of the volume, proven NO {100 * f['no']:.2f}%, "
        f"undecided {100 * f['undecided']:.2f}%",
    ]
    n = summary["regions"]
    if n:
        lines.append(
            f"certified regions (YES boxes joined through shared faces): {n}; the largest "
            f"holds {100 * summary['largest_region_fraction']:.2f}% of the volume"
        )
    else:
        lines.append("certified regions: none (no box proven YES)")
    reasons = summary["undecided_reasons"]
    if reasons:
        lines.append("undecided, by share of the volume:")
        for item in reasons[:MAX_REASONS]:
            share = 100 * item["fraction"]
            shown = f"{share:.2f}%" if share >= 0.005 else "<0.01%"
            lines.append(f"  {shown}: {item['reason']}")
        if len(reasons) > MAX_REASONS:
            lines.append(f"  ... and {len(reasons) - MAX_REASONS} other reason(s)")
    if summary.get("seconds") is not None:
        lines.append(f"time {summary['seconds']:.1f} s")
    return lines


def _least_box(min_fraction: float) -> float:
    """The least box a certified map makes, as a fraction of a cell's width:
    boxes are halved while wider than ``min_fraction``, so the largest
    1/2^k at most it."""
    k = max(0, math.ceil(-math.log2(min_fraction) - 1e-12))
    return 2.0**-k
