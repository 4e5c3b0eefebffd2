"""Enclosures of a robot's kinematics over boxes of poses (cdpm.certify):
at random poses of random boxes, what the robot computes (points, their
Jacobians, L, outputs, C_q, M, joint placements) lies in the enclosures,
in both forms; enclosures shrink with the box and are round-off wide on a
point; unsupported joints are refused by name.
"""

from __future__ import annotations

import textwrap
import zlib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import cdpm
from cdpm.certify import box_kinematics
from cdpm.certify.kinematics import FORMS

MODELS = Path(__file__).resolve().parents[1] / "models"
SHIPPED = ["two_link_planar", "two_link_vertical", "multilink_arm"]
WIDTHS = [1e-6, 1e-3, 0.1, 1.0]
N_POSES = 200

# a chain with an unaligned revolute axis, a prismatic joint, rotated joint
# origins, off-diagonal inertias, a fixed tip frame and every output kind
ODD_URDF = """\
<robot name="odd">
  <link name="base"/>
  <link name="link1">
    <inertial><origin xyz="0.1 0.02 0" rpy="0 0 0"/><mass value="1.0"/>
      <inertia ixx="0.02" ixy="0.003" ixz="-0.001" iyy="0.03" iyz="0.002" izz="0.025"/>
    </inertial>
  </link>
  <link name="link2">
    <inertial><origin xyz="0.05 0 0.01" rpy="0.3 0 0"/><mass value="0.5"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.012" iyz="0" izz="0.008"/>
    </inertial>
  </link>
  <link name="link3">
    <inertial><origin xyz="0.12 0 0" rpy="0 0 0"/><mass value="0.7"/>
      <inertia ixx="0.004" ixy="0.001" ixz="0" iyy="0.02" iyz="0" izz="0.02"/>
    </inertial>
  </link>
  <link name="tip"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="link1"/>
    <origin xyz="0 0 0.1" rpy="0.1 0.2 0.3"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-3.2" upper="3.2" effort="10" velocity="10"/>
  </joint>
  <joint name="j2" type="prismatic">
    <parent link="link1"/><child link="link2"/>
    <origin xyz="0.3 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-0.5" upper="0.5" effort="10" velocity="10"/>
  </joint>
  <joint name="j3" type="revolute">
    <parent link="link2"/><child link="link3"/>
    <origin xyz="0.2 0 0" rpy="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-3.2" upper="3.2" effort="10" velocity="10"/>
  </joint>
  <joint name="tip_joint" type="fixed">
    <parent link="link3"/><child link="tip"/><origin xyz="0.25 0 0.05" rpy="0 0 0"/>
  </joint>
</robot>
"""

ODD_SPEC = """\
urdf: odd.urdf
gravity: [0, 0, -9.81]
cables:
  - name: c1
    route: [{frame: base, point: [0.5, 0.5, 0]}, {frame: link1, point: [0.1, 0, 0]}]
  - name: c2
    route:
      - {frame: base, point: [-0.5, 0.5, 0.3]}
      - {frame: link2, point: [0.05, 0, 0]}
      - {frame: tip, point: [0, 0, 0]}
  - name: c3
    route: [{frame: base, point: [0, -0.5, 0]}, {frame: link3, point: [0.1, 0.02, 0]}]
outputs:
  - {name: tip_x, frame: tip, component: x}
  - {name: tip_rz, frame: tip, component: rz}
  - {name: slide, joint: j2}
  - {name: c2_length, cable: c2}
  - name: mix
    sum:
      - {weight: 0.5, frame: link2, component: y, point: [0.01, 0.02, 0.03]}
      - {weight: -2, joint: j1}
"""


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    out = {name: cdpm.load_robot(MODELS / name) for name in SHIPPED}
    folder = tmp_path_factory.mktemp("odd")
    (folder / "odd.urdf").write_text(ODD_URDF)
    (folder / "odd.yaml").write_text(ODD_SPEC)
    out["odd"] = cdpm.load_robot(folder / "odd.yaml")
    return out


def random_box(rng, robot, width):
    centre = rng.uniform(-2.5, 2.5, robot.nv)
    if robot.spec.path.stem == "odd":
        centre[1] = rng.uniform(-0.3, 0.3)  # the slide: keep the cables apart
    return centre - width / 2, centre + width / 2


