"""The model library: every shipped model loads, says where its numbers
come from, has an equilibrium at its named poses and runs through
``cdpm analyze``; the taut/slack input cone on two_link_vertical, by hand."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

import cdpm
from cdpm.cli import main
from cdpm.dynamics.equilibrium import equilibrium_tension
from cdpm.model.robot import spec_in_folder
from tests.conftest import MODELS, execute_notebook

linearise = cdpm.linearise

G = 9.81
MODEL_SPECS = sorted(MODELS.glob("*/*.yaml"))
NEW_MODELS = ("two_link_vertical", "spatial_8cable", "multilink_arm", "double_pendulum_cables")
#: specs beside a model's own one: the same robot with other outputs
SECOND_SPECS = ("spatial_8cable/spatial_8cable_pose.yaml",)


def load(spec):
    try:
        return cdpm.load_robot(spec)
    except cdpm.SpecError as exc:
        if "not installed" in str(exc):
            pytest.skip(f"needs an optional package: {exc}")
        raise


def test_the_library_ships_the_new_models():
    names = {p.parent.name for p in MODEL_SPECS}
    assert set(NEW_MODELS) <= names
    for spec in MODEL_SPECS:
        # models/<name>/<name>.yaml, or a second spec models/<name>/<name>_*.yaml
        if spec.stem != spec.parent.name:
            assert spec.stem.startswith(spec.parent.name + "_")
            assert f"{spec.parent.name}/{spec.name}" in SECOND_SPECS
        # the folder stands for its own spec, whatever else it holds
        assert spec_in_folder(spec.parent) == spec.parent / f"{spec.parent.name}.yaml"


def test_the_pose_spec_is_the_same_robot_with_the_full_pose_as_output():
    """spatial_8cable_pose.yaml: spatial_8cable.yaml's cables, poses and
    equilibrium, outputs x, y, z, rx, ry, rz of the platform."""
    folder = MODELS / "spatial_8cable"
    assert cdpm.load_robot(folder).spec.path.name == "spatial_8cable.yaml"
    position = yaml.safe_load((folder / "spatial_8cable.yaml").read_text())
    pose = yaml.safe_load((folder / "spatial_8cable_pose.yaml").read_text())
    for key in ("urdf", "gravity", "cables", "poses", "equilibrium", "source"):
        assert pose[key] == position[key], key
    robot = cdpm.load_robot(folder / "spatial_8cable_pose.yaml")
    assert robot.output_names == ("x", "y", "z", "rx", "ry", "rz")
    assert robot.output_units == ("m",) * 3 + ("rad",) * 3
    # at 'offset' (roll 0.05, pitch -0.05, yaw 0.1: R = Rz Ry Rx) the outputs
    # are the rotation vector of R, not the roll-pitch-yaw angles
    from scipy.spatial.transform import Rotation

    y = robot.output("offset")
    np.testing.assert_allclose(y[:3], [0.5, -0.3, 1.2], atol=1e-15)
    rotvec = Rotation.from_euler("xyz", [0.05, -0.05, 0.1]).as_rotvec()
    np.testing.assert_allclose(y[3:], rotvec, atol=1e-14)
    assert abs(y[3] - 0.05) > 2e-3  # 0.05245: not the roll angle


@pytest.mark.parametrize("spec", MODEL_SPECS, ids=lambda p: p.stem)
def test_model_has_source_description_and_feasible_named_poses(spec):
    raw = yaml.safe_load(spec.read_text())
    assert raw.get("source") and raw.get("description")
    robot = load(spec)
    assert robot.poses and robot.n_outputs >= 1
    for name in robot.poses:
        eq = equilibrium_tension(robot, name)
        assert eq.feasible, f"{spec.parent.name} pose {name}: {eq.message}"


@pytest.mark.slow
@pytest.mark.parametrize("spec", MODEL_SPECS, ids=lambda p: p.stem)
def test_cdpm_analyze_runs_on_every_model(spec, capsys):
    robot = load(spec)
    pose = next(iter(robot.poses))
    assert main(["analyze", str(spec), "--pose", pose]) == 0
    out = capsys.readouterr().out
    assert "Equilibrium (" in out and "statics hold" in out
    assert out.index("Equilibrium (") < out.index("Verdicts")
    assert main(["analyze", str(spec), "--pose", pose, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["equilibrium"]["feasible"] is True
    assert len(report["equilibrium"]["cables"]) == robot.n_cables


def test_model_facts():
    spatial = cdpm.load_robot(MODELS / "spatial_8cable")
    assert (spatial.nq, spatial.nv, spatial.n_cables) == (7, 6, 8)
    np.testing.assert_allclose(spatial.mass_matrix("centre")[:3, :3], 25.0 * np.eye(3))
    np.testing.assert_array_equal(spatial.tension_max, 720.0)
    # centred platform: the four upper cables share the weight (by symmetry)
    eq = equilibrium_tension(spatial, "centre")
    up = eq.tension[:4]
    np.testing.assert_allclose(up, up[0], rtol=1e-12)
    # each upper cable: 25 g / 4 = f * (vertical component of its unit
    # vector) = f * 1 / sqrt(1.94^2 + 1.44^2 + 1)
    np.testing.assert_allclose(up[0], 25 * G / 4 * math.hypot(1.94, 1.44, 1.0), rtol=1e-12)
    np.testing.assert_array_equal(eq.tension[4:], 0.0)
    np.testing.assert_allclose(spatial.output("centre"), [0, 0, 1], atol=1e-15)

    arm = cdpm.load_robot(MODELS / "multilink_arm")
    assert (arm.nq, arm.nv, arm.n_cables) == (6, 6, 10)
    segments = np.bincount(arm.kinematics("reach").segment_cable, minlength=arm.n_cables)
    assert segments.tolist() == [2, 1, 2, 1, 1, 1, 2, 1, 1, 1]  # routed through two links
    np.testing.assert_allclose(arm.output("hanging"), [0, 0, -0.7], atol=1e-15)


def test_packaged_urdf_from_example_robot_data():
    pytest.importorskip("cmeel", reason="example-robot-data (pip install 'cdpm[robots]')")
    robot = load(MODELS / "double_pendulum_cables" / "double_pendulum_cables.yaml")
    assert "example-robot-data" in str(robot.spec.urdf_path)
    assert robot.spec.urdf_path.name == "double_pendulum.urdf"
    np.testing.assert_allclose(robot.joint_damping, [0.05, 0.05])


def test_packaged_urdf_string_form_and_missing_package(tmp_path):
    spec = tmp_path / "pendulum.yaml"
    body = """
