"""JSON output of the commands: strict JSON (non-finite numbers as null)."""

from __future__ import annotations

import json
import math
from typing import Any


def strict(value: Any) -> Any:
    """``value`` with every non-finite float (NaN, inf) replaced by None,
    through dicts, lists and tuples: JSON has no NaN."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict(v) for v in value]
    return value


def dumps(value: Any) -> str:
    """Indented strict JSON of ``value`` (non-finite numbers as null)."""
    return json.dumps(strict(value), indent=2, allow_nan=False)
