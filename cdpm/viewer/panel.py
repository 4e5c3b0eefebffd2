"""The panel of the inspection page: every verdict at one pose, once analysed.

:func:`pose_panel` analyses a pose with one call of :func:`cdpm.analyze_pose`
and draws it (in a :class:`cdpm.viewer.Viewer`, or only as a
:class:`~cdpm.viewer.state.PoseState` without one) from that report, so the
scene and the panel show the same analysis. The :class:`PosePanel` holds the
verdicts (POC with its method and reach margin, Brammer positive
controllability, output controllability, wrench closure, static
feasibility), the cables' states and tensions, the outputs, and notes on
singular poses; ``as_dict`` is what the page's JSON endpoint returns and
``str`` what ``cdpm view`` prints.

A pose that cannot be analysed (no equilibrium within the tension bounds, a
zero-length cable, a singular mass matrix) is no error: the panel gives the
reason, and the verdicts that need the linearisation are ``unavailable``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium import InfeasibleEquilibriumError
from cdpm.errors import CdpmError
from cdpm.verdicts import NOT_ANALYSED, VERDICT_COLORS, verdict_code, verdict_key
from cdpm.viewer.state import (
    COLORS,
    PoseState,
    cable_colors,
    output_line,
    pose_state,
    tension_scale,
    with_unit,
)

if TYPE_CHECKING:  # pragma: no cover - for static type checkers only
    from cdpm.model.robot import CableRobot
    from cdpm.text.report import PoseReport
    from cdpm.viewer.scene import Viewer

__all__ = ["PosePanel", "VerdictRow", "pose_panel", "q_arguments", "rgb_hex"]


def rgb_hex(rgb: tuple[float, float, float]) -> str:
    """``(r, g, b)`` in 0..1 -> ``"#rrggbb"``."""
    return "#" + "".join(f"{int(round(255 * min(max(c, 0.0), 1.0))):02x}" for c in rgb)


def q_arguments(natural: Any, decimals: int = 4) -> str:
    """Natural coordinates as command-line arguments, e.g. ``--q 0.5236 1.0472``.

    Args:
        natural: natural coordinates (nv,) [rad or m].
        decimals: decimals kept (trailing zeros dropped).
    """
    words = []
    for value in np.asarray(natural, dtype=float).reshape(-1):
        text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
        words.append("0" if text in ("-0", "") else text)
    return "--q " + " ".join(words)


@dataclass(frozen=True)
class VerdictRow:
    """One line of the panel's verdict table.

    Attributes:
        key: ``poc``, ``positive_controllable``, ``output_controllable``,
            ``wrench_closure`` or ``static_feasible`` (the map criteria's names).
        label: what is decided, for people.
        verdict: ``"yes"``, ``"no"``, ``"marginal"`` or ``"unavailable"``.
        detail: the method and the reason, or why it is unavailable.
    """

    key: str
    label: str
    verdict: str
    detail: str

    @property
    def color(self) -> str:
        """The verdict's colour (hex, :data:`cdpm.verdicts.VERDICT_COLORS`)."""
        return VERDICT_COLORS[verdict_code(self.verdict)]

    @property
    def text(self) -> str:
        """The verdict as the panel writes it: ``YES``, ``NO``, ``MARGINAL``
        or ``unavailable``."""
        return "unavailable" if self.verdict == "unavailable" else self.verdict.upper()

    def as_dict(self) -> dict:
        """JSON-serialisable content (with ``text`` and ``color``)."""
        return {
            "key": self.key,
            "label": self.label,
            "verdict": self.verdict,
            "text": self.text,
            "detail": self.detail,
            "color": self.color,
        }


@dataclass(frozen=True)
class PosePanel:
    """Everything the inspection page shows about one pose.

    Attributes:
        state: what the scene draws (:class:`~cdpm.viewer.state.PoseState`:
            cable states, tensions [N], outputs with their units and
            formulas, POC verdict).
        report: the :class:`cdpm.PoseReport` of the pose, or None when it
            could not be analysed.
        reason: why it could not be analysed, else None.
        verdicts: the verdict table, one :class:`VerdictRow` per property.
        reach: the reach margin, ``{"value", "error"}`` in ``{"unit"}`` (the
            outputs' unit, :func:`cdpm.dynamics.reach.reach_unit`), ``{"horizon"}``
            [s], ``"budget"`` (text), or None when unavailable.
        notes: singular poses and other remarks, one sentence each.
        cable_rgb: colour (r, g, b in 0..1) each cable is drawn in.
        output_units: unit of each output (``"m"``, ``"rad"`` or the spec's).
        seconds: wall time [s] of ``analysis`` (:func:`cdpm.analyze_pose`)
            and ``draw`` (the scene, or the state without a viewer).
    """

    state: PoseState
    report: PoseReport | None
    reason: str | None
    verdicts: tuple[VerdictRow, ...]
    reach: dict | None
    notes: tuple[str, ...]
    cable_rgb: tuple[tuple[float, float, float], ...]
    output_units: tuple[str, ...]
    seconds: dict[str, float] = field(default_factory=dict)

    def verdict(self, key: str) -> VerdictRow:
        """The row of one property (e.g. ``"poc"``).

        Raises:
            KeyError: no such row.
        """
        for row in self.verdicts:
            if row.key == key:
                return row
        raise KeyError(f"no verdict {key!r}; rows: {', '.join(r.key for r in self.verdicts)}")

    def as_dict(self) -> dict:
        """JSON-serialisable content: what the page's panel renders."""
        state = self.state
        return {
            "natural": state.natural.tolist(),
            "coordinates": list(state.coordinate_names),
            "q_arguments": q_arguments(state.natural),
            "reason": self.reason,
            "verdicts": [row.as_dict() for row in self.verdicts],
            "reach": self.reach,
            "notes": list(self.notes),
            "cables": [
                {
                    "name": name,
                    "state": cable_state.value,
                    "tension": None if state.tension is None else float(state.tension[i]),
                    "color": rgb_hex(self.cable_rgb[i]),
                }
                for i, (name, cable_state) in enumerate(
                    zip(state.cable_names, state.cable_states, strict=True)
                )
            ],
            "outputs": [
                {
                    "name": name,
                    "value": float(value),
                    "unit": unit,
                    "kind": kind,
                    "definition": definition,
                }
                for name, value, unit, kind, definition in self._output_rows()
            ],
            "marker_color": rgb_hex(state.verdict_rgb),
            "seconds": dict(self.seconds),
        }

    def _output_rows(self):
        """(name, value, unit, kind, definition) of each output."""
        state = self.state
        return zip(
            state.output_names,
            state.output,
            self.output_units,
            state.output_kinds,
            state.output_definitions,
            strict=True,
        )

    def __str__(self) -> str:
        lines = []
        for row in self.verdicts:
            line = f"{row.label}: {row.text}"
            if row.key == "poc" and self.reason is not None:
                line += f" ({self.reason})"
            elif row.key == "poc" and self.reach is not None:
                reach = self.reach
                margin = with_unit(f"{reach['value']:.4g}", reach["unit"])
                line += (
                    f" ({row.detail.split(':', 1)[0]}); reach margin r_T = "
                    f"{margin} within T = {reach['horizon']:.3g} s"
                )
            elif row.detail and row.detail != _NEEDS_LINEARISATION:
                line += f" ({row.detail})"
            lines.append(line)
        lines += [f"note: {note}" for note in self.notes]
        state = self.state
        coords = ", ".join(
            f"{n} = {v:.4f}" for n, v in zip(state.coordinate_names, state.natural, strict=True)
        )
        outputs = ", ".join(output_line(*row) for row in self._output_rows())
        lines += [f"pose: {coords}  ({q_arguments(state.natural)})"]
        lines += [f"outputs: {outputs or '(none)'}"]
        for i, (name, cable_state) in enumerate(
            zip(state.cable_names, state.cable_states, strict=True)
        ):
            f = "    -" if state.tension is None else f"{state.tension[i]:9.4g} N"
            lines.append(f"  {name:<10} {f}  {cable_state.value}")
        return "\n".join(lines)


#: verdict rows of the panel: key -> label
LABELS = {
    "poc": "Positive output controllability (POC)",
    "positive_controllable": "Positive controllability (Brammer)",
    "output_controllable": "Output controllability",
    "wrench_closure": "Wrench closure",
    "static_feasible": "Static feasibility",
}


#: detail of the verdicts that need the linearisation, at a pose without one
_NEEDS_LINEARISATION = "needs the linearisation: none at this pose"


def pose_panel(robot: CableRobot, q: Any, *, viewer: Viewer | None = None) -> PosePanel:
    """Analyse a pose once and show it: the panel's content and the scene.

    :func:`cdpm.analyze_pose` analyses the pose (the spec's tension method,
    the model's reach horizon and tension budget); the viewer, if any,
    draws that report (:meth:`cdpm.viewer.Viewer.display`).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: a pose name, a configuration vector (nq,) or natural coordinates (nv,).
        viewer: a :class:`cdpm.viewer.Viewer` of the robot to move, or None.

    Returns:
        The :class:`PosePanel`. A pose that cannot be analysed is not an
        error: the panel gives the reason.

    Raises:
        InputError: q is not a pose of the robot.
    """

    q = robot.as_q(q)  # a bad q is the caller's error, not the pose's
    t0 = time.perf_counter()
    report, reason, error = None, None, None
    try:
        # the pose report's pipeline, loaded on first use (`cdpm --help` imports the viewer)
        from cdpm.text.report import analyze_pose

        report = analyze_pose(robot, q)
    except CdpmError as exc:
        reason, error = str(exc), exc
    t1 = time.perf_counter()
    if viewer is not None:
        state = viewer.display(q, report=report, reason=reason)
        rgb = viewer.cable_colors
    else:
        state = pose_state(robot, q, report=report, reason=reason)
        rgb = cable_colors(state, tension_scale(robot, state.tension))
    t2 = time.perf_counter()
    if report is not None:
        verdicts, reach, notes = _analysed_rows(report), _reach(report), _notes(report)
    else:
        verdicts, reach, notes = _unavailable_rows(robot, q, reason, error), None, ()
    return PosePanel(
        state=state,
        report=report,
        reason=reason,
        verdicts=verdicts,
        reach=reach,
        notes=notes,
        cable_rgb=tuple(COLORS["unavailable"] if c is None else c for c in rgb),
        output_units=tuple(robot.output_units),
        seconds={"analysis": t1 - t0, "draw": t2 - t1},
    )


def _value(verdict: Any) -> str:
    """``"yes"``, ``"no"``, ``"marginal"`` of a verdict (enum or string)."""
    return str(getattr(verdict, "value", verdict)).lower()


def _code_value(code: Any) -> str:
    key = verdict_key(int(code))
    return "unavailable" if int(code) == NOT_ANALYSED else key


def _analysed_rows(report: PoseReport) -> tuple[VerdictRow, ...]:
    poc, pc = report.poc, report.positive_controllability
    oc, wc, eq = report.output_controllability, report.wrench_closure, report.equilibrium
    if eq is None:
        statics = "given tensions"
    else:
        residual = f"statics residual {eq.residual:.3g}"
        statics = f"{eq.method}: {eq.message}, {residual}"
    return (
        VerdictRow("poc", LABELS["poc"], _value(poc.verdict), f"{poc.method}: {poc.reason}"),
        VerdictRow(
            "positive_controllable",
            LABELS["positive_controllable"],
            _value(pc.verdict),
            f"{pc.method}: {pc.reason}",
        ),
        VerdictRow(
            "output_controllable",
            LABELS["output_controllable"],
            "yes" if oc.controllable else "no",
            f"output rank {oc.rank} of p = {oc.p}",
        ),
        VerdictRow(
            "wrench_closure",
            LABELS["wrench_closure"],
            _value(wc.verdict),
            f"{wc.method}: {wc.reason}",
        ),
        VerdictRow(
            "static_feasible",
            LABELS["static_feasible"],
            _code_value(report.criteria.get("static_feasible", NOT_ANALYSED)),
            statics,
        ),
    )


def _unavailable_rows(
    robot: CableRobot, q: np.ndarray, reason: str | None, error: Exception | None
) -> tuple[VerdictRow, ...]:
    """Rows of a pose that could not be analysed: the verdicts that need a
    linearisation are unavailable; wrench closure needs only the cable
    Jacobian, static feasibility comes from the failed equilibrium."""
    # scipy: loaded on first use
    from cdpm import analysis

    rows = [
        VerdictRow(key, LABELS[key], "unavailable", _NEEDS_LINEARISATION)
        for key in ("poc", "positive_controllable", "output_controllable")
    ]
    try:
        wc = analysis.wrench_closure(robot.cable_jacobian(q))
        rows.append(
            VerdictRow(
                "wrench_closure",
                LABELS["wrench_closure"],
                _value(wc.verdict),
                f"{wc.method}: {wc.reason}",
            )
        )
    except CdpmError as exc:
        rows.append(VerdictRow("wrench_closure", LABELS["wrench_closure"], "unavailable", str(exc)))
    if isinstance(error, InfeasibleEquilibriumError):
        eq = error.result
        statics = (
            f"{eq.method}: no tension within the bounds holds the pose, "
            f"least statics residual {eq.residual:.3g}"
        )
        rows.append(VerdictRow("static_feasible", LABELS["static_feasible"], "no", statics))
    else:
        rows.append(
            VerdictRow("static_feasible", LABELS["static_feasible"], "unavailable", reason or "")
        )
    return tuple(rows)


def _reach(report: PoseReport) -> dict | None:
    if report.reach is None:
        return None
    value, error = report.reach_margin
    return {
        "value": value + 0.0,
        "error": error,
        "unit": report.reach_unit,
        "horizon": float(report.reach.horizon),
        "budget": report.reach.describe(),
    }


def _notes(report: PoseReport) -> tuple[str, ...]:
    """Singular poses, as ``cdpm analyze`` words them
    (:attr:`cdpm.PoseReport.singular_notes`)."""
    return report.singular_notes
