"""CASPR bodies and joints -> URDF (through yourdfpy's object model).

Every multi-DOF CASPR joint becomes a chain of 1-DOF URDF joints through
massless intermediate links, in the order of :data:`JOINT_CHAINS`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from cdpm.caspr._xml import JOINT_CHAINS, _Link, _OpSpace
from cdpm.errors import MissingExtraError
from cdpm.numerics import CASPR_UNBOUNDED_PRISMATIC

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def _slug(text: str) -> str:
    slug = re.sub(r"[^0-9A-Za-z]+", "_", text).strip("_").lower()
    return slug or "op"


@dataclass
class _Dof:
    joint_name: str
    link: _Link
    index: int  # in the CASPR joint's q
    kind: str


def _build_urdf(name: str, links: list[_Link], op_spaces: list[_OpSpace]):
    """yourdfpy Robot and the 1-DOF joints in chain order.

    Each operational space with position components gets a fixed frame
    ``op_<name>`` on its link at its offset; orientation components use the
    link frame ``link<k>`` itself.
    """
    try:
        # optional: cdpm[caspr]
        import yourdfpy
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingExtraError(
            "importing CASPR models writes the URDF with yourdfpy; install it with "
            "pip install 'cdpm[caspr]'"
        ) from exc

    def transform(xyz) -> np.ndarray:
        t = np.eye(4)
        t[:3, 3] = xyz
        return t

    urdf_links = [yourdfpy.Link(name="base")]
    urdf_joints = []
    dofs: list[_Dof] = []
    for link in links:
        parent = "base" if link.parent == 0 else f"link{link.parent}"
        chain = JOINT_CHAINS[link.joint_type]
        for k, (kind, axis_name, index) in enumerate(chain):
            last = k == len(chain) - 1
            child = f"link{link.num}" if last else f"link{link.num}_{k + 1}"
            suffix = (
                "" if len(chain) == 1 else "_" + ("r" if kind == "revolute" else "") + axis_name
            )
            joint_name = f"joint{link.num}{suffix}"
            axis = link.axis if axis_name == "axis" else _AXES[axis_name]
            lower, upper = link.q_min[index], link.q_max[index]
            if kind == "prismatic":
                lower = max(lower, -CASPR_UNBOUNDED_PRISMATIC)
                upper = min(upper, CASPR_UNBOUNDED_PRISMATIC)
            urdf_joints.append(
                yourdfpy.Joint(
                    name=joint_name,
                    type=kind,
                    parent=parent,
                    child=child,
                    origin=transform(link.parent_location if k == 0 else np.zeros(3)),
                    axis=np.array(axis, dtype=float),
                    limit=yourdfpy.Limit(effort=0.0, velocity=0.0, lower=lower, upper=upper),
                )
            )
            if last:
                urdf_links.append(
                    yourdfpy.Link(
                        name=child,
                        inertial=yourdfpy.Inertial(
                            origin=transform(link.com),
                            mass=float(link.mass),
                            inertia=link.inertia_com.copy(),
                        ),
                    )
                )
            else:
                urdf_links.append(yourdfpy.Link(name=child))
            dofs.append(_Dof(joint_name=joint_name, link=link, index=index, kind=kind))
            parent = child
        urdf_links.append(yourdfpy.Link(name=f"link{link.num}_end"))
        urdf_joints.append(
            yourdfpy.Joint(
                name=f"link{link.num}_end_joint",
                type="fixed",
                parent=f"link{link.num}",
                child=f"link{link.num}_end",
                origin=transform(link.end),
            )
        )
    for op, slug in zip(op_spaces, _op_slugs(op_spaces), strict=True):
        if not op.has_position:
            continue
        frame = f"op_{slug}"
        urdf_links.append(yourdfpy.Link(name=frame))
        urdf_joints.append(
            yourdfpy.Joint(
                name=f"{frame}_joint",
                type="fixed",
                parent=f"link{op.link}",
                child=frame,
                origin=transform(op.offset),
            )
        )
    robot = yourdfpy.Robot(name=name, links=urdf_links, joints=urdf_joints)
    return yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False), dofs


def _op_slugs(op_spaces: list[_OpSpace]) -> list[str]:
    """A distinct name per operational space: the slug of its CASPR name
    (``op_<slug>`` is its point's frame, ``<slug>_<component>`` its outputs)."""
    slugs: list[str] = []
    for op in op_spaces:
        slug = _slug(op.name)
        while slug in slugs:
            slug += "_"
        slugs.append(slug)
    return slugs
