"""Outputs: what a task controls, as weighted sums of components.

A spec's ``outputs`` list (docs/outputs.md) names, for each output, one
component or a weighted sum of components:

- a world coordinate ``x``, ``y``, ``z`` of a point fixed in a frame [m];
- a world component ``rx``, ``ry``, ``rz`` of a frame's rotation vector
  (log3 of its world rotation) [rad]; its rate is the frame's angular
  velocity about the world axes;
- the coordinate of a one-degree-of-freedom joint (``joint: NAME``) [rad or m];
- a cable's length (``cable: NAME``) [m].

This module defines them (:class:`OutputTerm`, :class:`OutputDef`), reads
them from a spec, and evaluates them in batch for the robot
(:class:`OutputBasis`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cdpm.expressions import parse_number
from cdpm.model._spec_parts import (
    WORLD_FRAME_NAMES,
    Problems,
    read_vector,
    unknown_keys,
    unprintable_name,
)
from cdpm.model._spec_urdf import FrameTable

__all__ = [
    "OutputTerm",
    "OutputDef",
    "OutputBasis",
    "parse_outputs",
    "POSITION_COMPONENTS",
    "ROTATION_COMPONENTS",
    "OUTPUT_COMPONENTS",
    "OUTPUT_TERM_KINDS",
]

#: Position components of a point: its world coordinates [m].
POSITION_COMPONENTS = {"x": 0, "y": 1, "z": 2}

#: Orientation components of a frame: the world components of its rotation
#: vector, log3 of its world rotation [rad]; their rates are the frame's
#: angular velocity about the world axes (docs/outputs.md).
ROTATION_COMPONENTS = {"rx": 0, "ry": 1, "rz": 2}

#: Every ``component`` a frame output may ask for, -> its axis (0, 1, 2).
OUTPUT_COMPONENTS = {**POSITION_COMPONENTS, **ROTATION_COMPONENTS}

#: Kinds of output term: ``position`` and ``rotation`` of a frame, a
#: ``joint`` coordinate, a ``cable`` length.
OUTPUT_TERM_KINDS = ("position", "rotation", "joint", "cable")

_TERM_KEYS = ("frame", "component", "point", "joint", "cable", "weight")
_OUTPUT_KEYS = ("name", "unit", "sum", *_TERM_KEYS)
_OUTPUT_EXAMPLE = (
    "{name: tip_x, frame: tip, component: x}, {name: elbow, joint: joint2}, "
    "{name: c1_length, cable: c1} or {name: s, sum: [{weight: 0.5, frame: tip, "
    "component: x}, ...]}"
)


@dataclass(frozen=True)
class OutputTerm:
    """One weighted component of an output.

    Attributes:
        kind: ``"position"`` (a world coordinate of a point fixed in
            ``frame`` [m]), ``"rotation"`` (a world component of ``frame``'s
            rotation vector [rad]), ``"joint"`` (the coordinate of a
            one-degree-of-freedom joint [rad or m]) or ``"cable"`` (a
            cable's length [m]).
        weight: the term's factor in its output's sum (1 for a plain output).
        frame: the frame (position, rotation), else "".
        component: ``x``, ``y``, ``z`` (position) or ``rx``, ``ry``, ``rz``
            (rotation), else "".
        point_in_frame: the point of a position term in ``frame`` [m],
            shape (3,) (the frame origin by default).
        joint: the joint name of a joint term, else "".
        cable: the cable name of a cable term, else "".
        unit: the component's unit: ``"m"`` or ``"rad"``.
    """

    kind: str
    weight: float = 1.0
    frame: str = ""
    component: str = ""
    point_in_frame: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint: str = ""
    cable: str = ""
    unit: str = "m"

    @property
    def axis(self) -> int:
        """World axis (0, 1, 2) of a position or rotation term."""
        return OUTPUT_COMPONENTS[self.component]

    def describe(self) -> str:
        """``tip.x``, ``tip.rz``, ``joint joint2``, ``cable c1``."""
        if self.kind in ("position", "rotation"):
            at = "" if not any(self.point_in_frame) else f"@{list(self.point_in_frame)}"
            return f"{self.frame}{at}.{self.component}"
        return f"{self.kind} {self.joint or self.cable}"


@dataclass(frozen=True)
class OutputDef:
    """One scalar output: a weighted sum of terms (:class:`OutputTerm`), most
    often a single term of weight 1.

    Attributes:
        name: the output's name.
        terms: its terms, at least one.
        unit: its unit: the terms' common unit (``"m"`` or ``"rad"``), the
            spec's ``unit:`` when given, else ``"mixed"``.
    """

    name: str
    terms: tuple[OutputTerm, ...]
    unit: str = "m"

    @property
    def frame(self) -> str:
        """The frame of the first position or rotation term ("" if none)."""
        term = self.marker_term
        return term.frame if term is not None else ""

    @property
    def component(self) -> str:
        """The component of a single frame term ("" otherwise)."""
        if len(self.terms) == 1 and self.terms[0].kind in ("position", "rotation"):
            return self.terms[0].component
        return ""

    @property
    def point_in_frame(self) -> tuple[float, float, float]:
        """The point of the first position or rotation term in its frame [m]."""
        term = self.marker_term
        return term.point_in_frame if term is not None else (0.0, 0.0, 0.0)

    @property
    def marker_term(self) -> OutputTerm | None:
        """The first position or rotation term: where the output is drawn."""
        return next((t for t in self.terms if t.kind in ("position", "rotation")), None)

    @property
    def has_rotation(self) -> bool:
        """Some term is an orientation component."""
        return any(t.kind == "rotation" for t in self.terms)

    def describe(self) -> str:
        """The output as a formula, e.g. ``0.5 link1.x + 0.5 tip.x``."""
        if len(self.terms) == 1 and self.terms[0].weight == 1.0:
            return self.terms[0].describe()
        parts = [f"{t.weight:g} {t.describe()}" for t in self.terms]
        return " + ".join(parts).replace("+ -", "- ")


def parse_outputs(
    problems: Problems,
    raw: Any,
    frames: FrameTable | None,
    model: Any,
    cables: list,
) -> list[OutputDef]:
    if raw is None or raw == []:
        problems.add("outputs", f"missing; give at least one output, e.g. - {_OUTPUT_EXAMPLE}")
        return []
    if not isinstance(raw, list):
        problems.add("outputs", f"expected a list of outputs, e.g. {_OUTPUT_EXAMPLE}")
        return []
    outputs: list[OutputDef] = []
    seen: set[str] = set()
    for i, item in enumerate(raw):
        where = f"outputs[{i}]"
        if not isinstance(item, dict):
            problems.add(where, f"expected a mapping such as {_OUTPUT_EXAMPLE}; got {item!r}")
            continue
        unknown_keys(problems, where, item, _OUTPUT_KEYS)
        if "sum" in item:
            extra = [k for k in _TERM_KEYS if k in item]
            if extra:
                problems.add(
                    where,
                    f"give either sum or {', '.join(extra)}, not both; put each component "
                    "of the sum in its list",
                )
                continue
            terms = _parse_sum(problems, f"{where}.sum", item["sum"], frames, model, cables)
        else:
            term = _parse_term(problems, where, item, frames, model, cables)
            terms = None if term is None else [term]
        if not terms:
            continue
        if "unit" in item and "sum" not in item:
            problems.add(
                f"{where}.unit",
                f"the unit of a single component is fixed ({terms[0].unit}); unit: names the "
                "unit of a weighted sum (sum: [...]); leave it out here",
            )
            continue
        unit = _output_unit(problems, where, item.get("unit"), terms)
        if unit is None:
            continue
        name = item.get("name", _default_output_name(terms) if "sum" not in item else None)
        if not isinstance(name, str) or not name:
            problems.add(f"{where}.name", f"expected a non-empty string, got {name!r}")
            continue
        if (unprintable := unprintable_name(name)) is not None:
            problems.add(f"{where}.name", f"the output name {unprintable}: rename the output")
            continue
        if name in seen:
            problems.add(f"{where}.name", f"duplicate output name {name!r}")
        seen.add(name)
        outputs.append(OutputDef(name=name, terms=tuple(terms), unit=unit))
    return outputs


def _default_output_name(terms: list[OutputTerm]) -> str:
    term = terms[0]
    if term.kind in ("position", "rotation"):
        return f"{term.frame}_{term.component}"
    return f"{term.joint or term.cable}_{'length' if term.kind == 'cable' else 'q'}"


def _output_unit(problems: Problems, where: str, raw: Any, terms: list[OutputTerm]) -> str | None:
    units = {t.unit for t in terms}
    derived = units.pop() if len(units) == 1 else "mixed"
    if raw is None:
        return derived
    if not isinstance(raw, str) or not raw.strip():
        problems.add(f"{where}.unit", f"expected a unit such as m or rad, got {raw!r}")
        return None
    if (unprintable := unprintable_name(raw.strip())) is not None:
        problems.add(f"{where}.unit", f"the unit {unprintable}")
        return None
    return raw.strip()


def _parse_sum(
    problems: Problems,
    where: str,
    raw: Any,
    frames: FrameTable | None,
    model: Any,
    cables: list,
) -> list[OutputTerm] | None:
    if not isinstance(raw, list) or not raw:
        problems.add(
            where,
            "expected a non-empty list of weighted components, e.g. "
            "[{weight: 0.5, frame: tip, component: x}, {weight: 2, joint: joint2}]",
        )
        return None
    terms = []
    for k, item in enumerate(raw):
        at = f"{where}[{k}]"
        if not isinstance(item, dict):
            problems.add(
                at,
                f"expected {{weight, frame, component}}, {{weight, joint}} or "
                f"{{weight, cable}}; got {item!r}",
            )
            return None
        unknown_keys(problems, at, item, _TERM_KEYS)
        term = _parse_term(problems, at, item, frames, model, cables)
        if term is None:
            return None
        terms.append(term)
    return terms


def _parse_term(
    problems: Problems,
    where: str,
    item: dict,
    frames: FrameTable | None,
    model: Any,
    cables: list,
) -> OutputTerm | None:
    """One output term from its mapping, or None after recording a problem."""
    weight = 1.0
    if "weight" in item:
        try:
            weight = parse_number(item["weight"])
        except ValueError as exc:
            problems.add(f"{where}.weight", str(exc))
            return None
        if not math.isfinite(weight) or weight == 0:
            problems.add(f"{where}.weight", f"must be finite and nonzero, got {weight!r}")
            return None
    kinds = [k for k in ("frame", "joint", "cable") if k in item]
    if len(kinds) != 1:
        said = f"got {' and '.join(kinds)}" if kinds else "got none"
        problems.add(
            where,
            f"name exactly one of frame (with component), joint or cable; {said}",
        )
        return None
    kind = kinds[0]
    if kind != "frame":
        extra = [k for k in ("component", "point") if k in item]
        if extra:
            problems.add(
                where,
                f"{' and '.join(extra)} {'apply' if len(extra) > 1 else 'applies'} to frame "
                "outputs only; leave "
                f"{'them' if len(extra) > 1 else 'it'} out of a {kind} output",
            )
            return None
    if kind == "joint":
        return _joint_term(problems, f"{where}.joint", item["joint"], model, weight)
    if kind == "cable":
        name = item["cable"]
        names = [c.name for c in cables]
        if not isinstance(name, str) or name not in names:
            problems.add(
                f"{where}.cable",
                f"{name!r} is not a cable of this spec; cables: {', '.join(names) or '(none)'}",
            )
            return None
        return OutputTerm(kind="cable", weight=weight, cable=name, unit="m")
    frame = item["frame"]
    component = item.get("component")
    if not isinstance(frame, str):
        problems.add(f"{where}.frame", f"expected a frame name, got {frame!r}")
        return None
    if frames is not None and not frames.exists(frame):
        problems.add(f"{where}.frame", f"frame {frame!r} not in URDF; frames: {frames.listing()}")
        return None
    if not isinstance(component, str) or component not in OUTPUT_COMPONENTS:
        problems.add(
            f"{where}.component",
            f"{component!r} is not valid; use one of {', '.join(OUTPUT_COMPONENTS)} "
            "(x, y, z: world position [m]; rx, ry, rz: rotation about the world axes [rad])",
        )
        return None
    rotation = component in ROTATION_COMPONENTS
    point = (0.0, 0.0, 0.0)
    if item.get("point") is not None:
        if rotation:
            problems.add(
                f"{where}.point",
                f"a frame's orientation ({component}) is the same at every point of it; "
                "leave point out",
            )
            return None
        xyz = read_vector(problems, f"{where}.point", item["point"], 3)
        if xyz is None:
            return None
        if not all(math.isfinite(x) for x in xyz):
            problems.add(f"{where}.point", f"values must be finite, got {xyz}")
            return None
        point = tuple(xyz)
    return OutputTerm(
        kind="rotation" if rotation else "position",
        weight=weight,
        frame=frame,
        component=component,
        point_in_frame=point,
        unit="rad" if rotation else "m",
    )


def _fixed_joint_type():
    # pinocchio: loaded on first use
    import pinocchio as pin

    return pin.FrameType.FIXED_JOINT


def _joint_term(problems: Problems, where: str, name: Any, model: Any, weight: float):
    """A joint term: one-degree-of-freedom joints only (their coordinate
    is the natural one, and its rate is the tangent direction)."""
    if model is None:
        return None
    joints = [model.names[j] for j in range(1, model.njoints)]
    if not isinstance(name, str):
        problems.add(where, f"expected one joint name, got {name!r}; joints: {', '.join(joints)}")
        return None
    if name not in joints:
        fixed = any(f.name == name for f in model.frames if f.type == _fixed_joint_type())
        why = "a fixed joint, which has no coordinate" if fixed else "not a joint of the URDF"
        problems.add(where, f"{name!r} is {why}; joints with a coordinate: {', '.join(joints)}")
        return None
    joint = model.joints[model.getJointId(name)]
    short = joint.shortname()
    if joint.nv != 1 or not short.startswith(("JointModelR", "JointModelP")):
        problems.add(
            where,
            f"joint {name!r} ({short.removeprefix('JointModel')}, {joint.nv} degrees of "
            "freedom) is not revolute or prismatic; use frame outputs (x, y, z, rx, ry, rz) "
            "of the link it moves",
        )
        return None
    unit = "rad" if short.startswith("JointModelR") else "m"
    return OutputTerm(kind="joint", weight=weight, joint=name, unit=unit)


class OutputBasis:
    """The outputs as weighted sums of basis components, evaluated in batch.

    Components: a world coordinate of a tracked point, a world component of
    a frame's rotation vector, a one-DOF joint's coordinate, a cable's
    length. When every output is one point coordinate of weight 1 (most
    specs) :meth:`evaluate` indexes the point arrays directly.
    """

    def __init__(
        self,
        model,
        spec,
        output_points: np.ndarray,
        first_point: int,
        joint_support: np.ndarray,
    ) -> None:
        """Args:
            model: the robot's ``pinocchio.Model``.
            spec: the robot's :class:`cdpm.model.spec.CableSpec`.
            output_points: per output, the index of its marker among the
                robot's tracked points, or -1, shape (p,).
            first_point: the index the first point this basis adds gets.
            joint_support: which tangent directions move each joint, shape
                (njoints, nv) bool.

        The tracked points the outputs need besides their markers are in
        :attr:`points`, as (parent joint, point in that joint's frame [m]);
        the robot tracks them after its own, from ``first_point`` on.
        """
        cable_index = {cable.name: k for k, cable in enumerate(spec.cables)}
        self.points: list[tuple[int, np.ndarray]] = []
        self.plain_rows: np.ndarray | None = None
        plain = []
        self.terms: list[list[tuple[float, str, Any]]] = []
        frames: list[tuple[int, np.ndarray]] = []  # rotation frames: (joint, R joint->frame)
        frame_keys: list[str] = []
        for k, out in enumerate(spec.outputs):
            terms = []
            for term in out.terms:
                if term.kind == "position":
                    if term is out.marker_term:
                        point = int(output_points[k])
                    else:
                        point = first_point + len(self.points)
                        self.points.append(
                            anchor_in_joint(model, term.frame, np.array(term.point_in_frame))
                        )
                    terms.append((term.weight, "position", (term.axis, point)))
                elif term.kind == "rotation":
                    if term.frame not in frame_keys:
                        frame_keys.append(term.frame)
                        frames.append(_frame_rotation(model, term.frame))
                    terms.append(
                        (term.weight, "rotation", (term.axis, frame_keys.index(term.frame)))
                    )
                elif term.kind == "joint":
                    jm = model.joints[model.getJointId(term.joint)]
                    terms.append((term.weight, "joint", (jm.idx_q, jm.idx_v, jm.nq)))
                else:
                    terms.append((term.weight, "cable", cable_index[term.cable]))
            self.terms.append(terms)
            single = len(terms) == 1 and terms[0][0] == 1.0 and terms[0][1] == "position"
            plain.append(3 * terms[0][2][1] + terms[0][2][0] if single else -1)
        if all(r >= 0 for r in plain):
            self.plain_rows = np.array(plain, dtype=int)
        self.frames = frames
        self._joint_support = joint_support

    def evaluate(self, qs, pos, pjac, pl, jac, lengths, rows_l) -> tuple[np.ndarray, np.ndarray]:
        """Outputs (N, p) and their Jacobians (N, p, nv) from the batch
        arrays of :meth:`CableRobot._kinematics_batch` (batch axis last:
        ``pos`` (3, P, N), ``pjac`` (3, P, nv, N), ``lengths`` (m, N),
        ``rows_l`` (m, nv, N); ``pl`` (N, njoints, 12), ``jac`` (N, 6, nv))."""
        if self.plain_rows is not None:
            comp, pts = self.plain_rows % 3, self.plain_rows // 3
            return pos[comp, pts].T, pjac[comp, pts].transpose(2, 0, 1)
        n, nv = qs.shape[0], jac.shape[2]
        rotations = [self._rotation(pl, jac, joint, r_local) for joint, r_local in self.frames]
        out = np.zeros((len(self.terms), n))
        out_jac = np.zeros((len(self.terms), nv, n))
        for k, terms in enumerate(self.terms):
            for weight, kind, where in terms:
                if kind == "position":
                    axis, point = where
                    value, rate = pos[axis, point], pjac[axis, point]
                elif kind == "rotation":
                    axis, frame = where
                    value, rate = rotations[frame][0][:, axis], rotations[frame][1][axis]
                elif kind == "joint":
                    iq, iv, nq = where
                    value = qs[:, iq] if nq == 1 else np.arctan2(qs[:, iq + 1], qs[:, iq])
                    rate = np.zeros((nv, n))
                    rate[iv] = 1.0
                else:
                    value, rate = lengths[where], rows_l[where]
                out[k] += weight * value
                out_jac[k] += weight * rate
        return out.T, out_jac.transpose(2, 0, 1)

    def _rotation(self, pl, jac, joint: int, r_local: np.ndarray):
        """Rotation vectors (N, 3) [rad] of a frame fixed to ``joint`` and its
        world angular Jacobian (3, nv, N)."""
        # scipy: loaded on first use
        from scipy.spatial.transform import Rotation

        # pl rows hold the joint rotation column-major: reshape gives R^T
        r_joint = pl[:, joint, :9].reshape(-1, 3, 3).transpose(0, 2, 1)
        rotvec = Rotation.from_matrix(r_joint @ r_local).as_rotvec()
        mask = self._joint_support[joint]
        angular = jac[:, 3:, :].transpose(1, 2, 0) * mask[None, :, None]
        return rotvec, angular


def anchor_in_joint(model, frame_name: str, point_in_frame: np.ndarray) -> tuple[int, np.ndarray]:
    """The parent joint of a frame of ``model`` and a point given in that
    frame [m], shape (3,), expressed in the joint's frame [m], shape (3,)
    (the world's joint 0 for the world frame's names)."""
    if frame_name in WORLD_FRAME_NAMES:
        return 0, point_in_frame
    frame = model.frames[model.getFrameId(frame_name)]
    return int(frame.parentJoint), np.asarray(frame.placement.act(point_in_frame), dtype=float)


def joint_support(model) -> np.ndarray:
    """Which tangent directions move each joint of ``model``: shape
    (njoints, nv) bool (row 0, the world, is all False)."""
    support = np.zeros((model.njoints, model.nv), dtype=bool)
    for j in range(1, model.njoints):
        for anc in model.supports[j]:
            if anc == 0:
                continue
            jm = model.joints[anc]
            support[j, jm.idx_v : jm.idx_v + jm.nv] = True
    return support


def _frame_rotation(model, frame: str) -> tuple[int, np.ndarray]:
    """(parent joint, rotation from the joint frame to ``frame``, (3, 3))."""
    if frame in WORLD_FRAME_NAMES:
        return 0, np.eye(3)
    f = model.frames[model.getFrameId(frame)]
    return int(f.parentJoint), np.array(f.placement.rotation)