cables:
  - name: c
    route: [{frame: world, point: [0, 0.1, 0.1]}, {frame: link1, point: [0, 0, 0.05]}]
outputs: [{frame: link2, component: y}]
poses: {up: [0, 0]}
"""
    spec.write_text(
        "urdf: package://example-robot-data/robots/double_pendulum_description/urdf/"
        "double_pendulum.urdf\n" + body
    )
    if cdpm.model.spec.package_share_directory("example-robot-data") is not None:
        assert cdpm.load_robot(spec).nv == 2
    spec.write_text("urdf: {package: no-such-robot-data, path: robots/x.urdf}\n" + body)
    with pytest.raises(cdpm.SpecError, match="package 'no-such-robot-data' is not installed"):
        cdpm.load_spec(spec)
    spec.write_text("urdf: {package: example-robot-data}\n" + body)
    with pytest.raises(cdpm.SpecError, match=r"needs \{package: NAME, path"):
        cdpm.load_spec(spec)


def test_taut_slack_classification_sets_the_input_cone_and_the_verdict():
    """two_link_vertical at q = (0, pi/2): link 1 level, link 2 upright.

    Worked by hand (plane coordinates: x along link 1 at q1 = 0, y up):
    - G = g (1.5 cos q1 + 0.5 cos(q1+q2), 0.5 cos(q1+q2)) = (14.715, 0).
    - c1 runs from A1 = (0, 0.5) to B1 = (0.8, 0.1): l1 = sqrt(0.8),
      u = (2, -1)/sqrt(5), dB1/dq1 = (-0.1, 0.8), so L[c1] = (-1/sqrt(5), 0).
      c1 alone balances G: f1 = 14.715 sqrt(5) = 32.9037 N, and that is the
      least-norm equilibrium: c1 taut (free input), c2, c3, c4 slack (u >= 0).
    - Elbow rows: B2 = (0.9, 0.8), u2 = (0.9, -0.7)/sqrt(1.3), dB2/dq2 =
      (-0.8, -0.1) -> L[c2, q2] = -0.57009; B4 = (1.1, 0.8), u4 = (1.1, 2.3)
      /sqrt(6.5), dB4/dq2 = (-0.8, 0.1) -> L[c4, q2] = -0.25495. Both turn the
      elbow the same way and G has no elbow torque, so no pretension (f >= p
      > 0) can hold this pose.
    - M = [[1.5, 0.25], [0.25, 0.25]], M^-1 = [[0.8, -0.8], [-0.8, 4.8]];
      dG/dq = -4.905 [[1, 1], [1, 1]]; cable stiffness f1 l1'' with
      l1'' = (0.1/2 - 0.2)/sqrt(0.8) = -0.167705 -> H11 = -5.5181.
      K = -M^-1 (dG/dq + H) = [[4.4145, 0], [15.2055, 19.62]].
    - K has eigenvalue 2g = 19.62 (link 2 falling over) with left eigenvector
      w = (1, 1): a sign-definite (sinh) mode. Its input row
      w M^-1 (-L^T) = -4 L[:, q2] = (0, 2.2804, 0, 1.0198): c1 and c3 do not
      reach it, c2 and c4 push it one way only. The output (tip_x, tip_z) is
      the full pose (dh/dq = [[-1, -1], [1, 0]], det 1), so by the modal test
      the pose is NOT positive output controllable - with c1 free (taut)
      as with every cable sign-constrained (the paper's convention).
    - Were c2 taut, it would be a free input whose row entry 2.2804 reaches
      the mode both ways: the cone then contains -b2 and the verdict is YES.
    """
    robot = cdpm.load_robot(MODELS / "two_link_vertical")
    q = [0.0, math.pi / 2]
    lin = linearise(robot, q)
    np.testing.assert_allclose(lin.tension, [14.715 * math.sqrt(5), 0, 0, 0], rtol=1e-12)
    assert lin.sign_constrained.tolist() == [False, True, True, True]
    np.testing.assert_allclose(lin.cable_jacobian[0], [-1 / math.sqrt(5), 0], atol=1e-12)
    np.testing.assert_allclose(lin.cable_jacobian[[1, 3], 1], [-0.57009, -0.25495], atol=1e-5)
    np.testing.assert_allclose(lin.stiffness, [[4.4145, 0], [15.2055, 19.62]], rtol=0, atol=1e-4)
    row = np.array([1.0, 1.0]) @ lin.B[2:]
    np.testing.assert_allclose(row, [0, 2.2804, 0, 1.0198], atol=1e-4)
    assert not equilibrium_tension(robot, q, method="pretension", pretension=1.0).feasible

    slack_cone = cdpm.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
    )
    paper_cone = cdpm.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=np.ones(4, dtype=bool)
    )
    c2_taut = lin.sign_constrained.copy()
    c2_taut[1] = False
    taut_cone = cdpm.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=c2_taut
    )
    assert slack_cone.verdict is cdpm.Verdict.NO
    assert paper_cone.verdict is cdpm.Verdict.NO
    assert taut_cone.verdict is cdpm.Verdict.YES


def test_gravity_changes_the_verdict_at_the_paper_pose(paper_robot):
    """Same arm, same pose (pi/6, pi/3): horizontal (paper, f = 0) versus
    vertical under gravity (c1 taut at 25.49 N). Positive controllability
    (Brammer) fails in the paper's case with witness (0, 0, -2, -1) (Remark
    11); under gravity A is no longer nilpotent and the witness no longer
    is an eigenvector of A^T."""
    vertical = cdpm.load_robot(MODELS / "two_link_vertical")
    flat = linearise(paper_robot, "nominal")
    hung = linearise(vertical, "nominal")
    assert flat.nilpotent and not hung.nilpotent
    # by hand: c1 alone holds G = g (1.5 cos 30deg, 0) = (12.744, 0) with
    # L[c1, q1] = -0.4999 (paper eq 16 at the nominal pose)
    np.testing.assert_allclose(hung.tension, [25.4927, 0, 0, 0], atol=1e-4)
    witness = np.array([0, 0, -2, -1.0])
    assert np.allclose(flat.A.T @ witness, 0)
    assert not np.allclose(hung.A.T @ witness, 0)


NOTEBOOK = MODELS.parent / "notebooks" / "gravity_and_pretension.ipynb"


def test_gravity_notebook_is_committed_without_outputs():
    nb = json.loads(NOTEBOOK.read_text())
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert code and all(not c.get("outputs") and c.get("execution_count") is None for c in code)


@pytest.mark.slow
def test_gravity_notebook_executes():
    nb = execute_notebook(NOTEBOOK, timeout=300)
    text = "\n".join(
        out.get("text", "")
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
    )
    assert "POC: YES | positive controllability: NO" in text  # the paper's case
    assert "Equilibrium (zero): INFEASIBLE" in text
    assert "as found (c1 taut, others slack): NO" in text
    assert "with c2 counted as taut: YES" in text