def enclosed(bk, robot, qs):
    """Which of the robot's values at poses qs (N, nv) lie in the box's
    enclosures: a dict name -> bool."""
    kin = robot.kinematics_batch(qs, dynamics=True)
    n_route = bk.point_positions.shape[0]
    found = {
        "points": bk.point_positions.contains(kin.point_positions[:, :n_route]).all(),
        "point jacobians": bk.point_jacobians.contains(kin.point_jacobians[:, :n_route]).all(),
        "lengths": bk.lengths.contains(kin.lengths).all(),
        "L": bk.jacobian.contains(kin.jacobian).all(),
        "segment lengths": bk.segment_lengths.contains(kin.segment_lengths).all(),
        "outputs": bk.output.contains(kin.output).all(),
        "C_q": bk.output_jacobian.contains(kin.output_jacobian).all(),
        "M": bk.mass_matrix.contains(kin.mass_matrix).all(),
    }
    data = robot.model.createData()
    placements = True
    for q in qs[:20]:
        pin.forwardKinematics(robot.model, data, q)
        for j in range(robot.model.njoints):
            placements &= bool(bk.joint_rotation[j].contains(data.oMi[j].rotation).all())
            placements &= bool(bk.joint_translation[j].contains(data.oMi[j].translation).all())
    found["joint placements"] = placements
    return found


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("name", [*SHIPPED, "odd"])
def test_every_pose_of_a_box_lies_in_its_enclosures(robots, name, form):
    robot = robots[name]
    rng = np.random.default_rng(zlib.crc32(f"{name} {form}".encode()))
    for width in WIDTHS:
        for _ in range(2):
            lower, upper = random_box(rng, robot, width)
            bk = box_kinematics(robot, lower, upper, form=form)
            qs = rng.uniform(lower, upper, (N_POSES, robot.nv))
            qs[:2] = lower, upper  # corners too
            found = enclosed(bk, robot, qs)
            assert all(found.values()), (name, form, width, found)


def _widest(bk):
    return {
        "points": bk.point_positions.width.max(),
        "L": bk.jacobian.width.max(),
        "C_q": bk.output_jacobian.width.max(),
        "M": bk.mass_matrix.width.max(),
    }


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("name", SHIPPED)
def test_enclosures_shrink_with_the_box(robots, name, form):
    robot = robots[name]
    centre = np.random.default_rng(7).uniform(-2, 2, robot.nv)
    wide = _widest(box_kinematics(robot, centre - 0.05, centre + 0.05, form=form))
    tiny = _widest(box_kinematics(robot, centre - 5e-7, centre + 5e-7, form=form))
    for key in wide:
        assert tiny[key] < 1e-4 * wide[key], (key, tiny[key], wide[key])


def test_the_mean_value_form_is_tighter_on_small_boxes(robots):
    robot = robots["multilink_arm"]
    centre = np.random.default_rng(8).uniform(-2, 2, robot.nv)
    naive = _widest(box_kinematics(robot, centre - 5e-4, centre + 5e-4))
    mv = _widest(box_kinematics(robot, centre - 5e-4, centre + 5e-4, form="mean_value"))
    assert mv["L"] < 0.2 * naive["L"]
    assert all(mv[k] <= naive[k] for k in naive)


@pytest.mark.parametrize("name", [*SHIPPED, "odd"])
def test_a_point_box_is_round_off_wide_around_the_robot_value(robots, name):
    robot = robots[name]
    q = np.random.default_rng(9).uniform(-1, 1, robot.nv)
    bk = box_kinematics(robot, q, q)
    kin = robot.kinematics_batch(q[None, :], dynamics=True)
    pairs = [
        (bk.jacobian, kin.jacobian[0]),
        (bk.output_jacobian, kin.output_jacobian[0]),
        (bk.mass_matrix, kin.mass_matrix[0]),
        (bk.lengths, kin.lengths[0]),
    ]
    if name != "odd":  # the odd model's tip_rz is only known within [-pi, pi]
        pairs.append((bk.output, kin.output[0]))
    for enclosure, value in pairs:
        assert enclosure.contains(value).all()
        scale = max(1.0, float(np.abs(value).max()))
        assert enclosure.width.max() <= 1e-12 * scale


