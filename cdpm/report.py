"""Pose report: every verdict cdpm gives about one pose, with its evidence.

:func:`analyze_pose` linearises the robot at a pose and runs the analysis
layer on the result; :class:`PoseReport` prints it for people (``str``),
notebooks (``_repr_html_``) and programs (``as_dict`` -> JSON).
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.analysis._common import to_plain
from cdpm.linearisation import Linearisation, linearise

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.robot import CableRobot

__all__ = ["PoseReport", "analyze_pose"]


@dataclass(frozen=True)
class PoseReport:
    """Verdicts at one pose of a cable robot.

    Attributes:
        model_name: name of the spec file.
        pose_name: name of the pose, or None for an explicit q.
        natural: natural coordinates of the pose, shape (nv,).
        coordinate_names: names of the natural coordinates.
        cable_lengths: cable lengths [m], shape (m,).
        linearisation: the :class:`~cdpm.linearisation.Linearisation` (A, B, C, f*).
        poc: positive output controllability result (paper Theorem 1).
        positive_controllability: Brammer positive (state) controllability.
        output_controllability: output controllability (rank test).
        controllability: Kalman controllability.
        wrench_closure: whether the columns of -L^T positively span R^nv.
        equilibrium: the :class:`~cdpm.equilibrium.EquilibriumResult` the
            linearisation is taken at (tensions, taut/slack cables, residual).
        criteria: every registered map criterion at this pose
            (:data:`cdpm.maps.criteria.CRITERIA`: name -> value), computed by
            the map pipeline on a batch of one, so a map shows the same.
        reach: the reach margin's horizon and tension budget
            (:class:`cdpm.reach.ReachSettings`); its value is
            ``criteria["reach_margin"]``.
        neighbourhood: the POC neighbourhood of the pose
            (:func:`cdpm.poc_neighbourhood`), or None.
    """

    model_name: str
    pose_name: str | None
    natural: np.ndarray
    coordinate_names: tuple[str, ...]
    cable_lengths: np.ndarray
    linearisation: Linearisation
    poc: Any
    positive_controllability: Any
    output_controllability: Any
    controllability: Any
    wrench_closure: Any
    equilibrium: Any = None
    criteria: dict[str, Any] = field(default_factory=dict)
    reach: Any = None
    neighbourhood: Any = None

    @property
    def reach_margin(self) -> tuple[float, float]:
        """(r_T [m], its error estimate [m]); NaN when not computed."""
        return (
            float(self.criteria.get("reach_margin", np.nan)),
            float(self.criteria.get("reach_margin_error", np.nan)),
        )

    def _reach_lines(self) -> list[str]:
        if self.reach is None:
            return []
        r, err = self.reach_margin
        names = ", ".join(self.linearisation.output_names) or "the outputs"
        exact = "exact" if err == 0 else f"+- {err:.2g}, quadrature estimate"
        if not np.isfinite(r):
            return [
                f"Reach margin r_T: not resolvable within T = {self.reach.horizon:.3g} s: a "
                "mode grows by more than 1e8 in that time (use a shorter --horizon)",
                f"  {self.reach.describe()}",
            ]
        return [
            f"Reach margin r_T = {r + 0.0:.4g} m ({exact}): within T = {self.reach.horizon:.3g} s "
            f"the cables can move {names} {r + 0.0:.4g} m in every direction",
            f"  {self.reach.describe()}",
        ]

    def as_dict(self) -> dict:
        """JSON-serialisable content of the report."""
        lin = self.linearisation
        return {
            "model": self.model_name,
            "pose": self.pose_name,
            "q": lin.q.tolist(),
            "coordinates": dict(zip(self.coordinate_names, self.natural.tolist(), strict=True)),
            "output": dict(zip(lin.output_names, lin.output.tolist(), strict=True)),
            "cables": [
                {
                    "name": name,
                    "length": float(length),
                    "tension": float(f),
                    "sign_constrained": bool(sc),
                }
                for name, length, f, sc in zip(
                    lin.cable_names,
                    self.cable_lengths,
                    lin.tension,
                    lin.sign_constrained,
                    strict=True,
                )
            ],
            "equilibrium": None if self.equilibrium is None else self.equilibrium.as_dict(),
            "linearisation": lin.as_dict(),
            "positive_output_controllability": self.poc.as_dict(),
            "positive_controllability": self.positive_controllability.as_dict(),
            "output_controllability": self.output_controllability.as_dict(),
            "controllability": self.controllability.as_dict(),
            "wrench_closure": self.wrench_closure.as_dict(),
            "criteria": to_plain(self.criteria),
            "reach": None
            if self.reach is None
            else {
                **self.reach.as_dict(),
                "reach_margin": self.reach_margin[0],
                "error": self.reach_margin[1],
            },
            "neighbourhood": None if self.neighbourhood is None else self.neighbourhood.to_plain(),
        }

    def __str__(self) -> str:
        lin = self.linearisation
        where = f"pose {self.pose_name!r}" if self.pose_name else "the given q"
        coords = ", ".join(
            f"{n} = {v:.6g}" for n, v in zip(self.coordinate_names, self.natural, strict=True)
        )
        outputs = ", ".join(
            f"{n} = {v:.6g}" for n, v in zip(lin.output_names, lin.output, strict=True)
        )
        lines = [
            f"cdpm report: {self.model_name}, {where}",
            f"  coordinates: {coords}",
            f"  outputs:     {outputs or '(none)'}",
            "",
            *self._equilibrium_lines(),
        ]
        with np.printoptions(precision=4, suppress=True, linewidth=100):
            lines += [
                "",
                "Linearisation (state = (dq, dq'))",
                _indent(f"A =\n{lin.A}"),
                _indent(f"B =\n{lin.B}"),
                _indent(f"C =\n{lin.C}"),
            ]
        lines += [
            "",
            "Verdicts",
            _indent(_labelled("Positive output controllability (Theorem 1)", self.poc)),
            _indent(_labelled("Positive controllability (Brammer)", self.positive_controllability)),
            _indent(f"Output controllability: {self.output_controllability}"),
            _indent(f"Controllability (Kalman): {self.controllability}"),
            _indent(f"Wrench closure: {self.wrench_closure}"),
            *[_indent(line) for line in self._reach_lines()],
        ]
        if self.neighbourhood is not None:
            lines += ["", *self.neighbourhood.lines()]
        if self.criteria:
            lines += ["", "Map criteria (as a workspace map stores them)"]
            names = self.linearisation.output_names
            lines += [_indent(line) for line in _criteria_lines(self.criteria, names)]
        return _without_negative_zeros("\n".join(lines))

    def _equilibrium_lines(self) -> list[str]:
        lin = self.linearisation
        eq = self.equilibrium
        if eq is None:
            head = ["Cables (equilibrium tension given)"]
            states = ["" for _ in lin.cable_names]
        else:
            status = "statics hold" if eq.feasible else "INFEASIBLE"
            head = [
                f"Equilibrium ({eq.method}"
                + (f", pretension {eq.pretension:g} N" if eq.method == "pretension" else "")
                + f"): {status}, residual |L^T f + G + w_ext| = {eq.residual:.3g}",
                f"  {eq.message}",
            ]
            states = eq.cable_states()
        inputs = {1: "u >= 0 (pull only)", -1: "u <= 0 (release only)", 0: "free"}
        signs = lin.input_sign if lin.input_sign is not None else lin.sign_constrained.astype(int)
        lines = head + [
            f"  {'name':<12} {'length [m]':>11} {'tension [N]':>12}  {'state':<7} input"
        ]
        for name, length, f, state, sign in zip(
            lin.cable_names, self.cable_lengths, lin.tension, states, signs, strict=True
        ):
            lines.append(f"  {name:<12} {length:>11.6f} {f:>12.6g}  {state:<7} {inputs[int(sign)]}")
        return lines

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(str(self))}</pre>"


# A printed zero with a minus sign: "-0", "-0.000", "-0e+00" (from format
# specs) or numpy's "-0." (followed by padding, "," or "]"), standing alone.
_NEGATIVE_ZERO = re.compile(r"(?<![\w.])-(0(?:\.0*)?(?:e[+-]?\d+)?)(?![\w.])")


def _without_negative_zeros(text: str) -> str:
    """``text`` with every printed negative zero shown as zero.

    Values such as -1e-17 print as ``-0`` at a few significant digits (and
    an exact -0.0 always does); the sign carries no information there.
    numpy's ``-0.`` becomes `` 0.`` so matrix columns stay aligned.
    """

    def positive(match: re.Match) -> str:
        zero = match.group(1)
        return (" " if zero == "0." else "") + zero

    return _NEGATIVE_ZERO.sub(positive, text)


def _criteria_lines(criteria: dict[str, Any], output_names=()) -> list[str]:
    """One line per criterion: verdict and status codes by name, quantities
    with their units (per-output values with the outputs' names)."""
    from cdpm.maps.criteria import CRITERIA

    lines = []
    for name, value in criteria.items():
        c = CRITERIA.get(name)
        if c is not None and c.flags is not None:
            names = {code: key for key, code in c.flags.items()}
            text = f"{names.get(int(value), str(value))} ({int(value)})"
        else:
            arr = np.asarray(value, dtype=float) + 0.0
            if c is not None and c.dims == ("output",) and len(output_names) == arr.size:
                text = ", ".join(f"{n} = {x:.6g}" for n, x in zip(output_names, arr, strict=True))
            elif arr.ndim:
                text = np.array2string(arr, precision=6, suppress_small=True)
            else:
                text = f"{float(arr):.6g}"
            if c is not None and c.units not in (None, "1"):
                text += f" {c.units}"
        lines.append(f"{name + ':':<24}{text}")
    return lines


def _labelled(label: str, result: Any) -> str:
    """A result's text under ``label`` (without the result's own name)."""
    text = str(result)
    head, sep, rest = text.partition(": ")
    if sep and head.lower() in label.lower():
        text = rest
    return f"{label}: {text}"


def _indent(text: str, prefix: str = "  ") -> str:
    return "\n".join(prefix + line for line in text.splitlines())


def analyze_pose(
    robot: CableRobot,
    q: Any,
    tension: Any = None,
    pretension: float | None = None,
    *,
    horizon: Any = None,
    tension_budget: Any = None,
    neighbourhood: float | None = None,
) -> PoseReport:
    """Linearise ``robot`` at ``q`` and decide every property at that pose.

    Args:
        robot: a :class:`~cdpm.robot.CableRobot`.
        q: a pose name from the spec, a configuration vector (nq,) or
            natural coordinates (nv,).
        tension: equilibrium tension: None (the spec's method), a method
            name or an array (see :func:`~cdpm.linearise`).
        pretension: least tension [N] for the ``pretension`` method.
        horizon: T [s] of the reach margin (default: the model's,
            :func:`cdpm.reach.reach_settings`).
        tension_budget: the reach margin's tension budget [N] (default:
            the model's).
        neighbourhood: half-width R [rad, m] of a local map around the pose
            for the POC neighbourhood (:func:`cdpm.poc_neighbourhood`), or
            None to skip it.

    Raises:
        InfeasibleEquilibriumError: no tension within the bounds holds the
            pose; its ``result`` (and message) give the residual.
    """
    from cdpm import analysis
    from cdpm.maps._evaluate import evaluate_batch
    from cdpm.maps.criteria import CRITERIA
    from cdpm.reach import reach_settings

    pose_name = q if isinstance(q, str) else None
    lin = linearise(robot, q, tension=tension, pretension=pretension)
    B_cone = lin.B_cone
    kin = robot.kinematics(lin.q)
    natural = robot.to_natural(lin.q)
    eq = lin.equilibrium
    setting = lin.tension if eq is None or eq.method == "given" else eq.method
    reach = reach_settings(robot, horizon, tension_budget)
    batch = evaluate_batch(robot, natural[None], setting, pretension=pretension, reach=reach)
    criteria = {name: c.compute(batch)[0] for name, c in CRITERIA.items()}
    ball = None
    if neighbourhood is not None:
        from cdpm.neighbourhood import poc_neighbourhood

        ball = poc_neighbourhood(
            robot, lin.q, neighbourhood, tension=setting, pretension=pretension
        )
    return PoseReport(
        model_name=robot.spec.path.name,
        pose_name=pose_name,
        natural=natural,
        coordinate_names=robot.coordinate_names,
        cable_lengths=kin.lengths.copy(),
        linearisation=lin,
        poc=analysis.positive_output_controllability(
            lin.A, B_cone, lin.C, sign_constrained=lin.sign_constrained
        ),
        positive_controllability=analysis.positive_controllability(
            lin.A, B_cone, sign_constrained=lin.sign_constrained
        ),
        output_controllability=analysis.output_controllability(lin.A, lin.B, lin.C),
        controllability=analysis.controllability(lin.A, lin.B),
        wrench_closure=analysis.wrench_closure(lin.cable_jacobian),
        equilibrium=lin.equilibrium,
        criteria=criteria,
        reach=reach,
        neighbourhood=ball,
    )
