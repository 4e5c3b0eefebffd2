"""Pose report: every verdict cdpm gives about one pose, with its evidence.

:func:`analyze_pose` linearises the robot at a pose and runs the analysis
layer on the result; :class:`PoseReport` prints it for people (``str``),
notebooks (``_repr_html_`` and IPython's ``_repr_pretty_``: the same
text; ``repr`` is one line) and programs (``as_dict`` -> JSON). At a pose
that no tension within the cable bounds holds there is nothing to linearise:
``analyze_pose(..., infeasible="report")`` then returns an
:class:`InfeasiblePoseReport` (the pose, the outputs, the cables, the
closest tensions and their statics residual, the map criteria) instead of
raising.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium import InfeasibleEquilibriumError
from cdpm.dynamics.linearisation import Linearisation, linearise
from cdpm.dynamics.reach import reach_settings, reach_unit
from cdpm.errors import InputError
from cdpm.pipeline.criteria import CRITERIA
from cdpm.pipeline.evaluate import evaluate_batch
from cdpm.printing import (
    TextRepr,
    largest_magnitude,
    matrix_text,
    packed_lines,
    strict,
    to_plain,
)
from cdpm.text.format import (
    criteria_lines,
    impulse_scale,
    indent,
    labelled,
    pose_head,
    pose_words,
    singular_pose_notes,
    tension_table,
    units_of_outputs,
    without_negative_zeros,
    without_round_off,
)
from cdpm.text.regions import neighbourhood_json, neighbourhood_lines
from cdpm.verdicts import STATUS_CODES

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.equilibrium import EquilibriumResult
    from cdpm.model.robot import CableRobot

__all__ = [
    "PoseReport",
    "InfeasiblePoseReport",
    "analyze_pose",
    "SINGULAR_MASS_MATRIX",
    "SINGULAR_MASS_MATRIX_FIX",
]

#: why a pose with a singular mass matrix has no linearisation ...
SINGULAR_MASS_MATRIX = (
    "the mass matrix is singular at this pose: a body has zero inertia about an axis that "
    "a joint turns it about, so the robot's accelerations and its linearisation are not "
    "defined"
)
#: ... and what to change
SINGULAR_MASS_MATRIX_FIX = (
    "give that body inertia about every axis in the URDF (e.g. izz > 0 in its <inertia>)"
)


@dataclass(frozen=True)
class PoseReport(TextRepr):
    """Verdicts at one pose of a cable robot.

    Attributes:
        model_name: name of the spec file.
        pose_name: name of the pose, or None for an explicit q.
        natural: natural coordinates of the pose, shape (nv,).
        coordinate_names: names of the natural coordinates.
        cable_lengths: cable lengths [m], shape (m,).
        linearisation: the :class:`~cdpm.dynamics.linearisation.Linearisation` (A, B, C, f*).
        poc: positive output controllability result (paper Theorem 1).
        positive_controllability: Brammer positive (state) controllability.
        output_controllability: output controllability (rank test).
        controllability: Kalman controllability.
        wrench_closure: whether the columns of -L^T positively span R^nv.
        equilibrium: the :class:`~cdpm.dynamics.equilibrium.EquilibriumResult` the
            linearisation is taken at (tensions, taut/slack cables, residual).
        criteria: every registered map criterion at this pose
            (:data:`cdpm.pipeline.criteria.CRITERIA`: name -> value), computed by
            the map pipeline on a batch of one, so a map shows the same.
        reach: the reach margin's horizon and tension budget
            (:class:`cdpm.dynamics.reach.ReachSettings`); its value is
            ``criteria["reach_margin"]``.
        neighbourhood: the POC neighbourhood of the pose
            (:func:`cdpm.poc_neighbourhood`), or None.
        length_scale: the robot's size at the pose [m]: the largest distance
            of a cable route point or an output from the world origin. Printed
            outputs below the last printed digit of it show as 0 (round-off).
        outputs: the spec's outputs (:class:`cdpm.model.spec.OutputDef`: unit and
            formula of each), in order; empty: every output in metres.
        criteria_attrs: the map store's attributes of each criterion for
            this robot (their ``units``; ``output_units`` of ``y``).
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
    length_scale: float | None = None
    outputs: tuple[Any, ...] = ()
    criteria_attrs: dict[str, dict] = field(default_factory=dict, repr=False)

    @property
    def feasible(self) -> bool:
        """True: the pose has an equilibrium (see :class:`InfeasiblePoseReport`)."""
        return True

    @property
    def output_units(self) -> tuple[str, ...]:
        """The unit of each output (``"m"``, ``"rad"``, a spec's ``unit:``)."""
        return units_of_outputs(self.outputs, len(self.linearisation.output_names))

    @property
    def reach_unit(self) -> str:
        """The unit of r_T: the outputs' common unit, or e.g. ``"m and rad,
        one to one"`` (:func:`cdpm.dynamics.reach.reach_unit`)."""

        return reach_unit(self.output_units)

    @property
    def reach_margin(self) -> tuple[float, float]:
        """(r_T, its error bound), in :attr:`reach_unit` (metres for
        position outputs): the true r_T lies in [r_T, r_T + error]; NaN when
        not computed."""
        return (
            float(self.criteria.get("reach_margin", np.nan)),
            float(self.criteria.get("reach_margin_error", np.nan)),
        )

    @property
    def singular_notes(self) -> tuple[str, ...]:
        """Whether the pose is singular, one sentence per Jacobian whose rank
        drops (the outputs' dy/dq, the cables' L); empty at a regular pose
        (:func:`cdpm.text.format.singular_pose_notes`)."""
        lin = self.linearisation
        return singular_pose_notes(lin.output_jacobian, lin.cable_jacobian)

    def _reach_lines(self) -> list[str]:
        if self.reach is None:
            return []
        r, err = self.reach_margin
        names = ", ".join(self.linearisation.output_names) or "the outputs"
        exact = "exact" if err == 0 else f"a lower bound: at most {err:.2g} more"
        if not np.isfinite(r) and np.isnan(err):
            p, m = len(self.linearisation.output_names), len(self.linearisation.cable_names)
            return [
                f"Reach margin r_T: not computed: with {p} outputs and {m} cables its facet "
                "search is too large (docs/analysis.md, 'Reach margin'); fewer outputs (or a "
                "weighted sum of them) make it tractable",
                f"  {self.reach.describe()}",
            ]
        if not np.isfinite(r):
            return [
                f"Reach margin r_T: not resolvable within T = {self.reach.horizon:.3g} s: a "
                "mode grows by more than 1e8 in that time (use a shorter --horizon)",
                f"  {self.reach.describe()}",
            ]
        unit = self.reach_unit
        if "," in unit:  # mixed metres and radians
            head = f"Reach margin r_T = {r + 0.0:.4g} ({unit}; {exact})"
            either = unit.removesuffix(", one to one").replace(" and ", " or ")
            moved = f"{r + 0.0:.4g} {either} in every direction of output space"
        else:
            head = f"Reach margin r_T = {r + 0.0:.4g} {unit} ({exact})"
            moved = f"{r + 0.0:.4g} {unit} in every direction"
        if r == 0:  # not POC within T: some direction of output space is not reached
            return [
                f"{head}: within T = {self.reach.horizon:.3g} s, on the linearisation, the "
                f"cables cannot move {names} in some direction of output space",
                f"  {self.reach.describe()}",
            ]
        return [
            f"{head}: within T = {self.reach.horizon:.3g} s, on the linearisation, the cables "
            f"can move {names} {moved}",
            f"  {self.reach.describe()}",
        ]

    def as_dict(self) -> dict:
        """JSON-serialisable content of the report (``"feasible": true``;
        ``"notes"``: :attr:`singular_notes`)."""
        lin = self.linearisation
        return {
            "model": self.model_name,
            "pose": self.pose_name,
            "feasible": True,
            "q": lin.q.tolist(),
            "coordinates": dict(zip(self.coordinate_names, self.natural.tolist(), strict=True)),
            "output": dict(zip(lin.output_names, lin.output.tolist(), strict=True)),
            "output_units": dict(zip(lin.output_names, self.output_units, strict=True)),
            "notes": list(self.singular_notes),
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
            "wrench_closure": _named_closure(self.wrench_closure, lin.cable_names),
            "criteria": to_plain(self.criteria),
            "reach": None
            if self.reach is None
            else {
                **self.reach.as_dict(),
                "reach_margin": self.reach_margin[0],
                "error": self.reach_margin[1],
                "unit": self.reach_unit,
            },
            "neighbourhood": None
            if self.neighbourhood is None
            else neighbourhood_json(self.neighbourhood),
        }

    def __str__(self) -> str:
        lin = self.linearisation
        lines = [
            *pose_head(self, lin.output, lin.output_names, self.outputs, self.singular_notes),
            *self._equilibrium_lines(),
        ]
        lines += [
            "",
            "Linearisation (state = (dq, dq'))",
            *packed_lines("  states:", list(lin.state_names)),
            indent(f"A =\n{matrix_text(lin.A)}"),
            indent(f"B =\n{matrix_text(lin.B)}"),
            indent(f"C =\n{matrix_text(lin.C)}"),
        ]
        verdicts = [
            labelled("Positive output controllability (Theorem 1)", self.poc),
            labelled("Positive controllability (Brammer)", self.positive_controllability),
            f"Output controllability: {self.output_controllability}"
            + self._more_outputs_than_dof(),
            f"Controllability (Kalman): {self.controllability}",
            # the wrench of each cable, named as in the spec
            f"Wrench closure: {self.wrench_closure.describe(lin.cable_names, 'cables')}",
        ]
        # decided quantities in the results' own text, each to its scale:
        # the span margin is on unit vectors, the eigenvalues are A's
        a_scale = largest_magnitude(lin.A)
        scales = {
            "impulse index": impulse_scale(self.poc),
            "margin": 1.0,
            "eigenvalue": a_scale,
            "A^T v =": a_scale,
        }
        lines += ["", "Verdicts", *[indent(without_round_off(v, scales)) for v in verdicts]]
        lines += [indent(line) for line in self._reach_lines()]
        if self.neighbourhood is not None:
            lines += ["", *neighbourhood_lines(self.neighbourhood)]
        if self.criteria:
            lines += ["", "Map criteria (as a workspace map stores them)"]
            lines += [
                indent(line)
                for line in criteria_lines(
                    {
                        name: value
                        for name, value in self.criteria.items()
                        # without the reach margin (margin=False), not listed
                        if self.reach is not None or not name.startswith("reach_margin")
                    },
                    lin.output_names,
                    self.length_scale or 0.0,
                    self.output_units,
                    self.criteria_attrs,
                )
            ]
        return without_negative_zeros("\n".join(lines))

    def __repr__(self) -> str:
        """One line: model, pose and the POC verdict (``str`` is the report)."""
        poc = f"POC {self.poc.verdict.value.upper()} ({self.poc.method})"
        r = self.reach_margin[0]
        if self.reach is not None and np.isfinite(r):
            poc += f", r_T = {r + 0.0:.4g} {self.reach_unit}"
        return f"<PoseReport {self.model_name}, {pose_words(self.pose_name)}: {poc}>"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        """IPython's text of the report: its ``str`` (the notebook's html is too)."""
        printer.text(repr(self) if cycle else str(self))

    def _more_outputs_than_dof(self) -> str:
        """A note when p > nv: the outputs move only through the nv
        coordinates, so their rank is at most nv whatever the cables do."""
        p, nv = len(self.linearisation.output_names), len(self.coordinate_names)
        if p <= nv:
            return ""
        return f" ({p} outputs, {nv} degrees of freedom: never output controllable)"

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
                + f"): {status}, residual |L^T f + G + w_ext| = {eq.residual:.3g} (N or N m)",
                f"  {eq.message}",
            ]
            states = eq.cable_states()
        inputs = {1: "u >= 0 (pull only)", -1: "u <= 0 (release only)", 0: "free"}
        signs = lin.input_sign if lin.input_sign is not None else lin.sign_constrained.astype(int)
        words = [inputs[int(sign)] for sign in signs]
        return head + tension_table(
            lin.cable_names,
            self.cable_lengths,
            lin.tension,
            states,
            words,
            "input",
            at_bound=lin.sign_constrained,
        )


