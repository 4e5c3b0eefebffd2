"""One verdict vocabulary: codes, labels and colours.

Maps store verdicts as int8 codes, the viewer colours its output marker and
map overlay by them, plots and pictures draw them: every one of them reads
the tables below, so a verdict has one code, one label and one colour
everywhere.
"""

from __future__ import annotations

__all__ = [
    "YES",
    "NO",
    "MARGINAL",
    "NOT_ANALYSED",
    "VERDICT_CODES",
    "VERDICT_LABELS",
    "VERDICT_COLORS",
    "VERDICT_RGB",
    "VERDICT_ORDER",
    "STATUS_CODES",
    "STATUS_LABELS",
    "verdict_code",
    "verdict_key",
    "hex_to_rgb",
]

#: verdict codes (int8 in maps)
YES, NO, MARGINAL, NOT_ANALYSED = 1, 0, 2, -1

#: verdict name -> code, in the order of a map's ``flag_values``
VERDICT_CODES: dict[str, int] = {
    "yes": YES,
    "no": NO,
    "marginal": MARGINAL,
    "not_analysed": NOT_ANALYSED,
}

#: code -> label for legends and text
VERDICT_LABELS: dict[int, str] = {
    YES: "yes",
    NO: "no",
    MARGINAL: "marginal",
    NOT_ANALYSED: "not analysed",
}

#: code -> colour (hex sRGB) in plots, pictures and the viewer
VERDICT_COLORS: dict[int, str] = {
    YES: "#2e9e44",  # green
    NO: "#d4453a",  # red
    MARGINAL: "#f2a33a",  # amber
    NOT_ANALYSED: "#c8c8c8",  # grey
}

#: codes in legend and colour-map order (worst to best)
VERDICT_ORDER: tuple[int, ...] = (NOT_ANALYSED, NO, MARGINAL, YES)

#: why a map pose has (or lacks) verdicts: name -> int8 code
STATUS_CODES: dict[str, int] = {
    "pending": -1,
    "ok": 0,
    "zero_length_cable": 1,
    "singular_mass_matrix": 2,
    "no_equilibrium": 3,
    "analysis_failed": 4,
}

#: status code -> label for legends and text
STATUS_LABELS: dict[int, str] = {
    code: name.replace("_", " ") for name, code in STATUS_CODES.items()
}


def hex_to_rgb(color: str) -> tuple[float, float, float]:
    """``"#rrggbb"`` -> (r, g, b) in 0..1."""
    value = color.lstrip("#")
    return tuple(int(value[i : i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


#: code -> (r, g, b) in 0..1, the same colours as :data:`VERDICT_COLORS`
VERDICT_RGB: dict[int, tuple[float, float, float]] = {
    code: hex_to_rgb(color) for code, color in VERDICT_COLORS.items()
}

_BY_VALUE = {"yes": YES, "no": NO, "marginal": MARGINAL}


def verdict_code(verdict) -> int:
    """The code of a :class:`cdpm.analysis.Verdict` (or its value string)."""
    value = getattr(verdict, "value", verdict)
    return _BY_VALUE.get(value, NOT_ANALYSED)


def verdict_key(code: int) -> str:
    """The name of a verdict code (``"yes"``, ..., ``"not_analysed"``)."""
    for name, value in VERDICT_CODES.items():
        if value == int(code):
            return name
    return "not_analysed"
