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

#: The names a workspace map gives its own variables and dimensions, with
#: what each is: the registered criteria (cdpm/pipeline/criteria.py
#: CRITERIA), their extra dimensions (CRITERION_DIMS), the POC regions
#: (cdpm/maps/regions.py REGION_VARIABLE) and a sampled map's pose
#: dimension. A map names a dimension after each coordinate, so no
#: coordinate may take one of these (the model layer cannot import the
#: registry; tests/test_names.py checks that this table covers it).
MAP_NAMES = {
    "poc": "a map variable (the POC verdicts)",
    "output_controllable": "a map variable (the output controllability verdicts)",
    "positive_controllable": "a map variable (the positive controllability verdicts)",
    "wrench_closure": "a map variable (the wrench closure verdicts)",
    "static_feasible": "a map variable (the static feasibility verdicts)",
    "reach_margin": "a map variable (the reach margins)",
    "reach_margin_error": "a map variable (the reach margins' errors)",
    "tension_min": "a map variable (the smallest equilibrium tensions)",
    "tension_max": "a map variable (the largest equilibrium tensions)",
    "n_taut": "a map variable (the numbers of taut cables)",
    "y": "a map variable (the outputs y)",
    "output_frame_position": "a map variable (the output frame's positions)",
    "status": "a map variable (the pose status)",
    "poc_some_tension": "a map variable (the tension search's POC verdicts)",
    "reach_margin_best": "a map variable (the tension search's reach margins)",
    "tension_best": "a map variable (the tension search's tensions)",
    "poc_region": "a map variable (the POC regions)",
    "output": "a map dimension (one entry per output)",
    "xyz": "a map dimension (x, y, z)",
    "cable": "a map dimension (one entry per cable)",
    "sample": "a map dimension (the poses of a sampled map)",
}


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


def unprintable_name(name: str) -> str | None:
    """Why ``name`` cannot be printed as it is, or None when it can.

    Names are printed raw in reports, tables and plots, so a control
    character (newline, tab, ESC starting a terminal escape sequence) or
    another non-printable one (``str.isprintable``: e.g. a right-to-left
    override) could rewrite what a report shows.
    """
    bad = next((ch for ch in name if not ch.isprintable()), None)
    if bad is None:
        return None
    return (
        f"{short_repr(name)} has the non-printable character {bad!r} (U+{ord(bad):04X}); "
        "names are printed in reports, so they must be printable text with no newline, "
        "tab or escape sequence"
    )


def unknown_keys(problems: Problems, where: str, mapping: dict, allowed: tuple) -> None:
    for key in mapping:
        if key not in allowed:
            problems.add(where, f"unknown key {key!r}; valid keys: {', '.join(allowed)}")
