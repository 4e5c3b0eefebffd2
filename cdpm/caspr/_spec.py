"""The cable spec side of a CASPR import: cable routes, the named pose, outputs.

Turns CASPR attachment points into spec route points, chooses the pose to
write (CASPR's ``q_initial`` or a sampled one) and checks the outputs on the
robot that :func:`cdpm.load_robot` builds from the written files.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cdpm.caspr._xml import _Attachment, _Cable, _Link
from cdpm.dynamics.linearisation import mass_inverse
from cdpm.errors import ModelError
from cdpm.numerics import (
    CASPR_LIMIT_TOL,
    CASPR_MIN_SEGMENT,
    CASPR_MOVING_OUTPUT_ATOL,
    CASPR_NULL_MOTION_RTOL,
    CASPR_OUTPUT_RANK_RTOL,
)

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

#: CASPR's gravity vector [m/s^2] (``SystemModel.GRAVITY_CONSTANT`` along -z).
GRAVITY = (0.0, 0.0, -9.81)


def _point_entry(links_by_num: dict[int, _Link], cable: _Cable, att: _Attachment) -> dict:
    loc = [float(x) for x in att.location]
    if att.link == 0:
        return {"frame": "base", "point": loc}
    frame = f"link{att.link}"
    if cable.reference == "com":
        if links_by_num[att.link].mass > 0:
            return {"frame": frame, "point": loc, "relative_to": "com"}
        # cdpm's relative_to: com needs a link with mass; shift by hand
        loc = [float(x) for x in att.location + links_by_num[att.link].com]
    return {"frame": frame, "point": loc}


def _outside_limits(robot: CableRobot, natural: np.ndarray, lower, upper) -> list[str]:
    return [
        f"{n}={v:g} not in [{lo:g}, {hi:g}]"
        for n, v, lo, hi in zip(robot.coordinate_names, natural, lower, upper, strict=True)
        if not lo - CASPR_LIMIT_TOL <= v <= hi + CASPR_LIMIT_TOL
    ]


def _pose_problem(robot: CableRobot, natural: np.ndarray) -> str | None:
    """Why a pose has degenerate cables (a zero-length segment), or None."""
    try:
        kin = robot.kinematics(robot.from_natural(natural))
    except ModelError as exc:
        return str(exc)
    if kin.segment_lengths.size and kin.segment_lengths.min() < CASPR_MIN_SEGMENT:
        k = int(np.argmin(kin.segment_lengths))
        return (
            f"cable {robot.cable_names[kin.segment_cable[k]]!r} has a segment of length "
            f"{kin.segment_lengths[k]:.3g} m"
        )
    return None


def _sample(rng, lower, upper) -> np.ndarray:
    lo = np.where(np.isfinite(lower), lower, -1.0)
    hi = np.where(np.isfinite(upper), upper, 1.0)
    return rng.uniform(lo, hi)


def _choose_pose(robot: CableRobot, initial, lower, upper, seed, warn) -> tuple[str, np.ndarray]:
    """CASPR's q_initial when its cables are non-degenerate, else a sampled pose."""
    problem = _pose_problem(robot, initial)
    if problem is None:
        outside = _outside_limits(robot, initial, lower, upper)
        if outside:
            warn(
                f"CASPR q_initial lies outside the joint limits ({'; '.join(outside)}); "
                "kept as pose 'initial' as CASPR uses it"
            )
        return "initial", initial
    rng = np.random.default_rng(seed)
    for _ in range(500):
        candidate = _sample(rng, lower, upper)
        if _pose_problem(robot, candidate) is None:
            warn(
                f"CASPR q_initial {initial.tolist()} is not usable ({problem}); wrote pose "
                f"'sampled' (seed {seed}) instead"
            )
            return "sampled", candidate
    raise ModelError(
        f"CASPR q_initial is not usable ({problem}) and no pose within the joint limits "
        "with non-degenerate cables was found in 500 samples; check the model"
    )


def _output_jacobians(robot: CableRobot, lower, upper, seed, extra=()) -> list[np.ndarray]:
    """Output Jacobians (p, nv) at a few poses sampled within the limits
    (and at the natural coordinates ``extra``)."""
    rng = np.random.default_rng(seed)
    poses = [_sample(rng, lower, upper) for _ in range(5)] + list(extra)
    jacobians = []
    for natural in poses:
        try:
            jacobians.append(robot.output_jacobian(robot.from_natural(natural)))
        except ModelError:
            continue
    return jacobians


def _moving_components(robot: CableRobot, lower, upper, seed) -> list[bool]:
    """Which outputs have a nonzero Jacobian row at some of a few sampled poses."""
    moving = np.zeros(robot.n_outputs, dtype=bool)
    for jac in _output_jacobians(robot, lower, upper, seed):
        moving |= np.linalg.norm(jac, axis=1) > CASPR_MOVING_OUTPUT_ATOL
    return moving.tolist()


def _rank(matrix: np.ndarray) -> int:
    s = np.linalg.svd(matrix, compute_uv=False)
    return int(
        np.count_nonzero(s > CASPR_OUTPUT_RANK_RTOL * max(1.0, float(s[0]) if s.size else 0.0))
    )