@dataclass(frozen=True)
class InfeasiblePoseReport(TextRepr):
    """What cdpm can say at a pose that no tension within the cable bounds
    holds (by the requested method): the pose, its kinematics, the closest
    tensions and the map criteria, but no linearisation and so no verdicts.

    Attributes:
        model_name: name of the spec file.
        pose_name: name of the pose, or None for an explicit q.
        q: configuration vector, shape (nq,).
        natural: natural coordinates of the pose, shape (nv,).
        coordinate_names: names of the natural coordinates.
        output: outputs y = h(q), shape (p,), each in its unit (``outputs``).
        output_names: names of the outputs.
        cable_names: names of the cables.
        cable_lengths: cable lengths [m], shape (m,).
        equilibrium: the infeasible :class:`~cdpm.dynamics.equilibrium.EquilibriumResult`:
            its ``tension`` [N] are the tensions within the method's bounds
            that come closest to holding the pose (least squares), its
            ``residual`` the statics residual ``|L^T f + G + w_ext|`` they
            leave [N or N m], its ``message`` why no tension holds the pose.
        criteria: every registered map criterion at this pose (status
            ``no_equilibrium``, the verdicts not analysed, static
            feasibility and wrench closure as a map stores them).
        length_scale: the robot's size at the pose [m] (as :class:`PoseReport`).
        neighbourhood_radius: the ``neighbourhood`` asked for [rad or m], or
            None; it is not computed at a pose without an equilibrium.
        outputs: the spec's outputs (unit and formula of each), as
            :class:`PoseReport`.
        criteria_attrs: the criteria's store attributes, as :class:`PoseReport`.
    """

    model_name: str
    pose_name: str | None
    q: np.ndarray
    natural: np.ndarray
    coordinate_names: tuple[str, ...]
    output: np.ndarray
    output_names: tuple[str, ...]
    cable_names: tuple[str, ...]
    cable_lengths: np.ndarray
    equilibrium: EquilibriumResult
    criteria: dict[str, Any] = field(default_factory=dict)
    length_scale: float | None = None
    neighbourhood_radius: Any = None
    outputs: tuple[Any, ...] = ()
    criteria_attrs: dict[str, dict] = field(default_factory=dict, repr=False)

    @property
    def feasible(self) -> bool:
        """False: no tension within the cable bounds holds the pose."""
        return False

    @property
    def output_units(self) -> tuple[str, ...]:
        """The unit of each output (as :attr:`PoseReport.output_units`)."""
        return units_of_outputs(self.outputs, len(self.output_names))

    @property
    def singular_mass_matrix(self) -> bool:
        """True: the mass matrix is singular at this pose (the map status
        ``singular_mass_matrix``, which a map gives the pose before asking
        for an equilibrium): even tensions that held the pose would give no
        linearisation."""
        return self.criteria.get("status") == STATUS_CODES["singular_mass_matrix"]

    @property
    def reason(self) -> str:
        """Why there is no linearisation and no verdict, in one sentence."""
        eq = self.equilibrium
        undefined = (
            "positive output controllability, positive controllability, output and Kalman "
            "controllability and the reach margin are not defined here"
        )
        if self.singular_mass_matrix:
            return (
                f"{SINGULAR_MASS_MATRIX}, and so {undefined}. To fix: "
                f"{SINGULAR_MASS_MATRIX_FIX}. Besides, no tension within the cable bounds holds "
                f"this pose by method {eq.method!r} (the closest tensions leave a statics "
                f"residual of {eq.residual:.3g} N or N m)"
            )
        text = (
            "the linearisation is taken at an equilibrium (q*, q' = 0, f*), and no tension "
            f"within the cable bounds holds this pose by method {eq.method!r} (the closest "
            f"tensions leave a statics residual of {eq.residual:.3g} N or N m), so {undefined}"
        )
        if self.criteria.get("static_feasible") == 1 and eq.method != "min_norm":
            text += (
                " (static_feasible is yes: other tensions within the bounds hold the pose, "
                "e.g. by method 'min_norm')"
            )
        return text

    def as_dict(self) -> dict:
        """JSON-serialisable content (``"feasible": false``; the verdicts,
        the linearisation and the reach margin are null)."""
        eq = self.equilibrium
        return {
            "model": self.model_name,
            "pose": self.pose_name,
            "feasible": False,
            "q": self.q.tolist(),
            "coordinates": dict(zip(self.coordinate_names, self.natural.tolist(), strict=True)),
            "output": dict(zip(self.output_names, self.output.tolist(), strict=True)),
            "output_units": dict(zip(self.output_names, self.output_units, strict=True)),
            "notes": None,  # singular poses are noted with the linearisation
            "cables": [
                {
                    "name": name,
                    "length": float(length),
                    "tension": float(f),
                    "state": state,
                    # an infinite bound is null (JSON has no infinity)
                    "tension_min": strict(low),
                    "tension_max": strict(high),
                }
                for name, length, f, state, low, high in zip(
                    self.cable_names,
                    self.cable_lengths,
                    eq.tension,
                    eq.cable_states(),
                    eq.tension_min,
                    eq.tension_max,
                    strict=True,
                )
            ],
            "equilibrium": eq.as_dict(),
            "statics_residual": float(eq.residual),
            "reason": self.reason,
            "linearisation": None,
            "positive_output_controllability": None,
            "positive_controllability": None,
            "output_controllability": None,
            "controllability": None,
            "wrench_closure": None,
            "criteria": to_plain(self.criteria),
            "reach": None,
            "neighbourhood": None,
        }

    def __str__(self) -> str:
        eq = self.equilibrium
        method = eq.method + (
            f", pretension {eq.pretension:g} N" if eq.method == "pretension" else ""
        )
        bounds = [
            f"[{low:g}, {high:g}]" for low, high in zip(eq.tension_min, eq.tension_max, strict=True)
        ]
        lines = [
            *pose_head(self, self.output, self.output_names, self.outputs),
            f"Equilibrium ({method}): INFEASIBLE, residual |L^T f + G + w_ext| = "
            f"{eq.residual:.3g} (N or N m)",
            f"  {eq.message}",
            f"  closest tensions: {_closest_words(eq)}",
            *tension_table(
                self.cable_names,
                self.cable_lengths,
                eq.tension,
                eq.cable_states(),
                bounds,
                "bounds [N]",
            ),
            "",
            "No linearisation and no verdicts:",
            *indent(_wrap(self.reason)).splitlines(),
        ]
        if self.neighbourhood_radius is not None:
            lines += [
                "",
                f"POC neighbourhood (R = {self.neighbourhood_radius}): not computed, the pose "
                "itself has no equilibrium",
            ]
        if self.criteria:
            lines += ["", "Map criteria (as a workspace map stores them)"]
            lines += [
                indent(line)
                for line in criteria_lines(
                    self.criteria,
                    self.output_names,
                    self.length_scale or 0.0,
                    self.output_units,
                    self.criteria_attrs,
                )
            ]
        return without_negative_zeros("\n".join(lines))

    def __repr__(self) -> str:
        """One line: model, pose and why there are no verdicts (``str`` is the report)."""
        why = (
            "singular mass matrix"
            if self.singular_mass_matrix
            else f"no equilibrium by method {self.equilibrium.method!r}"
        )
        where = pose_words(self.pose_name)
        return f"<InfeasiblePoseReport {self.model_name}, {where}: {why}, no verdicts>"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        """IPython's text of the report: its ``str`` (the notebook's html is too)."""
        printer.text(repr(self) if cycle else str(self))