def test_boxes_in_a_batch_get_their_own_enclosures(robots):
    robot = robots["two_link_planar"]
    rng = np.random.default_rng(10)
    lower = rng.uniform(-3, 3, (5, 2))
    upper = lower + rng.uniform(0, 0.2, (5, 2))
    batch = box_kinematics(robot, lower, upper, form="mean_value")
    assert batch.jacobian.shape == (5, 4, 2) and batch.mass_matrix.shape == (5, 2, 2)
    assert str(batch).startswith("BoxKinematics (mean_value, 5 boxes): widest enclosure of L ")
    for k in range(5):
        one = box_kinematics(robot, lower[k], upper[k], form="mean_value")
        np.testing.assert_array_equal(one.jacobian.lo, batch.jacobian.lo[k])
        np.testing.assert_array_equal(one.mass_matrix.hi, batch.mass_matrix.hi[k])


@pytest.mark.parametrize("name", ["spatial_8cable", "mixed"])
def test_a_free_flyers_boxes_hold_every_pose(tmp_path, name):
    """Free-flyer joints: natural coordinates x, y, z, roll, pitch, yaw;
    their degrees of freedom along and about the body's own axes (Pinocchio's
    local velocities). Every pose of a box, mapped to Pinocchio's
    configuration, has its L, C_q, M, G, lengths and outputs inside the
    enclosures (the platform alone, and a free-flyer carrying an unaligned
    prismatic and revolute joint)."""
    from tests.test_maps import MIXED_SPEC, MIXED_URDF

    if name == "mixed":
        (tmp_path / "mixed.urdf").write_text(MIXED_URDF)
        (tmp_path / "mixed.yaml").write_text(MIXED_SPEC.format(gravity="[0, 0, -9.81]"))
        robot = cdpm.load_robot(tmp_path / "mixed.yaml")
        centre = np.array([0.1, -0.2, 0.3, 0.2, -0.3, 0.4, 0.2, 0.5])
    else:
        robot = cdpm.load_robot(MODELS / "spatial_8cable")
        centre = np.asarray(robot.to_natural(robot.poses["offset"]), dtype=float)
    rng = np.random.default_rng(3)
    for width in (1e-6, 0.01, 0.1):
        c = centre + rng.uniform(-0.1, 0.1, robot.nv)
        for form in FORMS:
            bk = box_kinematics(robot, c - width, c + width, form)
            qs = rng.uniform(c - width, c + width, (40, robot.nv))
            kin = robot.kinematics_batch(
                np.array([robot.from_natural(x) for x in qs]), dynamics=True
            )
            for field in ("jacobian", "output_jacobian", "mass_matrix", "gravity", "lengths"):
                assert getattr(bk, field).contains(getattr(kin, field)).all(), (name, width, field)
            assert bk.output.contains(kin.output).all(), (name, width)
    # a point box is round-off wide
    tight = box_kinematics(robot, c, c, "naive")
    assert float(np.max(tight.jacobian.width)) < 1e-9


def test_a_continuous_joint_is_refused_by_name(tmp_path):
    urdf = ODD_URDF.replace('name="j3" type="revolute"', 'name="j3" type="continuous"')
    (tmp_path / "odd.urdf").write_text(urdf)
    (tmp_path / "odd.yaml").write_text(ODD_SPEC)
    robot = cdpm.load_robot(tmp_path / "odd.yaml")
    with pytest.raises(cdpm.InputError, match=r"joint 'j3' \(RUBY\) is not supported"):
        box_kinematics(robot, np.zeros(3), np.ones(3))


@pytest.mark.parametrize(
    ("lower", "upper", "message"),
    [
        ([0.2, 0.0], [0.1, 1.0], r"lower > upper for coordinate 'q1' \(0.2 > 0.1\); swap them"),
        ([0.0], [1.0], r"lower has shape \(1,\), expected \(2,\) or \(B, 2\)"),
        ([0.0, np.nan], [1.0, 1.0], "not finite numbers of at most 100000"),
        ([0.0, -1e6], [1.0, 1.0], "not finite numbers of at most 100000"),
        (["a", 0.0], [1.0, 1.0], "lower must be numbers"),
    ],
)
def test_bad_boxes_are_clear_errors(robots, lower, upper, message):
    with pytest.raises(cdpm.InputError, match=message):
        box_kinematics(robots["two_link_planar"], lower, upper)


