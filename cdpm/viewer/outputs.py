"""How each output of a spec is drawn: one place for the 3-D view, the
picture and the panels.

An output is drawn where it is measured:

- a **position** output (a world coordinate of a point of a frame) as a
  marker on its point, coloured by the POC verdict;
- an **orientation** output (``rx``, ``ry``, ``rz``: a world component of a
  frame's rotation vector) as the axes of its frame (a large triad, x red,
  y green, z blue) with the verdict marker at the frame's origin;
- a **weighted sum** at its first position or orientation term
  (:attr:`cdpm.model.spec.OutputDef.marker_term`), as that term would be; the
  panels give its formula (:meth:`cdpm.model.spec.OutputDef.describe`);
- a **cable length** output on its cable (emphasised, named in its label),
  with no point of its own;
- a **joint** output with no marker: the panels give its value (the picture
  names it at its joint).

Outputs measured at the same point share one marker. :func:`output_drawing`
gathers this from a robot's spec, without Pinocchio or meshcat.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot
    from cdpm.model.spec import OutputDef

__all__ = ["OutputPoint", "OutputDrawing", "output_drawing", "output_kind", "OUTPUT_KINDS"]

#: What an output is, for its drawing: ``position``, ``rotation``, ``joint``,
#: ``cable`` (single terms of weight 1) or ``sum`` (anything else).
OUTPUT_KINDS = ("position", "rotation", "joint", "cable", "sum")


def output_kind(output: OutputDef) -> str:
    """The kind of an output (:data:`OUTPUT_KINDS`): a single term of weight
    1 is of its term's kind, any other output a ``sum``."""
    if len(output.terms) == 1 and output.terms[0].weight == 1.0:
        return output.terms[0].kind
    return "sum"


@dataclass(frozen=True)
class OutputPoint:
    """One marker: a point at which one or more outputs are measured.

    Attributes:
        name: a distinct name: the frame's name, ``"<frame>.<k>"`` for the
            k-th point of a frame (k >= 2); the scene's node is
            ``output/<name>``.
        frame: the frame holding the point.
        point_in_frame: the point in that frame [m], shape (3,).
        outputs: indices of the outputs drawn here, in spec order.
        label: their names, ``"tip_x, tip_z"``.
        tracked: index of the point among the robot's tracked points
            (:attr:`cdpm.model.robot.CableRobot.output_points`, rows of
            ``point_positions``).
        rotation: an orientation output is drawn here: the frame's axes
            (a triad) are drawn with the marker.
    """

    name: str
    frame: str
    point_in_frame: tuple[float, float, float]
    outputs: tuple[int, ...]
    label: str
    tracked: int
    rotation: bool


@dataclass(frozen=True)
class OutputDrawing:
    """How a robot's outputs are drawn.

    Attributes:
        kinds: kind of each of the p outputs (:func:`output_kind`).
        definitions: each output as a formula (``tip.x``, ``platform.rz``,
            ``joint joint2``, ``cable c1``, ``0.5 link1.x + 0.5 tip.x``).
        points: the markers, each distinct point once, in the order of the
            outputs first drawn there.
        cables: cable index -> names of the outputs whose terms include
            that cable's length (those cables are emphasised).
        joints: joint name -> names of the outputs whose terms include that
            joint's coordinate.
    """

    kinds: tuple[str, ...]
    definitions: tuple[str, ...]
    points: tuple[OutputPoint, ...]
    cables: dict[int, tuple[str, ...]]
    joints: dict[str, tuple[str, ...]]


def output_drawing(robot: CableRobot) -> OutputDrawing:
    """Gather where each output of the robot is drawn.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.

    Returns:
        The :class:`OutputDrawing`.
    """
    outputs = robot.spec.outputs
    keys: list[tuple] = []
    members: list[list[int]] = []
    rotation: list[bool] = []
    cables: dict[int, list[str]] = {}
    joints: dict[str, list[str]] = {}
    cable_index = {name: i for i, name in enumerate(robot.cable_names)}
    for k, out in enumerate(outputs):
        for term in out.terms:
            if term.kind == "cable":
                names = cables.setdefault(cable_index[term.cable], [])
            elif term.kind == "joint":
                names = joints.setdefault(term.joint, [])
            else:
                continue
            if out.name not in names:
                names.append(out.name)
        marker = out.marker_term
        if marker is None:
            continue
        key = (marker.frame, tuple(float(c) for c in marker.point_in_frame))
        if key not in keys:
            keys.append(key)
            members.append([])
            rotation.append(False)
        i = keys.index(key)
        members[i].append(k)
        rotation[i] = rotation[i] or marker.kind == "rotation"
    per_frame: dict[str, int] = {}
    points = []
    for (frame, point), ks, turns in zip(keys, members, rotation, strict=True):
        per_frame[frame] = per_frame.get(frame, 0) + 1
        n = per_frame[frame]
        points.append(
            OutputPoint(
                name=frame if n == 1 else f"{frame}.{n}",
                frame=frame,
                point_in_frame=point,
                outputs=tuple(ks),
                label=", ".join(outputs[k].name for k in ks),
                tracked=int(robot.output_points[ks[0]]),
                rotation=turns,
            )
        )
    return OutputDrawing(
        kinds=tuple(output_kind(o) for o in outputs),
        definitions=tuple(o.describe() for o in outputs),
        points=tuple(points),
        cables={i: tuple(names) for i, names in cables.items()},
        joints={name: tuple(names) for name, names in joints.items()},
    )