def _closest_words(eq: EquilibriumResult) -> str:
    """Which tensions the infeasible result shows, in words."""
    if eq.method == "zero":
        return "method 'zero' allows f = 0 only"
    where = "within the cable bounds"
    if eq.method == "pretension":
        where += f" and at least {eq.pretension:g} N (the pretension)"
    return f"the least-squares solution of the statics {where}"


def _named_closure(result, cable_names) -> dict:
    """The wrench closure's ``as_dict()`` with the cables' names beside the
    0-based column indices of its certificate (``cables``)."""
    out = result.as_dict()
    indices = out["certificate"]["indices"]
    if indices is not None:
        out["certificate"]["cables"] = [str(cable_names[i]) for i in indices]
    return out


def _wrap(text: str, width: int = 88) -> str:
    return textwrap.fill(text, width)


def analyze_pose(
    robot: CableRobot,
    q: Any,
    tension: Any = None,
    pretension: float | None = None,
    *,
    horizon: Any = None,
    tension_budget: Any = None,
    neighbourhood: Any = None,
    neighbourhood_points: int | None = None,
    infeasible: str = "raise",
    margin: bool = True,
) -> PoseReport | InfeasiblePoseReport:
    """Linearise ``robot`` at ``q`` and decide every property at that pose.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        q: a pose name from the spec, a configuration vector (nq,),
            natural coordinates (nv,) or ``{coordinate: value}`` (as
            :meth:`~cdpm.model.robot.CableRobot.as_q` reads it).
        tension: equilibrium tension: None (the spec's method), a method
            name or an array (see :func:`~cdpm.linearise`).
        pretension: least tension [N] for the ``pretension`` method.
        horizon: T [s] of the reach margin (default: the model's,
            :func:`cdpm.dynamics.reach.reach_settings`).
        tension_budget: the reach margin's tension budget [N] (default:
            the model's).
        neighbourhood: half-width R [rad, m] of a local map around the pose
            for the POC neighbourhood (:func:`cdpm.poc_neighbourhood`), or
            None to skip it.
        neighbourhood_points: grid points per coordinate of that map, odd
            (default: :func:`cdpm.poc_neighbourhood`'s).
        infeasible: what to do when no tension within the cable bounds holds
            the pose by the method: ``"raise"`` (default) raises
            :class:`~cdpm.dynamics.equilibrium.InfeasibleEquilibriumError`,
            ``"report"`` returns an :class:`InfeasiblePoseReport` (the pose,
            the closest tensions and their residual, the map criteria; no
            linearisation, no verdicts).

    Returns:
        The :class:`PoseReport`, or with ``infeasible="report"`` at a pose
        without an equilibrium an :class:`InfeasiblePoseReport`; both have
        ``feasible``.

    Raises:
        InfeasibleEquilibriumError: with ``infeasible="raise"``, no tension
            within the bounds holds the pose; its ``result`` (and message)
            give the closest tensions and the residual.
        InputError: a bad argument, or given tensions that do not hold the
            pose (:class:`~cdpm.dynamics.equilibrium.NotAnEquilibriumError`).
    """
    # scipy: loaded on first use
    from cdpm import analysis

    if infeasible not in ("raise", "report"):
        raise InputError(f"infeasible must be 'raise' or 'report', got {infeasible!r}")
    pose_name = q if isinstance(q, str) else None
    reach = reach_settings(robot, horizon, tension_budget)
    try:
        lin = linearise(robot, q, tension=tension, pretension=pretension)
    except InfeasibleEquilibriumError as exc:
        if infeasible == "raise":
            raise
        return _infeasible_report(robot, exc.result, pose_name, pretension, reach, neighbourhood)
    B_cone = lin.B_cone
    kin = robot.kinematics(lin.q)
    natural = robot.to_natural(lin.q)
    eq = lin.equilibrium
    setting = lin.tension if eq is None or eq.method == "given" else eq.method
    if not margin:  # r_T skipped: its criteria stay NaN and the report leaves it out
        reach = None
    batch = evaluate_batch(
        robot, natural[None], setting, pretension=pretension, margin=margin, reach=reach
    )
    criteria = {name: c.compute(batch)[0] for name, c in CRITERIA.items()}
    ball = None
    if neighbourhood is not None:
        # multiprocessing: loaded on first use
        from cdpm.regions.neighbourhood import poc_neighbourhood

        ball = poc_neighbourhood(
            robot,
            lin.q,
            neighbourhood,
            points=neighbourhood_points,
            tension=setting,
            pretension=pretension,
            horizon=reach_settings(robot, horizon, tension_budget),
            pose_name=pose_name,
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
        length_scale=_length_scale(kin),
        outputs=tuple(robot.spec.outputs),
        criteria_attrs={name: c.attrs(robot) for name, c in CRITERIA.items()},
    )