def test_an_unknown_form_is_a_clear_error(robots):
    with pytest.raises(cdpm.InputError, match="form must be one of naive, mean_value"):
        box_kinematics(robots["two_link_planar"], [0, 0], [1, 1], form="taylor")


def test_the_odd_model_has_the_joints_it_claims(robots):
    """The model above exercises what it says: an unaligned revolute axis,
    a prismatic joint and a revolute one about y."""
    model = robots["odd"].model
    kinds = [model.joints[j].shortname() for j in range(1, model.njoints)]
    assert kinds == ["JointModelRevoluteUnaligned", "JointModelPX", "JointModelRY"]
    assert textwrap.dedent(ODD_SPEC).count("- name:") == 4


def _prismatic_root(tmp_path):
    """The odd chain with its first joint made prismatic (along an unaligned axis)."""
    urdf = ODD_URDF.replace(
        '<joint name="j1" type="revolute">', '<joint name="j1" type="prismatic">'
    )
    urdf = urdf.replace(
        '<axis xyz="0 0.6 0.8"/>\n    <limit lower="-3.2" upper="3.2"',
        '<axis xyz="0 0.6 0.8"/>\n    <limit lower="-0.4" upper="0.4"',
    )
    (tmp_path / "odd.urdf").write_text(urdf)
    (tmp_path / "odd.yaml").write_text(ODD_SPEC)
    return cdpm.load_robot(tmp_path / "odd.yaml")


@pytest.mark.parametrize("name", [*SHIPPED, "odd", "odd_prismatic_root"])
def test_the_root_frame_jets_hold_every_value_and_derivative(robots, tmp_path, name):
    """box_jets evaluates the chain in the frame of the joint carrying every
    body: its values (L, lengths, outputs, C_q, M) and derivatives must still
    hold the robot's at every pose of the box (derivatives against central
    differences, within their error)."""
    from cdpm.certify.kinematics import box_jets

    robot = _prismatic_root(tmp_path) if name == "odd_prismatic_root" else robots[name]
    rng = np.random.default_rng(7)
    keys = {
        "lengths": "lengths",
        "jacobian": "jacobian",
        "output_jacobian": "output_jacobian",
        "mass_matrix": "mass_matrix",
        "output": "output",
    }
    for width in (1e-3, 0.05):
        lo, hi = random_box(rng, robot, width)
        if name == "odd_prismatic_root":
            lo[0], hi[0] = -0.1, -0.1 + width
            lo[1], hi[1] = 0.0, width
        centre_vals, over_box, _ = box_jets(robot, lo, hi)
        qs = rng.uniform(lo, hi, (40, robot.nv))
        kin = robot.kinematics_batch(qs, dynamics=True)
        centre = robot.kinematics_batch(((lo + hi) / 2)[None], dynamics=True)
        step = 1e-6
        for key, attr in keys.items():
            jet = over_box[key]
            val = jet.val if hasattr(jet, "val") else jet
            got = getattr(kin, attr)
            assert val[0].contains(got).all(), (name, key, width)
            assert centre_vals[key][0].contains(getattr(centre, attr)[0]).all(), (name, key)
            # (a rotation output's value is only bounded by [-pi, pi]: its
            # derivative is C_q's row, checked there)
            if not hasattr(jet, "grad") or key == "output":
                continue
            for k in range(robot.nv):
                e = np.zeros(robot.nv)
                e[k] = step
                plus = getattr(robot.kinematics_batch(qs + e, dynamics=True), attr)
                minus = getattr(robot.kinematics_batch(qs - e, dynamics=True), attr)
                fd = (plus - minus) / (2 * step)
                g = jet.grad[0][..., k]
                slack = 1e-5 * (1 + np.abs(fd))
                inside = (fd >= g.lo - slack) & (fd <= g.hi + slack)
                # poses within a step of the box's faces: the difference reaches outside
                assert inside.all(), (name, key, width, k)
