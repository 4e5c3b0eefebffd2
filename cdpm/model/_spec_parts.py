"""Pieces every part of the spec loader uses: the problem list and the
readers of numbers and keys (cdpm/model/spec.py, cdpm/model/outputs.py,
cdpm/model/_spec_urdf.py)."""

from __future__ import annotations

import math
from typing import Any

from cdpm.errors import short_repr
from cdpm.expressions import parse_number

#: Names that refer to the fixed world frame in a route.
WORLD_FRAME_NAMES = ("world", "universe")


class Problems:
    """Collects problems with their YAML path so all are reported at once."""

    def __init__(self) -> None:
        self.items: list[str] = []

    def add(self, where: str, what: str) -> None:
        self.items.append(f"{where}: {what}" if where else what)


def read_vector(
    problems: Problems, where: str, value: Any, size: int | None, infinite: bool = False
) -> list[float] | None:
    """``value`` as a list of ``size`` floats, or None after recording a
    problem. NaN is never a value; +-inf only with ``infinite``."""
    if not isinstance(value, (list, tuple)):
        problems.add(where, f"expected a list of {size or 'some'} numbers, got {short_repr(value)}")
        return None
    if size is not None and len(value) != size:
        problems.add(where, f"expected {size} numbers, got {len(value)}: {short_repr(value)}")
        return None
    out = []
    for k, item in enumerate(value):
        try:
            number = parse_number(item)
        except ValueError as exc:
            problems.add(f"{where}[{k}]", str(exc))
            return None
        if math.isnan(number) or (math.isinf(number) and not infinite):
            problems.add(f"{where}[{k}]", f"{short_repr(item)} is not a finite number")
            return None
        out.append(number)
    return out


def unknown_keys(problems: Problems, where: str, mapping: dict, allowed: tuple) -> None:
    for key in mapping:
        if key not in allowed:
            problems.add(where, f"unknown key {key!r}; valid keys: {', '.join(allowed)}")