def _infeasible_report(
    robot: CableRobot, eq: EquilibriumResult, pose_name, pretension, reach, neighbourhood
) -> InfeasiblePoseReport:
    """The report at a pose without an equilibrium (``eq`` infeasible)."""

    kin = robot.kinematics(eq.q)
    natural = robot.to_natural(eq.q)
    batch = evaluate_batch(robot, natural[None], eq.method, pretension=pretension, reach=reach)
    return InfeasiblePoseReport(
        model_name=robot.spec.path.name,
        pose_name=pose_name,
        q=eq.q.copy(),
        natural=natural,
        coordinate_names=robot.coordinate_names,
        output=kin.output.copy(),
        output_names=robot.output_names,
        cable_names=robot.cable_names,
        cable_lengths=kin.lengths.copy(),
        equilibrium=eq,
        criteria={name: c.compute(batch)[0] for name, c in CRITERIA.items()},
        length_scale=_length_scale(kin),
        neighbourhood_radius=neighbourhood,
        outputs=tuple(robot.spec.outputs),
        criteria_attrs={name: c.attrs(robot) for name, c in CRITERIA.items()},
    )


def _length_scale(kin: Any) -> float:
    """The robot's size at a pose [m]: the largest distance of a cable
    route point or an output from the world origin."""
    points = np.linalg.norm(kin.point_positions, axis=-1) if kin.point_positions.size else [0.0]
    return max(largest_magnitude(points), largest_magnitude(kin.output))
