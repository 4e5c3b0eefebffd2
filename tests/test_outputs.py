"""Outputs beyond point positions (docs/outputs.md): orientation, joint and
cable-length outputs and weighted sums, against finite differences and
Pinocchio at seeded random poses; their spec validation; their units in
maps, reports and the reach margin; the full-pose spec of spatial_8cable."""

from __future__ import annotations

import math
import re
import shutil

import numpy as np
import pinocchio as pin
import pytest

import cdpm
from cdpm.dynamics.equilibrium import equilibrium_tension
from cdpm.dynamics.linearisation import output_jacobian_rounded
from cdpm.dynamics.reach import reach_scale, reach_settings, reach_unit
from cdpm.verdicts import VERDICT_CODES
from tests.conftest import MODELS

SEED = 20261124
N_POSES = 6
#: central-difference step in the tangent space [rad or m]
FD_STEP = 1e-6
#: acceptance: analytic output Jacobian rows within this of central differences
FD_TOL = 1e-6
#: spread of the random poses about each model's first named pose
SPREAD = 0.8

POSE_SPEC = MODELS / "spatial_8cable" / "spatial_8cable_pose.yaml"
ARM = MODELS / "multilink_arm"
VERTICAL = MODELS / "two_link_vertical"


def with_outputs(tmp_path, folder, outputs: str, name: str = "spec.yaml"):
    """A copy of the model in ``folder`` (its YAML and URDF) in ``tmp_path``
    with its outputs replaced by ``outputs`` (YAML list items)."""
    model = folder.name
    shutil.copy(folder / f"{model}.urdf", tmp_path / f"{model}.urdf")
    text = (folder / f"{model}.yaml").read_text()
    text, n = re.subn(r"outputs:\n(?:  - .*\n)+", "outputs:\n" + outputs, text)
    assert n == 1
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def arm_rotations(tmp_path_factory):
    """multilink_arm with rx, ry, rz of its hand and forearm frames."""
    items = "".join(
        f"  - {{name: {frame}_{c}, frame: {frame}, component: {c}}}\n"
        for frame in ("hand", "forearm")
        for c in ("rx", "ry", "rz")
    )
    return cdpm.load_robot(with_outputs(tmp_path_factory.mktemp("arm"), ARM, items))


@pytest.fixture(scope="module")
def pose_robot():
    return cdpm.load_robot(POSE_SPEC)


def random_poses(robot, n: int = N_POSES, seed: int = SEED, feasible: bool = False):
    """n configurations about the first named pose (seeded); with
    ``feasible``, only poses with a min-norm equilibrium (so that they can
    be linearised)."""
    rng = np.random.default_rng(seed)
    centre = next(iter(robot.poses.values()))
    poses = []
    for _ in range(100 * n):
        q = pin.integrate(robot.model, centre, rng.uniform(-SPREAD, SPREAD, robot.nv))
        if not feasible or equilibrium_tension(robot, q, method="min_norm").feasible:
            poses.append(q)
        if len(poses) == n:
            return poses
    raise AssertionError(f"only {len(poses)} poses found")


