"""Import CASPR models: bodies + cables XML -> URDF + cdpm cable spec.

CASPR (the MATLAB cable-robot platform) describes a robot in two XML files:
``<name>_bodies.xml`` (rigid links, their joints, inertias and parents) and
``<name>_cables.xml`` (cable sets; each cable an ordered list of attachment
points), plus an optional ``<name>_operational_spaces.xml``. This package
reads them with the standard library's XML parser (nothing is executed and no
external DTD or entity is fetched), writes a URDF through yourdfpy's object
model and a cable spec with ``yaml.safe_dump``, and checks that
:func:`cdpm.load_robot` loads the pair.

CASPR conventions reproduced here (CASPR ``SystemModelBodies.update``,
``JointBase``, ``CableAttachmentPoint``, ``BodyModelRigid``):

* Link k's frame sits at its joint point P. Its origin in the parent frame
  is ``r_Parent + r_rel(q)`` (``<parent><location>`` is given in the parent
  link's frame, relative to the parent's joint point, not its centre of mass;
  ``r_rel`` is the joint's translation along the parent's axes) and its
  orientation is ``R_pe(q)`` (vector_in_parent = R_pe @ vector_in_link).
* ``com_location`` and ``end_location`` are given in the link frame from P.
* ``<inertia ref="com">`` is about the centre of mass in link axes;
  ``ref="joint"`` is about P and is shifted to the centre of mass.
* Attachment ``location`` is in the link frame, from the centre of mass
  (``attachment_reference="com"``) or from P (``"joint"``); on link 0 (the
  ground) it is always a world position.
* Gravity is ``[0, 0, -9.81]`` m/s^2 in the world frame.

Every multi-DOF CASPR joint becomes a chain of 1-DOF URDF joints through
massless intermediate links, in the order of CASPR's rotation product, so
the cdpm coordinates are exactly CASPR's q (same values, same singularities;
only ``S_FIXED_XYZ`` lists its three angles in reverse order). See
``docs/caspr.md`` for the full mapping and what is refused or ignored.

Operational spaces become outputs: position axes the world coordinates of
the operational point [m], orientation axes (CASPR's Euler angles a, b, g)
the world components rx, ry, rz of the link frame's rotation vector [rad],
whose C rows are CASPR's own Jacobian rows (the world angular velocity).

Layout: ``_xml`` reads and validates the XML files into plain records,
``_urdf`` turns bodies and joints into the URDF, ``_spec`` turns cables and
the named pose into the cable spec and checks its outputs; :func:`import_caspr`
here runs them in that order and writes the outputs. Thresholds live in
:mod:`cdpm.numerics`.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cdpm.caspr._spec import (
    GRAVITY,
    _choose_pose,
    _moving_components,
    _output_rank_deficit,
    _point_entry,
    _singular_mass_matrix,
)
from cdpm.caspr._urdf import _build_urdf, _op_slugs
from cdpm.caspr._xml import (
    JOINT_CHAINS,
    OPERATIONAL_SPACE_TYPES,
    _OpSpace,
    _read_bodies,
    _read_cables,
    _read_operational_spaces,
    cable_sets,
)
from cdpm.errors import InputError
from cdpm.model.robot import load_robot
from cdpm.printing import TextRepr

__all__ = [
    "CasprImport",
    "CasprWarning",
    "import_caspr",
    "cable_sets",
    "JOINT_CHAINS",
    "OPERATIONAL_SPACE_TYPES",
    "GRAVITY",
]


class CasprWarning(UserWarning):
    """Something in a CASPR file was ignored or changed during import."""


@dataclass(frozen=True)
class CasprImport(TextRepr):
    """Result of :func:`import_caspr`.

    Attributes:
        name: model name (file stem of the URDF and spec).
        urdf_path: the URDF written.
        spec_path: the cable spec written (load it with :func:`cdpm.load_robot`).
        cable_set: id of the CASPR cable set imported.
        operational_set: id of the CASPR operational set turned into outputs,
            or None.
        n_links: number of CASPR links.
        cable_names: names of the cables, in spec order.
        output_names: names of the spec outputs.
        output_units: unit of each output: ``"m"`` (world coordinate of a
            point) or ``"rad"`` (world component of a link frame's rotation
            vector).
        output_sources: for each output, what it is and the CASPR element it
            comes from: ``"world x of frame op_ee (CASPR <position> 'ee' axis
            'x')"``.
        coordinates: for each cdpm coordinate (tangent-space order), the
            CASPR coordinate it is: ``"joint2_rx <- link 2 'Lower Arm' q[1]"``.
        caspr_coordinates: for each cdpm coordinate, (CASPR link number,
            index in that link's joint q), to translate poses either way.
        pose_name: name of the pose written to the spec.
        pose: that pose in cdpm coordinates, shape (nv,).
        warnings: what was ignored or changed, one line each.
    """

    name: str
    urdf_path: Path
    spec_path: Path
    cable_set: str
    operational_set: str | None
    n_links: int
    cable_names: tuple[str, ...]
    output_names: tuple[str, ...]
    coordinates: tuple[str, ...]
    caspr_coordinates: tuple[tuple[int, int], ...]
    pose_name: str
    pose: np.ndarray
    warnings: tuple[str, ...] = field(default=())
    output_units: tuple[str, ...] = field(default=())
    output_sources: tuple[str, ...] = field(default=())

    def as_dict(self) -> dict:
        """JSON-serialisable content."""
        return {
            "name": self.name,
            "urdf": str(self.urdf_path),
            "spec": str(self.spec_path),
            "cable_set": self.cable_set,
            "operational_set": self.operational_set,
            "n_links": self.n_links,
            "cables": list(self.cable_names),
            "outputs": list(self.output_names),
            "output_units": list(self.output_units),
            "output_sources": list(self.output_sources),
            "coordinates": list(self.coordinates),
            "pose": {self.pose_name: self.pose.tolist()},
            "warnings": list(self.warnings),
        }

    def __str__(self) -> str:
        lines = [
            f"CASPR model {self.name!r}: {self.n_links} link(s), {len(self.coordinates)} "
            f"coordinate(s), {len(self.cable_names)} cable(s) (set {self.cable_set!r}), "
            f"{len(self.output_names)} output(s)"
            + (f" (operational set {self.operational_set!r})" if self.operational_set else ""),
            f"  URDF: {self.urdf_path}",
            f"  spec: {self.spec_path}",
            f"  pose {self.pose_name!r}: {np.round(self.pose, 6).tolist()}",
            "  coordinates:",
            *(f"    {c}" for c in self.coordinates),
            "  outputs:",
            *(
                f"    {n} [{u}]: {s}"
                for n, u, s in zip(
                    self.output_names, self.output_units, self.output_sources, strict=True
                )
            ),
        ]
        if self.warnings:
            lines.append(f"  {len(self.warnings)} warning(s):")
            lines.extend(f"    - {w}" for w in self.warnings)
        return "\n".join(lines)


def import_caspr(
    bodies_xml: str | os.PathLike,
    cables_xml: str | os.PathLike,
    out_dir: str | os.PathLike,
    cable_set: str | None = None,
    *,
    operational_spaces_xml: str | os.PathLike | None = None,
    operational_set: str | None = None,
    name: str | None = None,
    seed: int = 0,
) -> CasprImport:
    """Convert a CASPR model into a URDF and a cdpm cable spec.

    Args:
        bodies_xml: CASPR ``<name>_bodies.xml``.
        cables_xml: CASPR ``<name>_cables.xml``.
        out_dir: folder to write ``<name>.urdf`` and ``<name>.yaml`` into
            (created if missing; existing files of that name are replaced).
        cable_set: id of the cable set to import; default the file's
            ``default_cable_set``.
        operational_spaces_xml: CASPR operational spaces file; default
            ``<name>_operational_spaces.xml`` beside the bodies file, if any.
        operational_set: id of the operational set whose components become
            outputs; default the file's default set, else its first.
            Position axes ``x y z`` become world coordinates of the
            operational point [m], orientation axes ``a b g`` the world
            components ``rx ry rz`` of the link frame's rotation vector [rad]
            (``docs/caspr.md`` relates them to CASPR's Euler angles). With no
            outputs from it, the outputs are the world coordinates of the
            last link's end point that the joints can move.
        name: model name for the files; default the bodies file name without
            ``_bodies.xml``.
        seed: seed of the search for a pose when CASPR's ``q_initial`` has a
            zero-length cable segment or lies outside the joint limits.

    Returns:
        A :class:`CasprImport` with the paths written and the warnings.

    Raises:
        UnsupportedError: the model uses something cdpm cannot represent
            (pulleys, passive springs, actuated joints, quaternion joints,
            unknown joint or cable types); the message names the element and
            the file.
        InputError: a file is missing, malformed or inconsistent.
        MissingExtraError: yourdfpy is not installed.
    """

    bodies_path = Path(bodies_xml).expanduser().resolve()
    cables_path = Path(cables_xml).expanduser().resolve()
    out = Path(out_dir).expanduser().resolve()
    stem = bodies_path.name
    stem = stem[: -len("_bodies.xml")] if stem.endswith("_bodies.xml") else bodies_path.stem
    model_name = name or stem
    if not re.fullmatch(r"[A-Za-z0-9_.\-]+", model_name):
        raise InputError(
            f"model name {model_name!r} must be letters, digits, '_', '-' or '.'; pass name="
        )

    collected: list[str] = []

    def warn(message: str) -> None:
        collected.append(message)
        warnings.warn(message, CasprWarning, stacklevel=3)

    links, meta = _read_bodies(bodies_path)
    links_by_num = {link.num: link for link in links}
    chosen_set, cables = _read_cables(cables_path, cable_set, len(links), warn)

    if operational_spaces_xml is None:
        candidate = bodies_path.with_name(f"{stem}_operational_spaces.xml")
        ops_path = candidate if candidate.is_file() else None
    else:
        ops_path = Path(operational_spaces_xml).expanduser().resolve()
    op_set, op_spaces = (None, [])
    if ops_path is not None:
        op_set, op_spaces = _read_operational_spaces(ops_path, operational_set, len(links), warn)
    elif operational_set is not None:
        raise InputError(
            f"operational set {operational_set!r} asked for, but no operational spaces file "
            f"(looked for {bodies_path.with_name(f'{stem}_operational_spaces.xml')})"
        )

    urdf, dofs = _build_urdf(model_name, links, op_spaces)
    out.mkdir(parents=True, exist_ok=True)
    urdf_path = out / f"{model_name}.urdf"
    spec_path = out / f"{model_name}.yaml"
    urdf.write_xml_file(str(urdf_path))

    outputs, sources = _operational_outputs(op_spaces)
    default_outputs = not outputs
    if default_outputs:
        tip = f"link{links[-1].num}_end"
        outputs = [{"name": f"{tip}_{a}", "frame": tip, "component": a} for a in "xyz"]
        sources = [
            f"world {a} of frame {tip} (end point of link {links[-1].num}; no operational "
            "space output)"
            for a in "xyz"
        ]

    description = (
        f"CASPR model {stem}: {len(links)} link(s) "
        f"({', '.join(f'{k.num}: {k.name} [{k.joint_type}]' for k in links)}); "
        f"cable set {chosen_set!r}"
        + (f"; operational set {op_set!r}" if op_set else "")
        + "".join(f"; CASPR {k.replace('_', ' ')}: [{v}]" for k, v in meta.items())
    )
    spec: dict[str, Any] = {
        "description": description,
        "source": (
            f"CASPR model library (darwinlau/CASPR, BSD-3-Clause): {bodies_path.name}, "
            f"{cables_path.name}" + (f", {ops_path.name}" if ops_path else "")
        ),
        "urdf": urdf_path.name,
        "gravity": list(GRAVITY),
        "cables": [
            {
                "name": cable.name,
                "tension": [cable.force_min, cable.force_max],
                "route": [_point_entry(links_by_num, cable, a) for a in cable.attachments],
            }
            for cable in cables
        ],
        "outputs": outputs,
    }

    def write_spec() -> None:
        spec_path.write_text(
            "# Imported from CASPR by cdpm import-caspr; see docs/caspr.md for the mapping.\n"
            + yaml.safe_dump(spec, sort_keys=False, default_flow_style=None, width=100),
            encoding="utf-8",
        )

    write_spec()

    robot = load_robot(spec_path)
    dof_of_joint = {d.joint_name: d for d in dofs}
    # cdpm coordinates (tangent order) <- CASPR coordinates
    order = [dof_of_joint[n] for n in robot.coordinate_names]
    lower = np.array([d.link.q_min[d.index] for d in order])
    upper = np.array([d.link.q_max[d.index] for d in order])
    initial = np.array([d.link.q_initial[d.index] for d in order])
    pose_name, natural = _choose_pose(robot, initial, lower, upper, seed, warn)

    if default_outputs:
        keep = _moving_components(robot, lower, upper, seed)
        spec["outputs"] = [o for o, k in zip(outputs, keep, strict=True) if k]
        sources = [s for s, k in zip(sources, keep, strict=True) if k]
        warn(
            f"{bodies_path}: no operational space outputs; outputs are the world "
            f"{''.join(o['component'] for o in spec['outputs']) or '(none)'} coordinates of "
            f"the end point of link {links[-1].num} ({links[-1].name!r})"
        )
    spec["poses"] = {
        pose_name: {d.joint_name: float(v) for d, v in zip(order, natural, strict=True)}
    }
    write_spec()
    robot = load_robot(spec_path)
    deficit = _output_rank_deficit(robot, natural, lower, upper, seed, links)
    if deficit:
        warn(f"{spec_path}: {deficit}")
    singular = _singular_mass_matrix(robot, natural, pose_name, links)
    if singular:
        warn(f"{bodies_path}: {singular}")

    coordinates = tuple(
        f"{d.joint_name} <- link {d.link.num} {d.link.name!r} ({d.link.joint_type}) q[{d.index}]"
        for d in order
    )
    return CasprImport(
        name=model_name,
        urdf_path=urdf_path,
        spec_path=spec_path,
        cable_set=chosen_set,
        operational_set=op_set,
        n_links=len(links),
        cable_names=robot.cable_names,
        output_names=robot.output_names,
        coordinates=coordinates,
        caspr_coordinates=tuple((d.link.num, d.index) for d in order),
        pose_name=pose_name,
        pose=natural,
        warnings=tuple(collected),
        output_units=robot.output_units,
        output_sources=tuple(sources),
    )


def _operational_outputs(op_spaces: list[_OpSpace]) -> tuple[list[dict], list[str]]:
    """Spec output entries of the operational spaces, and what each one is.

    A position component ``c`` of operational space ``name`` is the world
    coordinate ``c`` of frame ``op_<name>`` (the operational point), output
    ``<name>_c`` [m]; an orientation component ``rc`` is the world component
    of link k's rotation vector, output ``<name>_rc`` [rad].
    """
    outputs: list[dict] = []
    sources: list[str] = []
    for op, slug in zip(op_spaces, _op_slugs(op_spaces), strict=True):
        for component, letter in zip(op.components, op.letters, strict=True):
            origin = f"CASPR <{op.tag}> {op.name!r} axis {letter!r}"
            if component.startswith("r"):
                frame = f"link{op.link}"
                what = f"world {component[1]} component of the rotation vector of frame {frame}"
            else:
                frame = f"op_{slug}"
                what = f"world {component} of frame {frame}"
            outputs.append({"name": f"{slug}_{component}", "frame": frame, "component": component})
            sources.append(f"{what} ({origin})")
    return outputs, sources