#: CASPR joints that turn a link about a fixed point (three rotations).
_SPHERICAL_JOINTS = ("S_EULER_XYZ", "S_FIXED_XYZ")


def _output_rank_deficit(robot: CableRobot, natural, lower, upper, seed, links) -> str | None:
    """Why the outputs can never be output controllable, or None.

    With fewer independent output directions than outputs at every pose
    (rank of the output Jacobian < p), rank C [B AB ...] < p everywhere, so
    output controllability and POC are NO at every pose whatever the cables.
    """
    p = robot.n_outputs
    jacobians = _output_jacobians(robot, lower, upper, seed, extra=[natural])
    if not jacobians or p == 0:
        return None
    rank = max(_rank(jac) for jac in jacobians)
    if rank >= p:
        return None
    # a subset of `rank` outputs that the joints do move independently
    best = max(jacobians, key=_rank)
    keep: list[int] = []
    for i in range(p):
        if _rank(best[keep + [i]]) > len(keep):
            keep.append(i)
    names = robot.output_names
    why = "the joints cannot move them independently"
    if p > robot.nv:
        why += f" (the model has only {robot.nv} coordinate(s))"
    spherical = [k.name for k in links if k.joint_type in _SPHERICAL_JOINTS]
    if spherical and not all(o.has_rotation for o in robot.spec.outputs):
        why += (
            f" (link {spherical[0]!r} turns about a spherical joint: a point on it moves on a "
            "sphere and never along its radius)"
        )
    return (
        f"the {p} outputs ({', '.join(names)}) span only {rank} direction(s) at every sampled "
        f"pose: {why}. So output controllability fails and positive output controllability "
        f"is NO at every pose. Keep {rank} output(s) that move independently in the spec's "
        f"outputs (e.g. {', '.join(names[i] for i in keep)}), or give an operational space "
        f"(<name>_operational_spaces.xml) with at most {rank} independent components"
    )


def _axis_words(axis: np.ndarray) -> tuple[str, str]:
    """(``"its z axis"``, ``"Izz"``) for a unit axis along a link axis, else
    (``"the axis (0.6, 0.8, 0) of its frame"``, "")."""
    k = int(np.argmax(np.abs(axis)))
    if abs(axis[k]) > 1.0 - CASPR_NULL_MOTION_RTOL:
        letter = "xyz"[k]
        return f"its {letter} axis", f"I{letter}{letter}"
    return f"the axis ({', '.join(f'{a:.3g}' for a in axis + 0.0)}) of its frame", ""


def _singular_mass_matrix(robot: CableRobot, natural, pose_name: str, links) -> str | None:
    """Why the mass matrix is singular at the written pose (bodies that move
    with its null motion without inertia against it), or None when it is
    regular there (:func:`cdpm.dynamics.linearisation.mass_inverse`, the
    pipeline's rule).

    A body with a zero principal moment of inertia is harmless unless the
    joints turn it about that axis with nothing else moving: then M q' = 0
    for that q', M is singular and no pose where that happens can be
    analysed (the pipeline flags it ``singular_mass_matrix``).
    """
    # pinocchio: loaded on first use
    import pinocchio as pin

    q = robot.from_natural(natural)
    mass_matrix = robot.mass_matrix(q)
    if mass_inverse(mass_matrix[None])[1][0]:
        return None
    motion = np.linalg.eigh(mass_matrix)[1][:, 0]  # unit q' with M q' ~ 0
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q, motion)
    speeds = []
    for link in links:
        frame = model.getFrameId(f"link{link.num}")
        velocity = pin.getFrameVelocity(model, data, frame, pin.LOCAL)  # in link axes
        turn = np.array(velocity.angular)
        com_speed = float(np.linalg.norm(velocity.linear + np.cross(turn, link.com)))
        speeds.append((link, turn, max(float(np.linalg.norm(turn)), com_speed / robot.size)))
    fastest = max((s for _l, _t, s in speeds), default=0.0)
    parts, fixes = [], []
    for link, turn, speed in speeds:
        if speed <= CASPR_NULL_MOTION_RTOL * fastest:
            continue
        moments = np.linalg.eigvalsh(link.inertia_com)
        listed = ", ".join(f"{m + 0.0:.3g}" for m in moments)
        who = f"link {link.num} {link.name!r}"
        if link.mass == 0 and not moments.any():
            parts.append(f"{who} moves with no mass or inertia")
            fixes.append(f"{who} a mass and inertia")
            continue
        axis, entry = _axis_words(turn / np.linalg.norm(turn))
        parts.append(
            f"{who} turns about {axis} with no inertia about it (principal moments {listed} "
            "kg m^2 about its centre of mass)"
        )
        fixes.append(
            f"{who} inertia about {axis}"
            + (f" (a nonzero {entry} in its <inertia>)" if entry else "")
        )
    what = "; ".join(parts) or "a joint motion moves no body with mass"
    fix = " or ".join(fixes) or "the bodies mass and inertia"
    return (
        f"the mass matrix is singular at pose {pose_name!r}: {what}. Nothing resists that "
        "motion, so cdpm cannot analyse this pose, nor any other where it happens (they are "
        f"reported as having a singular mass matrix). To analyse them, give {fix}"
    )