def frame_rotation(robot, q, frame: str) -> np.ndarray:
    """World rotation of ``frame`` at q, (3, 3), by Pinocchio."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.model.getFrameId(frame)].rotation.copy()


def fd_rotation_rows(robot, q, frame: str, h: float = FD_STEP) -> np.ndarray:
    """Central differences of log3(R(q + dq) R(q)^T) over the tangent
    directions dq = +-h e_i, (3, nv)."""
    R = frame_rotation(robot, q, frame)
    cols = []
    for i in range(robot.nv):
        step = np.zeros(robot.nv)
        step[i] = h
        plus = frame_rotation(robot, pin.integrate(robot.model, q, step), frame)
        minus = frame_rotation(robot, pin.integrate(robot.model, q, -step), frame)
        cols.append((pin.log3(plus @ R.T) - pin.log3(minus @ R.T)) / (2 * h))
    return np.array(cols).T


def fd_output_rows(robot, q, h: float = FD_STEP) -> np.ndarray:
    """Central differences of the output values y(q + dq), (p, nv)."""
    cols = []
    for i in range(robot.nv):
        step = np.zeros(robot.nv)
        step[i] = h
        plus = robot.output(pin.integrate(robot.model, q, step))
        minus = robot.output(pin.integrate(robot.model, q, -step))
        cols.append((plus - minus) / (2 * h))
    return np.array(cols).T


def rotation_rows(robot) -> dict[str, np.ndarray]:
    """frame -> indices of its rx, ry, rz outputs, in that order."""
    rows: dict[str, list[int]] = {}
    for k, out in enumerate(robot.spec.outputs):
        if out.has_rotation:
            rows.setdefault(out.frame, []).append(k)
    for frame, ks in rows.items():
        assert [robot.spec.outputs[k].component for k in ks] == ["rx", "ry", "rz"], frame
    return {frame: np.array(ks) for frame, ks in rows.items()}


# ---------------------------------------------------------------- (a), (d)


@pytest.mark.slow
@pytest.mark.parametrize("which", ["spatial_8cable_pose", "multilink_arm"])
def test_orientation_rows_are_finite_differences_of_log3(which, pose_robot, arm_rotations):
    """The C rows of rx, ry, rz (the robot's output Jacobian and the
    linearisation's C[:, :nv]) equal central differences of
    log3(R(q + dq) R(q)^T) to 1e-6 at seeded random poses; the stored value
    is log3(R(q))."""
    robot = pose_robot if which == "spatial_8cable_pose" else arm_rotations
    rows = rotation_rows(robot)
    assert len(rows) == (1 if which == "spatial_8cable_pose" else 2)
    worst = 0.0
    largest_angle = 0.0
    for q in random_poses(robot, feasible=True):
        jac = robot.output_jacobian(q)
        C = cdpm.linearise(robot, q, tension="min_norm").C[:, : robot.nv]
        y = robot.output(q)
        for frame, ks in rows.items():
            fd = fd_rotation_rows(robot, q, frame)
            worst = max(worst, np.abs(jac[ks] - fd).max(), np.abs(C[ks] - fd).max())
            rotvec = pin.log3(frame_rotation(robot, q, frame))
            np.testing.assert_allclose(y[ks], rotvec, atol=1e-12)  # (d)
            largest_angle = max(largest_angle, float(np.linalg.norm(rotvec)))
    assert worst < FD_TOL, worst
    # the poses turn the frames far enough from the identity that the C rows
    # are not the derivative of the stored value (next test)
    assert largest_angle > 0.3


def test_the_stored_value_changes_otherwise_away_from_the_identity(arm_rotations):
    """Away from the identity, d log3(R(q))/dq differs from the angular
    velocity rows: the rows describe the rotation relative to the pose."""
    q = random_poses(arm_rotations, n=1, seed=SEED + 1)[0]
    ks = rotation_rows(arm_rotations)["hand"]
    angle = np.linalg.norm(arm_rotations.output(q)[ks])
    assert angle > 0.3
    stored = fd_output_rows(arm_rotations, q)[ks]
    rows = arm_rotations.output_jacobian(q)[ks]
    assert np.abs(stored - rows).max() > 1e-2 * angle
    # at the identity (the hanging arm, every joint 0) they agree
    q0 = arm_rotations.configuration("hanging")
    np.testing.assert_allclose(
        fd_output_rows(arm_rotations, q0)[ks], arm_rotations.output_jacobian(q0)[ks], atol=1e-8
    )


def test_rotation_vector_angle_is_in_0_pi(pose_robot):
    """A half turn about z: the rotation vector has angle pi (at the
    discontinuity, either sign); just past it, the vector flips."""
    near = pose_robot.configuration({"platform_joint": [0, 0, 1, 0, 0, math.pi - 1e-3]})
    past = pose_robot.configuration({"platform_joint": [0, 0, 1, 0, 0, math.pi + 1e-3]})
    np.testing.assert_allclose(pose_robot.output(near)[3:], [0, 0, math.pi - 1e-3], atol=1e-12)
    np.testing.assert_allclose(pose_robot.output(past)[3:], [0, 0, -(math.pi - 1e-3)], atol=1e-12)
    # the C rows do not jump: the angular velocity is the same
    np.testing.assert_allclose(
        pose_robot.output_jacobian(near)[3:], pose_robot.output_jacobian(past)[3:], atol=3e-3
    )


# ---------------------------------------------------------------- (b), (c)


JOINT_AND_CABLE_OUTPUTS = {
    "multilink_arm": (
        ARM,
        "  - {name: elbow, joint: elbow}\n"
        "  - {name: wrist, joint: wrist_x}\n"
        "  - {name: s1_length, cable: s1}\n"  # routed through two links
        "  - {name: w2_length, cable: w2}\n",
        ["elbow", "wrist_x"],
        ["s1", "w2"],
    ),
    "two_link_vertical": (
        VERTICAL,
        "  - {name: shoulder, joint: q1}\n"
        "  - {name: elbow, joint: q2}\n"
        "  - {name: c1_length, cable: c1}\n"
        "  - {name: c4_length, cable: c4}\n",
        ["q1", "q2"],
        ["c1", "c4"],
    ),
}


@pytest.mark.parametrize("model", list(JOINT_AND_CABLE_OUTPUTS))
def test_joint_and_cable_outputs_against_finite_differences(model, tmp_path):
    folder, items, joints, cables = JOINT_AND_CABLE_OUTPUTS[model]
    robot = cdpm.load_robot(with_outputs(tmp_path, folder, items))
    assert robot.output_units == ("rad", "rad", "m", "m")
    assert robot.output_points.tolist() == [-1] * 4  # nothing to draw at a frame
    cable_index = [robot.cable_names.index(c) for c in cables]
    for q in random_poses(robot):
        y = robot.output(q)
        for k, joint in enumerate(joints):
            jm = robot.model.joints[robot.model.getJointId(joint)]
            assert y[k] == q[jm.idx_q]
        np.testing.assert_allclose(y[2:], robot.cable_lengths(q)[cable_index], rtol=1e-15)
        jac = robot.output_jacobian(q)
        np.testing.assert_allclose(jac, fd_output_rows(robot, q), atol=FD_TOL)
        np.testing.assert_allclose(jac[2:], robot.cable_jacobian(q)[cable_index], rtol=1e-15)
        assert set(np.unique(jac[:2])) == {0.0, 1.0} and (jac[:2] == 1.0).sum() == 2


def test_a_weighted_sum_is_the_weighted_sum_of_its_terms(tmp_path):
    terms = [
        (0.5, "{frame: hand, component: rz}"),
        (-2.0, "{joint: elbow}"),
        (1.5, "{cable: s1}"),
        (0.25, "{frame: forearm, component: x, point: [0.1, 0.02, 0]}"),
        (3.0, "{frame: tip, component: z}"),
    ]
    items = "".join(f"  - {{name: t{k}, {body[1:]}\n" for k, (_, body) in enumerate(terms))
    items += "  - name: total\n    sum:\n" + "".join(
        f"      - {{weight: {w}, {body[1:]}\n" for w, body in terms
    )
    robot = cdpm.load_robot(with_outputs(tmp_path, ARM, items))
    total = robot.spec.outputs[-1]
    assert total.describe() == (
        "0.5 hand.rz - 2 joint elbow + 1.5 cable s1 + 0.25 forearm@[0.1, 0.02, 0.0].x + 3 tip.z"
    )
    assert total.unit == "mixed" and robot.output_units[:-1] == ("rad", "rad", "m", "m", "m")
    weights = np.array([w for w, _ in terms])
    for q in random_poses(robot, seed=SEED + 2):
        y, jac = robot.output(q), robot.output_jacobian(q)
        assert y[-1] == pytest.approx(weights @ y[:-1], abs=1e-14)
        np.testing.assert_allclose(jac[-1], weights @ jac[:-1], atol=1e-14)
        # the terms without a rotation: derivatives of their values
        np.testing.assert_allclose(jac[1:-1], fd_output_rows(robot, q)[1:-1], atol=FD_TOL)
    # a sum marked with a unit keeps it
    unit = with_outputs(
        tmp_path,
        ARM,
        "  - name: lean\n    unit: m\n    sum:\n"
        "      - {weight: 0.5, frame: hand, component: rx}\n"
        "      - {weight: 1, frame: tip, component: x}\n",
        name="unit.yaml",
    )
    assert cdpm.load_robot(unit).output_units == ("m",)


# ---------------------------------------------------------------- (e)


BAD_OUTPUTS = [
    ("{frame: tip, component: rx, point: [1, 0, 0]}", "is the same at every point of it; leave"),
    ("{joint: q9}", r"'q9' is not a joint of the URDF; joints with a coordinate: q1, q2"),
    ("{cable: c9}", r"'c9' is not a cable of this spec; cables: c1"),
    ("{frame: tip, component: x, joint: q1}", "name exactly one of frame .* got frame and joint"),
    ("{name: s, frame: tip, sum: [{frame: tip, component: x}]}", "give either sum or frame"),
    ("{name: s, sum: []}", "expected a non-empty list of weighted components"),
    ("{name: s, sum: [{weight: 0, frame: tip, component: x}]}", "must be finite and nonzero"),
    ("{name: s, sum: [{weight: .nan, frame: tip, component: x}]}", "must be finite and nonzero"),
    ("{frame: tip, component: roll}", r"'roll' is not valid; use one of x, y, z, rx, ry, rz"),
    ("{joint: q1, component: x}", "applies to frame outputs only; leave it out of a joint"),
    ("{joint: q1, unit: m}", r"the unit of a single component is fixed \(rad\)"),
    ("{joint: tip_joint}", "is a fixed joint, which has no coordinate"),
    ("{joint: [q1, q2]}", "expected one joint name"),
]


@pytest.mark.parametrize(("output", "message"), BAD_OUTPUTS)
def test_bad_outputs_are_spec_errors_naming_the_fix(output, message, write_spec):
    spec = write_spec(
        f"""\
        urdf: arm.urdf
        cables:
          - name: c1
            route: [{{frame: base, point: [0, 0.5, 0]}}, {{frame: tip, point: [0, 0, 0]}}]
        outputs:
          - {output}
        """
    )
    with pytest.raises(cdpm.SpecError, match=message):
        cdpm.load_spec(spec)


def test_a_multi_dof_joint_output_is_refused(tmp_path):
    spec = with_outputs(
        tmp_path, MODELS / "spatial_8cable", "  - {name: flyer, joint: platform_joint}\n"
    )
    with pytest.raises(
        cdpm.SpecError,
        match=r"joint 'platform_joint' \(FreeFlyer, 6 degrees of freedom\) is not revolute or "
        r"prismatic; use frame outputs \(x, y, z, rx, ry, rz\)",
    ):
        cdpm.load_spec(spec)


# ---------------------------------------------------------------- units


def test_round_off_floor_is_per_output_row(arm_rotations, tmp_path):
    """Each row is judged against its own scale: |weight| times the
    robot's size for metre terms, times 1 for radian terms."""
    size = arm_rotations.size
    assert abs(size - 1.0) > 0.2  # metres and radians give different floors
    robot = cdpm.load_robot(
        with_outputs(
            tmp_path,
            ARM,
            "  - {name: tip_x, frame: tip, component: x}\n"
            "  - {name: hand_rz, frame: hand, component: rz}\n"
            "  - name: s\n    sum:\n"
            "      - {weight: 0.5, frame: tip, component: x}\n"
            "      - {weight: -2, joint: elbow}\n",
        )
    )
    np.testing.assert_allclose(robot.output_scales, [size, 1.0, 0.5 * size + 2.0], rtol=1e-15)
    entry = 1e-12 * np.array([0.9, 0.9, 0.9])[:, None] * robot.output_scales[:, None]
    jac = np.repeat(entry, robot.nv, axis=1)
    assert not np.any(output_jacobian_rounded(robot, jac))  # all below their floors
    # between the metre row's floor (1e-12 x 0.72 m) and the rotation row's
    # (1e-12 x 1): round-off in the rotation row, kept in the metre row
    between = 1e-12 * (size + 1.0) / 2
    kept = output_jacobian_rounded(robot, np.full((3, robot.nv), between))
    assert kept[0].all() and not kept[1].any() and not kept[2].any()


def test_reach_margin_units_and_scale(pose_robot, arm_rotations):
    assert reach_unit(("m", "m")) == "m" and reach_unit(("rad",)) == "rad"
    assert reach_unit(("m", "rad")) == "m and rad, one to one"
    assert reach_unit(("mixed",)) == "m and rad, one to one"
    assert reach_unit(("rad", "mm", "m")) == "m and rad and mm, one to one"
    # radian outputs: the metre scale divided by the robot's size
    settings = reach_settings(arm_rotations)
    metres = reach_scale(cdpm.load_robot(ARM), settings)
    assert reach_scale(arm_rotations, settings) == pytest.approx(
        metres / arm_rotations.size, rel=1e-15
    )
    # the position-only spec keeps the metre scale exactly
    spatial = cdpm.load_robot(MODELS / "spatial_8cable")
    assert reach_scale(spatial, reach_settings(spatial)) == (
        reach_settings(spatial).tension_budget / 25.0 * reach_settings(spatial).horizon ** 2 / 2
    )


# ---------------------------------------------------------------- (f)


MIXED = (
    "  - {name: tip_x, frame: tip, component: x}\n"
    "  - {name: elbow, joint: q2}\n"
    "  - {name: c1_length, cable: c1}\n"
)
JOINT_AND_CABLE = "  - {name: elbow, joint: q2}\n  - {name: c1_length, cable: c1}\n"


@pytest.mark.parametrize(
    ("items", "units"),
    [(MIXED, ["m", "rad", "m"]), (JOINT_AND_CABLE, ["rad", "m"])],
    ids=["tip_joint_cable", "joint_cable"],
)
def test_a_map_with_mixed_outputs_equals_the_per_pose_api(items, units, tmp_path):
    robot = cdpm.load_robot(with_outputs(tmp_path, VERTICAL, items))
    axes = {"q1": np.linspace(-3.0, 3.0, 5), "q2": np.linspace(-2.5, 2.5, 5)}
    ds = cdpm.workspace_map(robot, axes, workers=1)
    assert ds["y"].attrs["output_units"] == units
    assert ds["reach_margin"].attrs["units"] == "m and rad, one to one"
    assert ds["reach_margin_error"].attrs["units"] == "m and rad, one to one"
    assert ds["output"].values.tolist() == list(robot.output_names)
    codes = {"poc": [], "output_controllable": []}
    for i, q1 in enumerate(axes["q1"]):
        for j, q2 in enumerate(axes["q2"]):
            q = np.array([q1, q2])
            np.testing.assert_allclose(ds["y"].values[i, j], robot.output(q), rtol=1e-14)
            report = cdpm.analyze_pose(robot, q, infeasible="report")
            for name in ("poc", "output_controllable", "positive_controllable", "static_feasible"):
                assert ds[name].values[i, j] == report.criteria[name], (name, q)
            if report.feasible:
                assert ds["poc"].values[i, j] == VERDICT_CODES[report.poc.verdict.name.lower()]
                np.testing.assert_allclose(
                    ds["reach_margin"].values[i, j], report.reach_margin[0], rtol=1e-12
                )
            for name in codes:
                codes[name].append(int(ds[name].values[i, j]))
    if len(units) == 3:  # three outputs of a 2-DOF arm: never output controllable
        assert set(codes["output_controllable"]) <= {0, VERDICT_CODES["not_analysed"]}
        assert VERDICT_CODES["yes"] not in codes["poc"]
        # drawn at the tip, the first output with a frame
        assert ds["output_frame_position"].attrs["frame"] == "tip"
    else:
        assert codes["poc"].count(VERDICT_CODES["yes"]) >= 15  # POC in these two outputs
        # no output has a frame: no frame position, and the attributes say so
        assert np.isnan(ds["output_frame_position"].values).all()
        assert "no output is a position or rotation" in ds["output_frame_position"].attrs["note"]


def test_the_report_prints_units_and_formulas(tmp_path):
    spec = with_outputs(
        tmp_path,
        VERTICAL,
        MIXED + "  - name: mid\n    sum:\n"
        "      - {weight: 0.5, frame: link1, component: x}\n"
        "      - {weight: 0.5, frame: tip, component: x}\n",
    )
    report = cdpm.analyze_pose(cdpm.load_robot(spec), "nominal")
    text = str(report)
    assert (
        "  outputs:     tip_x = 0.866025 m, elbow = 1.0472 rad, c1_length = 0.64296 m, "
        "mid = 0.433013 m\n"
        "  where:       elbow = joint q2; c1_length = cable c1; mid = 0.5 link1.x + 0.5 tip.x\n"
    ) in text
    assert "Reach margin r_T = 0 (m and rad, one to one; exact)" in text
    assert "reach_margin:           0 m and rad, one to one" in text
    plain = report.as_dict()
    assert plain["output_units"] == {"tip_x": "m", "elbow": "rad", "c1_length": "m", "mid": "m"}
    assert plain["reach"]["unit"] == "m and rad, one to one"


# ---------------------------------------------------------------- (g)


def test_the_full_pose_spec_at_its_nominal_pose(pose_robot):
    report = cdpm.analyze_pose(pose_robot, "centre")
    lin = report.linearisation
    assert report.poc.verdict is cdpm.Verdict.YES
    assert report.poc.certificate.verify(lin.A, lin.B_cone, lin.C)
    assert report.reach_unit == "m and rad, one to one"
    value, error = report.reach_margin
    assert value == pytest.approx(0.0886, abs=1e-3) and 0 < error < 1e-3
    # rotations are harder to drive than positions: the position-only spec's
    # margin at the same pose is far larger
    position = cdpm.analyze_pose(cdpm.load_robot(MODELS / "spatial_8cable"), "centre")
    assert position.reach_margin[0] > 10 * value
    # C: the identity on the six pose coordinates at the centred platform
    np.testing.assert_allclose(lin.C[:, :6], np.eye(6), atol=1e-15)
    assert "outputs:     x = 0 m, y = 0 m, z = 1 m, rx = 0 rad, ry = 0 rad, rz = 0 rad" in (
        str(report)
    )


def test_output_frame_position_is_the_first_output_drawn_at_a_frame(tmp_path):
    """A joint output first, then the hand's rz: the map's frame position is
    the hand frame's origin."""
    robot = cdpm.load_robot(
        with_outputs(
            tmp_path,
            ARM,
            "  - {name: elbow, joint: elbow}\n  - {name: hand_rz, frame: hand, component: rz}\n",
        )
    )
    assert robot.output_points[0] == -1 and robot.output_points[1] >= 0
    from cdpm.pipeline.criteria import CRITERIA

    attrs = CRITERIA["output_frame_position"].attrs(robot)
    assert attrs["frame"] == "hand" and attrs["output"] == "hand_rz"
    poses = random_poses(robot, n=3, seed=SEED + 3)
    out = cdpm.evaluate_poses(robot, np.array([robot.to_natural(q) for q in poses]))
    for k, q in enumerate(poses):
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, q)
        hand = data.oMf[robot.model.getFrameId("hand")].translation
        np.testing.assert_allclose(out["output_frame_position"][k], hand, atol=1e-14)
