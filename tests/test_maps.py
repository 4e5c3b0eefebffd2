"""Workspace maps: batched kinematics, verdicts against the per-pose public
API, degenerate poses, storage and resumption, local and Dask execution."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.dynamics.reach import reach_margins_at
from cdpm.errors import InputError
from cdpm.maps import (
    STATUS_CODES,
    VERDICT_CODES,
    StoreSettingsError,
    open_map,
    sample_axes,
    workspace_map,
)
from tests.conftest import MODELS, PAPER_SPEC

CODE = {"yes": 1, "no": 0, "marginal": 2}

MIXED_URDF = """<?xml version="1.0"?>
<robot name="mixed">
  <link name="base"/>
  <link name="body">
    <inertial><origin xyz="0.1 0.05 0.02" rpy="0.1 0.2 0.3"/><mass value="2.0"/>
      <inertia ixx="0.3" ixy="0.01" ixz="0.02" iyy="0.2" iyz="0.03" izz="0.25"/></inertial>
  </link>
  <link name="slider">
    <inertial><origin xyz="0.0 0.1 0.0" rpy="0 0 0"/><mass value="0.5"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.03"/></inertial>
  </link>
  <link name="arm">
    <inertial><origin xyz="0.3 0 0" rpy="0 0 0"/><mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
  </link>
  <link name="tip"/>
  <joint name="root" type="floating"><parent link="base"/><child link="body"/></joint>
  <joint name="slide" type="prismatic"><parent link="body"/><child link="slider"/>
    <origin xyz="0.2 0 0.1" rpy="0 0.3 0"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="hinge" type="revolute"><parent link="slider"/><child link="arm"/>
    <origin xyz="0 0.1 0" rpy="0.2 0 0"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="tipj" type="fixed"><parent link="arm"/><child link="tip"/>
    <origin xyz="0.6 0 0"/></joint>
</robot>
"""

MIXED_SPEC = """\
urdf: mixed.urdf
gravity: {gravity}
cables:
  - name: a
    route:
      - {{frame: world, point: [1, 0, 1]}}
      - {{frame: body, point: [0.1, 0, 0]}}
  - name: b
    route:
      - {{frame: world, point: [-1, 0.5, 1]}}
      - {{frame: slider, point: [0, 0.1, 0]}}
      - {{frame: tip, point: [0, 0, 0.05]}}
  - name: c
    route:
      - {{frame: world, point: [0, -1, -1]}}
      - {{frame: arm, point: [0.5, 0, 0]}}
outputs:
  - {{name: tip_x, frame: tip, component: x}}
  - {{name: tip_z, frame: tip, component: z}}
"""


@pytest.fixture
def mixed_robot(tmp_path):
    """A free-flyer with an unaligned prismatic and revolute joint, full
    inertias and a cable routed over two links."""

    def make(gravity="[0, 0, -9.81]"):
        (tmp_path / "mixed.urdf").write_text(MIXED_URDF)
        spec = tmp_path / "mixed.yaml"
        spec.write_text(MIXED_SPEC.format(gravity=gravity))
        return cdpm.load_robot(spec)

    return make


def _same(a, b) -> None:
    """Datasets equal value by value (NaN == NaN), same variables and coords."""
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.data_vars:
        x, y = np.asarray(a[name].values), np.asarray(b[name].values)
        assert x.dtype == y.dtype, name
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name
    for name in a.coords:
        assert np.array_equal(np.asarray(a[name].values), np.asarray(b[name].values)), name


PAPER_AXES = {"q1": np.linspace(-3.1, 3.1, 41), "q2": np.linspace(-3.1, 3.1, 37)}


@pytest.fixture(scope="module")
def paper_map():
    return workspace_map(cdpm.load_robot(PAPER_SPEC), PAPER_AXES, workers=1)


# --------------------------------------------------------------------------
# batched kinematics


def _reference_kinematics(robot, q):
    """Cable rows, outputs and their Jacobians at q from Pinocchio's own
    computeJointJacobians / getFrameJacobian (independent of the batch)."""
    import pinocchio as pin

    from cdpm.model.spec import OUTPUT_COMPONENTS, WORLD_FRAME_NAMES

    model = robot.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    def point(frame, local):
        if frame in WORLD_FRAME_NAMES:
            return np.asarray(local, float), np.zeros((3, robot.nv))
        fid = model.getFrameId(frame)
        placement = data.oMf[fid]
        p = placement.act(np.asarray(local, float))
        jf = pin.getFrameJacobian(model, data, fid, world)
        # velocity of a point fixed to the frame: v_frame + w x (p - origin)
        arm = p - placement.translation
        return p, jf[:3] + np.cross(jf[3:].T, arm).T

    lengths, rows = [], []
    for cable in robot.spec.cables:
        pts = [point(r.frame, r.point_in_frame) for r in cable.route]
        length, row = 0.0, np.zeros(robot.nv)
        for (pa, ja), (pb, jb) in zip(pts[:-1], pts[1:], strict=True):
            d = pb - pa
            length += np.linalg.norm(d)
            row += (d / np.linalg.norm(d)) @ (jb - ja)
        lengths.append(length)
        rows.append(row)
    outs = [point(o.frame, np.zeros(3)) for o in robot.spec.outputs]
    comps = [OUTPUT_COMPONENTS[o.component] for o in robot.spec.outputs]
    y = np.array([p[c] for (p, _), c in zip(outs, comps, strict=True)])
    cq = np.array([j[c] for (_, j), c in zip(outs, comps, strict=True)])
    return np.array(lengths), np.array(rows), y, cq


@pytest.mark.parametrize("model", ["paper", "mixed", "spatial_8cable", "multilink_arm"])
def test_batch_kinematics_equal_pinocchio_per_pose(model, mixed_robot, paper_robot):
    """kinematics_batch (one crba per pose plus array arithmetic) against
    Pinocchio's frame Jacobians and the single-pose robot methods."""
    from cdpm.model.poses import configurations

    if model == "paper":
        robot = paper_robot
    elif model == "mixed":
        robot = mixed_robot()  # free-flyer, unaligned prismatic and revolute
    else:
        robot = cdpm.load_robot(MODELS / model / f"{model}.yaml")
    natural = np.random.default_rng(7).uniform(-1.5, 1.5, (25, robot.nv))
    qs = configurations(robot, natural)
    res = robot.kinematics_batch(qs, dynamics=True)
    for i, x in enumerate(natural):
        q = robot.from_natural(x)
        # a quaternion may differ in sign only
        np.testing.assert_allclose(
            robot.to_natural(qs[i]), robot.to_natural(q), atol=1e-12, err_msg="configuration"
        )
        lengths, rows, y, cq = _reference_kinematics(robot, q)
        np.testing.assert_allclose(res.lengths[i], lengths, atol=1e-12)
        np.testing.assert_allclose(res.jacobian[i], rows, atol=1e-12)
        np.testing.assert_allclose(res.output[i], y, atol=1e-12)
        np.testing.assert_allclose(res.output_jacobian[i], cq, atol=1e-12)
        np.testing.assert_allclose(res.mass_matrix[i], robot.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(res.gravity[i], robot.gravity_torque(q), atol=1e-11)
    np.testing.assert_array_equal(robot.mass_matrix_batch(qs), res.mass_matrix)
    assert np.array_equal(res.mass_matrix, np.swapaxes(res.mass_matrix, 1, 2))
    # without dynamics: the same kinematics, no M or G
    plain = robot.kinematics_batch(qs)
    assert plain.mass_matrix is None and plain.gravity is None
    np.testing.assert_array_equal(plain.jacobian, res.jacobian)


def test_batch_without_the_flat_placement_view(mixed_robot):
    """The per-joint (rotation, translation) views, used when Pinocchio's
    placements are not laid out as one flat array, give the same batch."""
    robot = mixed_robot()
    natural = np.random.default_rng(8).uniform(-1, 1, (6, robot.nv))
    qs = np.array([robot.from_natural(x) for x in natural])
    flat = robot.kinematics_batch(qs, dynamics=True)
    data, jac, mass, placements, moving = robot._batch_views()
    assert isinstance(placements, np.ndarray)  # this build has the flat layout
    pairs = [(data.oMi[j].rotation, data.oMi[j].translation) for j in range(robot.model.njoints)]
    robot._batch_views_cache = (data, jac, mass, pairs, moving)
    per_joint = robot.kinematics_batch(qs, dynamics=True)
    for field in dataclasses.fields(flat):
        value = getattr(flat, field.name)
        np.testing.assert_array_equal(getattr(per_joint, field.name), value, err_msg=field.name)


def test_one_crba_fills_jacobians_placements_and_mass(mixed_robot):
    """The batch relies on crba(WORLD) filling data.J, data.oMi and the
    upper triangle of data.M exactly as the dedicated calls do."""
    import pinocchio as pin

    robot = mixed_robot()
    model = robot.model
    for seed in range(3):
        q = robot.from_natural(np.random.default_rng(seed).uniform(-1, 1, robot.nv))
        a, b = model.createData(), model.createData()
        pin.crba(model, a, q, pin.Convention.WORLD)
        pin.computeJointJacobians(model, b, q)
        M = pin.crba(model, b, q)
        np.testing.assert_array_equal(a.J, b.J)
        for j in range(model.njoints):
            np.testing.assert_array_equal(a.oMi[j].homogeneous, b.oMi[j].homogeneous)
        np.testing.assert_allclose(np.triu(a.M), np.triu(M), atol=1e-14)


# --------------------------------------------------------------------------
# verdicts


def test_map_dataset_contract(paper_map):
    ds = paper_map
    assert ds["poc"].dims == ("q1", "q2")
    assert ds["y"].dims == ("q1", "q2", "output")
    assert ds["output_frame_position"].dims == ("q1", "q2", "xyz")
    assert list(ds["output"].values) == ["tip_x"]
    assert ds["q1"].attrs["units"] == "rad"
    for name in (
        "poc",
        "output_controllable",
        "positive_controllable",
        "wrench_closure",
        "static_feasible",
        "status",
    ):
        assert ds[name].dtype == np.int8
        assert ds[name].attrs["flag_values"] and ds[name].attrs["flag_meanings"]
    assert ds.attrs["spec_sha256"] == cdpm.load_robot(PAPER_SPEC).spec.sha256
    assert ds.attrs["cdpm_version"] == cdpm.__version__
    assert (ds["status"] == STATUS_CODES["ok"]).all()
    # both verdicts occur on this grid, and the margin is positive exactly on YES
    poc = ds["poc"].values
    assert (poc == 1).any() and (poc == 0).any()
    assert np.all((ds["reach_margin"].values > 0) == (poc == 1))
    assert ds.attrs["reach_horizon"] > 0 and ds.attrs["tension_budget"] > 0
    # tip x = cos q1 + cos(q1 + q2) (paper eq 17)
    q1, q2 = np.meshgrid(PAPER_AXES["q1"], PAPER_AXES["q2"], indexing="ij")
    np.testing.assert_allclose(ds["y"].values[..., 0], np.cos(q1) + np.cos(q1 + q2), atol=1e-12)


def test_map_verdicts_equal_public_per_pose(paper_map, paper_robot):
    ds = paper_map
    rng = np.random.default_rng(3)
    for _ in range(30):
        i, j = rng.integers(ds.sizes["q1"]), rng.integers(ds.sizes["q2"])
        q = [float(ds["q1"][i]), float(ds["q2"][j])]
        lin = cdpm.linearise(paper_robot, q)
        poc = cdpm.positive_output_controllability(
            lin.A, lin.B, lin.C, sign_constrained=lin.sign_constrained
        )
        brammer = cdpm.positive_controllability(lin.A, lin.B, sign_constrained=lin.sign_constrained)
        closure = cdpm.wrench_closure(lin.cable_jacobian)
        oc = cdpm.output_controllability(lin.A, lin.B, lin.C)
        at = ds.isel(q1=i, q2=j)
        assert int(at["poc"]) == CODE[poc.verdict.value]
        r = reach_margins_at(paper_robot, lin, None, [poc.verdict is cdpm.Verdict.NO]).value[0]
        assert float(at["reach_margin"]) == pytest.approx(r, rel=1e-9, abs=1e-15)
        assert int(at["positive_controllable"]) == CODE[brammer.verdict.value]
        assert int(at["wrench_closure"]) == CODE[closure.verdict.value]
        assert int(at["output_controllable"]) == (1 if oc.controllable else 0)


def test_paper_nominal_pose_is_yes(paper_robot):
    ds = workspace_map(paper_robot, {"q1": [np.pi / 6]}, base="nominal", workers=1)
    assert ds["poc"].values.tolist() == [VERDICT_CODES["yes"]]
    assert ds.attrs["base"] == pytest.approx([np.pi / 6, np.pi / 3])


def test_mixed_robot_verdicts_equal_public(mixed_robot):
    """Free-flyer coordinates as axes, p = 2, nv = 8: the deferred paths."""
    robot = mixed_robot("[0, 0, 0]")
    axes = {"root.x": np.linspace(-0.5, 0.5, 3), "hinge": np.linspace(-2, 2, 4)}
    ds = workspace_map(robot, axes, base={"root.z": 0.2, "slide": 0.1}, workers=1)
    assert ds["poc"].dims == ("root.x", "hinge")
    assert ds["root.x"].attrs["units"] == "m" and ds["hinge"].attrs["units"] == "rad"
    for i in range(3):
        for j in range(4):
            q = robot.configuration(
                {
                    "root.x": axes["root.x"][i],
                    "hinge": axes["hinge"][j],
                    "root.z": 0.2,
                    "slide": 0.1,
                }
            )
            lin = cdpm.linearise(robot, q)
            poc = cdpm.positive_output_controllability(
                lin.A, lin.B, lin.C, sign_constrained=lin.sign_constrained
            )
            assert int(ds["poc"][i, j]) == CODE[poc.verdict.value]
            closure = cdpm.wrench_closure(lin.cable_jacobian)
            assert int(ds["wrench_closure"][i, j]) == CODE[closure.verdict.value]


def test_degenerate_poses_are_flagged(write_spec):
    # cable c1 runs from (1, 0, 0) to the point 1 m along link1: zero length at q1 = 0
    spec = write_spec(
        """\
        urdf: arm.urdf
        gravity: [0, 0, 0]
        cables:
          - name: c1
            route:
              - {frame: base, point: [1, 0, 0]}
              - {frame: link1, point: [1, 0, 0]}
          - name: c2
            route:
              - {frame: base, point: [0, 1.5, 0]}
              - {frame: link2, point: [0.3, 0.1, 0], relative_to: com}
        outputs:
          - {name: tip_x, frame: tip, component: x}
        """
    )
    ds = workspace_map(spec, {"q1": [-0.5, 0.0, 0.5], "q2": [0.3, 1.0]}, workers=1)
    status = ds["status"].values
    assert (status[1] == STATUS_CODES["zero_length_cable"]).all()
    assert (status[[0, 2]] == STATUS_CODES["ok"]).all()
    for name in ("poc", "wrench_closure", "positive_controllable"):
        assert (ds[name].values[1] == VERDICT_CODES["not_analysed"]).all()
        assert np.isin(ds[name].values[[0, 2]], [0, 1, 2]).all()
    assert np.isnan(ds["reach_margin"].values[1]).all()
    # the outputs stay defined at degenerate poses
    assert np.isfinite(ds["y"].values).all()


def test_singular_mass_matrix_is_flagged(write_spec, tmp_path):
    urdf = (tmp_path / "arm.urdf").read_text()
    # link2 without mass: M is singular at every pose
    head, tail = urdf.split('<link name="link2">')
    (tmp_path / "arm.urdf").write_text(
        head + '<link name="link2">' + tail.replace('<mass value="1.0"/>', '<mass value="0.0"/>', 1)
    )
    spec = write_spec(
        """\
        urdf: arm.urdf
        gravity: [0, 0, 0]
        cables:
          - name: c1
            route:
              - {frame: base, point: [0, 0.5, 0]}
              - {frame: link1, point: [0.3, 0.1, 0], relative_to: com}
          - name: c2
            route:
              - {frame: base, point: [0, -1.5, 0]}
              - {frame: link2, point: [0.8, -0.1, 0]}
        outputs:
          - {name: tip_x, frame: tip, component: x}
        """
    )
    ds = workspace_map(spec, {"q1": [0.0, 1.0], "q2": [0.5]}, workers=1)
    assert (ds["status"].values == STATUS_CODES["singular_mass_matrix"]).all()
    assert (ds["poc"].values == VERDICT_CODES["not_analysed"]).all()


VERTICAL_SPEC = MODELS / "two_link_vertical" / "two_link_vertical.yaml"


@pytest.mark.parametrize("tension", [None, "pretension"])
def test_gravity_map_equals_public_per_pose(tension):
    """The batched general path (equilibria, linearisations, output rank)
    against cdpm.linearise and the public analysers, pose by pose."""
    from cdpm.dynamics.equilibrium import InfeasibleEquilibriumError, equilibrium_tension

    robot = cdpm.load_robot(VERTICAL_SPEC)
    natural = np.random.default_rng(2).uniform(-np.pi, np.pi, (24, 2))
    out = cdpm.maps.evaluate_poses(robot, natural, tension)
    seen = set()
    for i, x in enumerate(natural):
        q = robot.from_natural(x)
        feasible = equilibrium_tension(robot, q, method="min_norm").feasible
        assert out["static_feasible"][i] == (1 if feasible else 0)
        assert (
            out["wrench_closure"][i]
            == CODE[cdpm.wrench_closure(robot.cable_jacobian(q)).verdict.value]
        )
        try:
            lin = cdpm.linearise(robot, q, tension=tension)
        except InfeasibleEquilibriumError:
            assert out["status"][i] == STATUS_CODES["no_equilibrium"]
            assert out["poc"][i] == VERDICT_CODES["not_analysed"]
            assert np.isnan(out["tension_max"][i])
            seen.add("infeasible")
            continue
        seen.add("feasible")
        assert out["status"][i] == STATUS_CODES["ok"]
        args = (lin.A, lin.B_cone, lin.C)
        poc = cdpm.positive_output_controllability(*args, sign_constrained=lin.sign_constrained)
        brammer = cdpm.positive_controllability(
            lin.A, lin.B_cone, sign_constrained=lin.sign_constrained
        )
        assert out["poc"][i] == CODE[poc.verdict.value]
        # the map assembles A from batched terms: equal up to round-off, and
        # the margin is continuous in A
        r = reach_margins_at(robot, lin, None, [poc.verdict is cdpm.Verdict.NO]).value[0]
        assert out["reach_margin"][i] == pytest.approx(r, rel=1e-7, abs=1e-9)
        assert out["positive_controllable"][i] == CODE[brammer.verdict.value]
        assert out["output_controllable"][i] == int(cdpm.output_controllability(*args).controllable)
        assert out["tension_min"][i] == pytest.approx(lin.tension.min(), rel=1e-9, abs=1e-9)
        assert out["tension_max"][i] == pytest.approx(lin.tension.max(), rel=1e-9, abs=1e-9)
    assert seen == {"feasible", "infeasible"}


def test_map_without_margin_has_the_same_verdicts(tmp_path):
    """margin=False: NaN margins, every verdict as with margins (the taut
    cables' mixed-cone exit decides most gravity poses without the analyser)."""
    robot = cdpm.load_robot(VERTICAL_SPEC)
    axes = {"q1": np.linspace(-3, 3, 7), "q2": np.linspace(-3, 3, 6)}
    full = workspace_map(robot, axes, workers=1)
    fast = workspace_map(robot, axes, workers=1, margin=False, store=tmp_path / "m.zarr")
    assert fast.attrs["cdpm_settings"] != full.attrs["cdpm_settings"]
    assert np.isnan(fast["reach_margin"].values).all()
    assert (full["poc"].values == VERDICT_CODES["yes"]).any()
    for name in full.data_vars:
        if not name.startswith("reach_margin"):
            np.testing.assert_array_equal(fast[name].values, full[name].values, err_msg=name)
    paper = workspace_map(PAPER_SPEC, {"q1": [0.1, 0.5]}, base="nominal", workers=1, margin=False)
    assert np.isnan(paper["reach_margin"].values).all()
    assert paper["poc"].values.tolist() == [VERDICT_CODES["yes"]] * 2


def test_batched_equilibria_equal_the_solver():
    """min_norm_tensions: solved poses are the QP's optimum, 'infeasible'
    ones have no equilibrium (Farkas), on models with 2 to 8 cables."""
    from cdpm.dynamics.equilibrium import equilibrium_tension
    from cdpm.dynamics.equilibrium.newton import min_norm_tensions
    from cdpm.model.poses import configurations

    decided = 0
    for name, spread in (("two_link_vertical", 3.0), ("spatial_8cable", 0.3)):
        robot = cdpm.load_robot(MODELS / name / f"{name}.yaml")
        natural = np.random.default_rng(1).uniform(-spread, spread, (60, robot.nv))
        qs = configurations(robot, natural)
        kin = robot.kinematics_batch(qs, dynamics=True)
        LT = np.swapaxes(kin.jacobian, 1, 2)
        load = -kin.gravity - robot.external_wrench
        for method, lower in (("min_norm", robot.tension_min), ("pretension", None)):
            if lower is None:
                lower = np.maximum(robot.tension_min, robot.spec.pretension or 10.0)
            f, solved, infeasible = min_norm_tensions(
                LT, load, lower, robot.tension_max, robot.force_scale
            )
            assert not (solved & infeasible).any()
            for i in np.flatnonzero(solved | infeasible):
                eq = equilibrium_tension(robot, qs[i], method=method, pretension=float(lower.max()))
                assert eq.feasible == bool(solved[i])
                if solved[i]:
                    np.testing.assert_allclose(f[i], eq.tension, rtol=1e-8, atol=1e-8)
                decided += 1
    assert decided >= 0.9 * 4 * 60  # the per-pose solver is a rare fallback


def test_given_tension_outside_bounds_is_refused(paper_robot):
    with pytest.raises(InputError, match=r"tension outside the cable bounds: c1=-1"):
        workspace_map(paper_robot, {"q1": [0.0]}, tension=[-1.0, 0, 0, 0], workers=1)


# --------------------------------------------------------------------------
# inputs


def test_bad_axes_are_rejected(paper_robot, tmp_path):
    with pytest.raises(InputError, match="not a coordinate of the robot; coordinates: q1, q2"):
        workspace_map(paper_robot, {"q3": [0.0]})
    with pytest.raises(InputError, match="axis 'q1' has no values"):
        workspace_map(paper_robot, {"q1": []})
    with pytest.raises(InputError, match="non-finite"):
        workspace_map(paper_robot, {"q1": [0.0, np.nan]})
    with pytest.raises(InputError, match="pose 'nope' not in spec"):
        workspace_map(paper_robot, {"q1": [0.0]}, base="nope")
    with pytest.raises(InputError, match="workers must be a positive integer"):
        workspace_map(paper_robot, {"q1": [0.0]}, workers=0)
    with pytest.raises(InputError, match="axis 'q1' repeats a value"):
        workspace_map(paper_robot, {"q1": [0.0, 1.0, 1.0]})
    with pytest.raises(InputError, match=r"1-D list of values, got shape \(2, 2\)"):
        workspace_map(paper_robot, {"q1": [[0.0, 1.0], [1.0, 2.0]]})
    # an in-memory map too large for memory is refused before any work
    huge = {"q1": np.linspace(-3, 3, 100_000), "q2": np.linspace(-3, 3, 100_000)}
    with pytest.raises(InputError, match=r"10,000,000,000 poses needs about .* GiB(.|\n)*store="):
        workspace_map(paper_robot, huge)
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "file.txt").write_text("x")
    with pytest.raises(InputError, match="is a folder of other files, not a zarr store"):
        workspace_map(paper_robot, {"q1": [0.0]}, store=tmp_path / "junk")
    (tmp_path / "plain.zarr").write_text("x")  # a file: replaced only when asked
    with pytest.raises(InputError, match="exists and is not a cdpm map store.*--overwrite"):
        workspace_map(paper_robot, {"q1": [0.0]}, store=tmp_path / "plain.zarr")


def test_random_samples(paper_robot):
    ds = workspace_map(paper_robot, {"q1": (-3, 3), "q2": (0, 1)}, samples=300, seed=5, workers=1)
    assert ds["poc"].dims == ("sample",)
    assert ds["q1"].dims == ("sample",) and ds.sizes["sample"] == 300
    assert float(ds["q2"].min()) >= 0 and float(ds["q2"].max()) <= 1
    again = workspace_map(
        paper_robot, sample_axes({"q1": (-3, 3), "q2": (0, 1)}, 300, seed=5), workers=1
    )
    _same(ds, again)
    # per-sample verdicts equal a grid evaluation at the same poses
    q = np.stack([ds["q1"].values, ds["q2"].values], axis=1)[:20]
    ref = cdpm.maps.evaluate_poses(paper_robot, q)
    np.testing.assert_array_equal(ds["poc"].values[:20], ref["poc"])


# --------------------------------------------------------------------------
# storage, resumption, parallel runs


@pytest.mark.parametrize("kept", [True, False], ids=["returned-from-memory", "read-back"])
@pytest.mark.parametrize("sampled", [False, True])
def test_a_stored_map_reads_back_identical_to_the_map_in_memory(
    paper_robot, tmp_path, monkeypatch, sampled, kept
):
    """The store's skeleton is written through zarr directly (not through
    xarray): read back, a map is the in-memory map, attributes, coordinates
    (the sampled axes as non-dimension coordinates) and regions included.
    The run returns the map it kept in memory (``kept``: a small map) or
    reads it back from the store (a map above RESULT_IN_MEMORY_MAX), and
    either is the map open_map reads."""
    import xarray as xr
    import zarr

    from cdpm.maps import _store

    if not kept:
        monkeypatch.setattr(_store, "RESULT_IN_MEMORY_MAX", 0)
    if sampled:
        axes, kw = {"q1": (-3, 3), "q2": (0, 1)}, {"samples": 200, "seed": 2}
    else:
        axes, kw = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}, {}
    memory = workspace_map(paper_robot, axes, workers=1, **kw)
    stored = workspace_map(paper_robot, axes, workers=1, store=tmp_path / "m.zarr", **kw)
    opened = open_map(tmp_path / "m.zarr")
    # the returned map indexes the coordinates it wrote, without reading
    # them back: the same indexes, and every variable read from the store
    # as open_map reads it (its regions are the labels just computed)
    assert {name: type(index) for name, index in stored.xindexes.items()} == {
        name: type(index) for name, index in opened.xindexes.items()
    }
    # read back, the variables carry the store's encoding (chunks, codecs);
    # kept in memory, none
    assert ("chunks" in stored["poc"].encoding) is not kept
    assert list(stored.data_vars) == list(opened.data_vars)  # in the same order
    # coordinates as the map lists them (axes first), not by name as zarr does
    first = ["sample", "q1", "q2"] if sampled else ["q1", "q2"]
    for ds in (memory, stored, opened):
        assert list(ds.coords) == [*first, "output", "xyz", "cable"]
    for name in opened.variables:
        if name != "poc_region" and not kept:
            got, read = stored[name].encoding, opened[name].encoding
            assert got.keys() == read.keys(), name
            for key, value in read.items():  # NaN fill values compare unequal
                assert got[key] == value or (np.isnan(got[key]) and np.isnan(value)), (name, key)
    for ds in (stored, opened):
        xr.testing.assert_identical(ds.load(), memory)
        assert ds.encoding["source"] == os.path.abspath(tmp_path / "m.zarr")
    if sampled:
        assert set(stored.coords) - set(stored.dims) == {"q1", "q2"}
    # the regions' array is added to the consolidated metadata in place:
    # the root document is the one zarr's own consolidation writes
    root = tmp_path / "m.zarr" / "zarr.json"
    written = json.loads(root.read_text())
    assert "poc_region" in written["consolidated_metadata"]["metadata"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # consolidated metadata: not in the v3 spec yet
        zarr.consolidate_metadata(str(tmp_path / "m.zarr"))
    assert json.loads(root.read_text()) == written
    # no temporary file is left behind
    assert not [p for p in (tmp_path / "m.zarr").rglob("*") if p.name.endswith(".partial")]


def test_the_regions_chunks_lie_side_by_side_also_in_stores_of_earlier_versions(
    paper_robot, tmp_path
):
    """The regions' chunk files lie side by side (c.i.j, as every data
    variable's: no folder per chunk); a store whose regions were written
    in nested folders (c/i/j, by earlier versions) reads, and writing its
    regions again leaves no nested folder."""
    import zarr

    from cdpm.maps.regions import attach_regions

    axes = {"q1": np.linspace(-3, 3, 64), "q2": np.linspace(0, 1, 40)}  # 2 chunks
    store = tmp_path / "m.zarr"
    ds = workspace_map(paper_robot, axes, workers=1, store=store, chunk_size=1280)
    assert sorted(os.listdir(store / "poc_region")) == ["c.0.0", "c.1.0", "zarr.json"]
    labels = ds["poc_region"].values
    assert labels.max() > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # consolidated metadata: not in the v3 spec yet
        group = zarr.open_group(str(store), mode="r+")
        old = group.create_array(
            "poc_region",
            shape=labels.shape,
            chunks=group["poc"].chunks,
            dtype=labels.dtype,
            fill_value=0,
            dimension_names=list(ds["poc_region"].dims),
            attributes=dict(ds["poc_region"].attrs),
            chunk_key_encoding={"name": "default", "separator": "/"},
            overwrite=True,
        )
        old[...] = labels
        zarr.consolidate_metadata(str(store))
    assert sorted(os.listdir(store / "poc_region")) == ["c", "zarr.json"]
    np.testing.assert_array_equal(open_map(store)["poc_region"].values, labels)
    attach_regions(open_map(store), store)
    assert sorted(os.listdir(store / "poc_region")) == ["c.0.0", "c.1.0", "zarr.json"]
    np.testing.assert_array_equal(open_map(store)["poc_region"].values, labels)


def test_a_map_to_a_store_silences_only_zarrs_warnings(paper_robot, tmp_path, monkeypatch):
    """zarr's warnings about a map store's string coordinates and
    consolidated metadata are silenced; a warning from anywhere else (here
    the evaluation) still reaches the caller, and the warning filters are
    as they were."""
    from cdpm.pipeline.evaluate import MapJob

    evaluate = MapJob.evaluate

    def warns(self, robot, natural):
        warnings.warn("a warning from the evaluation", UserWarning, stacklevel=1)
        return evaluate(self, robot, natural)

    monkeypatch.setattr(MapJob, "evaluate", warns)
    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    filters = list(warnings.filters)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        workspace_map(paper_robot, axes, workers=1, store=tmp_path / "m.zarr")
    assert [str(w.message) for w in caught] == ["a warning from the evaluation"]
    assert warnings.filters == filters


def test_a_run_stopped_while_creating_its_store_is_made_again(paper_robot, tmp_path, monkeypatch):
    """A run stopped while it writes the new store's files (written in
    place, not renamed, in a thread of their own; here by a full disk)
    raises the error and leaves a store without its created marker; the
    next run makes the store again instead of refusing it as not a map."""
    import threading

    import xarray as xr

    import cdpm.maps._filestore

    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    store = tmp_path / "m.zarr"
    write_new_file, calls = cdpm.maps._filestore.write_new_file, []

    def full_after_five(path, data):
        calls.append(path)
        if len(calls) > 5:
            raise OSError(28, "No space left on device")
        write_new_file(path, data)

    monkeypatch.setattr(cdpm.maps._filestore, "write_new_file", full_after_five)
    with pytest.raises(OSError, match="No space left"):
        workspace_map(paper_robot, axes, workers=1, store=store)
    assert not [t for t in threading.enumerate() if t.name == "cdpm-store-files"]
    assert (store / ".cdpm").is_dir() and not (store / ".cdpm" / "created").exists()
    assert sum(p.is_file() for p in store.rglob("*") if ".cdpm" not in p.parts) == 5
    with pytest.raises(InputError, match="incomplete cdpm map .* run the same `cdpm map"):
        open_map(store)  # its files may be half written
    monkeypatch.setattr(cdpm.maps._filestore, "write_new_file", write_new_file)
    again = workspace_map(paper_robot, axes, workers=1, store=store)
    xr.testing.assert_identical(again.load(), workspace_map(paper_robot, axes, workers=1))


def test_a_finished_map_is_read_not_written_again(paper_robot, tmp_path):
    """A run that finds its map finished, regions included, reads it and
    writes nothing into the store (which may then be read-only)."""
    import xarray as xr

    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    store = tmp_path / "m.zarr"
    first = workspace_map(paper_robot, axes, workers=1, store=store)

    def files() -> dict:
        return {p: p.stat().st_mtime_ns for p in store.rglob("*") if p.is_file()}

    before = files()
    again = workspace_map(paper_robot, axes, workers=1, store=store)
    assert files() == before
    xr.testing.assert_identical(again.load(), first)


def test_a_resumed_map_is_read_from_its_store(paper_robot, tmp_path):
    """A run that finds its map finished (or resumes it) returns the map as
    open_map reads it, coordinates included: only the run that created the
    store indexes the coordinate values it wrote without reading them."""
    import xarray as xr
    import zarr

    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    store = tmp_path / "m.zarr"
    workspace_map(paper_robot, axes, workers=1, store=store)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # consolidated metadata: not in the v3 spec yet
        zarr.open_array(str(store / "q1"), mode="r+")[:] = np.arange(9.0)  # edited by hand
    again = workspace_map(paper_robot, axes, workers=1, store=store)
    np.testing.assert_array_equal(again["q1"].values, np.arange(9.0))
    assert "chunks" in again["poc"].encoding  # read back, not kept in memory
    xr.testing.assert_identical(
        again.drop_vars("poc_region"), open_map(store).drop_vars("poc_region")
    )


def test_new_store_consolidated_metadata_is_zarrs_own(paper_robot, tmp_path, monkeypatch):
    """A new store's root document, whose consolidated metadata is made
    from the arrays just created (not read back), is the one zarr's own
    consolidation writes from the files (regions left out: their write
    rewrites the document)."""
    import zarr

    import cdpm.maps

    monkeypatch.setattr(cdpm.maps, "attach_new_regions", lambda ds, *args, **kw: ds)
    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    workspace_map(paper_robot, axes, workers=1, store=tmp_path / "m.zarr")
    root = tmp_path / "m.zarr" / "zarr.json"
    written = root.read_bytes()
    assert "poc_region" not in json.loads(written)["consolidated_metadata"]["metadata"]
    with warnings.catch_warnings(), zarr.config.set({"json_indent": None}):
        warnings.simplefilter("ignore")  # consolidated metadata: not in the v3 spec yet
        zarr.consolidate_metadata(str(tmp_path / "m.zarr"))
    assert root.read_bytes() == written


def test_the_new_stores_regions_are_the_ones_zarr_writes(paper_robot, tmp_path):
    """The run that creates a store writes its POC regions without opening
    it (the array made in memory, the group's document updated): the
    store's files are those the general write (zarr's creation of the array
    in the opened store) leaves, and the root document is the one zarr's
    consolidation writes from the files."""
    import zarr

    from cdpm.maps.regions import attach_regions

    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    store = tmp_path / "m.zarr"
    workspace_map(paper_robot, axes, workers=1, store=store)

    def files() -> dict:
        return {
            p.relative_to(store).as_posix(): p.read_bytes()
            for p in sorted(store.rglob("*"))
            if p.is_file() and ".cdpm" not in p.parts
        }

    written = files()
    assert "poc_region/zarr.json" in written and "poc_region/c.0.0" in written
    assert "poc_region" in json.loads(written["zarr.json"])["consolidated_metadata"]["metadata"]
    attach_regions(open_map(store), store)
    assert files() == written
    with warnings.catch_warnings(), zarr.config.set({"json_indent": None}):
        warnings.simplefilter("ignore")  # consolidated metadata: not in the v3 spec yet
        zarr.consolidate_metadata(str(store))
    assert files() == written


@pytest.mark.slow
def test_every_array_document_is_the_one_zarr_creates(tmp_path):
    """The data variables of a kind share the metadata zarr made for the
    first of them, with their own attributes and dimension names: each
    variable's zarr.json is the document zarr's create_array writes from its
    shape, dtype, dimensions and attributes in the in-memory map, its
    criterion's fill value and the map's chunks (a map under load with a
    tension search: every kind of variable)."""
    import zarr

    from cdpm.pipeline.criteria import CRITERIA

    # the arm's three outputs: y and output_frame_position are one kind with
    # other dimension names
    spec = MODELS / "multilink_arm" / "multilink_arm.yaml"
    axes = {"shoulder_x": np.linspace(-0.3, 0.3, 5), "elbow": np.linspace(-1, 0, 4)}
    store = tmp_path / "m.zarr"
    kw = dict(base="reach", workers=1, tension="best")
    workspace_map(spec, axes, store=store, **kw)
    memory = workspace_map(spec, axes, **kw)
    assert memory["y"].shape[2:] == memory["output_frame_position"].shape[2:] == (3,)
    for name, criterion in CRITERIA.items():
        written = json.loads((store / name / "zarr.json").read_text())
        variable = memory[name]
        chunks = written["chunk_grid"]["configuration"]["chunk_shape"]
        assert chunks[:2] == [5, 4] and chunks[2:] == list(variable.shape[2:]), name
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            made = zarr.create_array(
                zarr.storage.MemoryStore(),
                shape=variable.shape,
                chunks=chunks,
                dtype=variable.dtype,
                fill_value=criterion.fill,
                dimension_names=list(variable.dims),
                attributes=variable.attrs,
                chunk_key_encoding={"name": "default", "separator": "."},
            )
        assert json.loads(json.dumps(made.metadata.to_dict())) == written, name


def test_regions_write_creates_nothing_on_a_wrong_path_and_consolidates_again(
    paper_robot, tmp_path
):
    """Writing the POC regions into a path that holds no store fails with
    the fix and leaves no folder behind; into a store with an array that its
    consolidated metadata does not list (added by hand), the metadata is
    consolidated again from the files, so open_map sees both."""
    import warnings

    import zarr

    from cdpm.maps.regions import attach_regions

    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    store = tmp_path / "m.zarr"
    ds = workspace_map(paper_robot, axes, workers=1, store=store)
    typo = tmp_path / "typo.zarr"
    with pytest.raises(InputError, match="give the store the map was written to"):
        attach_regions(ds, typo)
    assert not typo.exists()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # zarr: consolidated metadata not in the v3 spec
        group = zarr.open_group(str(store), mode="r+", use_consolidated=False)
        group.create_array("extra", shape=(3,), dtype="f8", dimension_names=["extra_dim"])
    attach_regions(ds, store)
    listed = json.loads((store / "zarr.json").read_text())["consolidated_metadata"]["metadata"]
    assert {"extra", "poc_region", "poc"} <= set(listed)
    assert "extra" in open_map(store).data_vars


def test_store_roundtrip_and_settings_mismatch(paper_robot, paper_map, tmp_path):
    store = tmp_path / "m.zarr"
    ds = workspace_map(paper_robot, PAPER_AXES, workers=1, store=store, chunk_size=300)
    _same(ds, paper_map)
    _same(open_map(store), paper_map)
    assert len(os.listdir(store / ".cdpm" / "done")) == 6  # 41 x 37 poses, chunks of 8 x 37
    other = {"q1": PAPER_AXES["q1"], "q2": PAPER_AXES["q2"][:-1]}
    with pytest.raises(
        StoreSettingsError, match=r"different settings(.|\n)*axis 'q2'(.|\n)*overwrite=True"
    ):
        workspace_map(paper_robot, other, workers=1, store=store, chunk_size=300)
    with pytest.raises(InputError, match="chunk_size: stored 300, now 400"):
        workspace_map(paper_robot, PAPER_AXES, workers=1, store=store, chunk_size=400)
    replaced = workspace_map(paper_robot, other, workers=1, store=store, overwrite=True)
    assert replaced.sizes["q2"] == 36


def test_interrupted_run_resumes_without_recomputing(paper_robot, paper_map, tmp_path):
    store = tmp_path / "m.zarr"
    seen: list[int] = []

    def stop_after_three(done, total, index):
        if index >= 0:
            seen.append(index)
        if len(seen) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        workspace_map(
            paper_robot,
            PAPER_AXES,
            workers=1,
            store=store,
            chunk_size=150,
            progress=stop_after_three,
        )
    done_before = {int(p.name) for p in (store / ".cdpm" / "done").iterdir()}
    assert done_before == set(seen)
    resumed: list[int] = []
    ds = workspace_map(
        paper_robot,
        PAPER_AXES,
        workers=1,
        store=store,
        chunk_size=150,
        progress=lambda d, t, k: resumed.append(k) if k >= 0 else None,
    )
    n_chunks = len(done_before) + len(resumed)
    assert not done_before & set(resumed)
    assert sorted(done_before | set(resumed)) == list(range(n_chunks))
    _same(ds, paper_map)


_KILL_CHILD = """
import sys, numpy as np, cdpm.maps
axes = {"q1": np.linspace(-3.1, 3.1, 301), "q2": np.linspace(-3.1, 3.1, 300)}
cdpm.maps.workspace_map(sys.argv[1], axes, workers=1, store=sys.argv[2], chunk_size=600)
"""


@pytest.mark.slow
def test_sigkilled_map_resumes_to_the_same_result(paper_robot, tmp_path):
    store = tmp_path / "killed.zarr"
    done_dir = store / ".cdpm" / "done"
    proc = subprocess.Popen(
        [sys.executable, "-c", _KILL_CHILD, str(PAPER_SPEC), str(store)],
        cwd=str(Path(__file__).resolve().parents[1]),
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if done_dir.is_dir() and len([p for p in done_dir.iterdir() if p.name.isdigit()]) >= 5:
                break
            if proc.poll() is not None:
                pytest.fail("the map finished before it could be killed")
            time.sleep(0.02)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    done_before = {int(p.name) for p in done_dir.iterdir() if p.name.isdigit()}
    axes = {"q1": np.linspace(-3.1, 3.1, 301), "q2": np.linspace(-3.1, 3.1, 300)}
    assert 5 <= len(done_before) < 151  # 90300 poses in chunks of 600 (2 rows of 300)
    resumed: list[int] = []
    ds = workspace_map(
        paper_robot,
        axes,
        workers=1,
        store=store,
        chunk_size=600,
        progress=lambda d, t, k: resumed.append(k) if k >= 0 else None,
    )
    assert not done_before & set(resumed)
    assert sorted(done_before | set(resumed)) == list(range(151))
    fresh = workspace_map(paper_robot, axes, workers=1, chunk_size=600)
    _same(ds, fresh)
    assert (ds["status"].values == 0).all()


def test_default_chunks_under_load_are_few_and_even(tmp_path):
    """Writing a chunk costs about 10 ms whatever its size, so default chunks
    under load hold at least 2048 poses (a 2048-pose map is one: a second
    chunk would add its writing, and a worker process starts slower than
    the map runs), a thirty-second of a larger map, at most 4096; a map's
    chunk files lie side by side (no folder per chunk)."""
    from cdpm.maps import MIN_PER_POSE_CHUNK_SIZE, PER_POSE_CHUNK_SIZE, _per_pose_chunk_size

    assert (MIN_PER_POSE_CHUNK_SIZE, PER_POSE_CHUNK_SIZE) == (2048, 4096)
    sizes = {n: _per_pose_chunk_size(n) for n in (1, 2048, 4096, 16384, 80000, 131072, 10**6)}
    assert sizes == {
        1: 2048,
        2048: 2048,
        4096: 2048,
        16384: 2048,
        80000: 2560,
        131072: 4096,
        10**6: 4096,
    }
    assert [-(-n // size) for n, size in sizes.items()] == [1, 1, 2, 8, 32, 32, 245]
    axes = {"q1": np.linspace(-3.0, 3.0, 64), "q2": np.linspace(-3.0, 3.0, 64)}
    store = tmp_path / "v.zarr"
    ds = workspace_map(VERTICAL_SPEC, axes, workers=1, store=store, margin=False)
    assert ds.attrs["chunk_size"] == 2048
    assert open_map(store)["poc"].encoding["chunks"] == (32, 64)
    assert sorted(p.name for p in (store / "poc").iterdir()) == ["c.0.0", "c.1.0", "zarr.json"]
    assert sorted(p.name for p in (store / ".cdpm" / "done").iterdir()) == ["0", "1"]
    _same(ds, workspace_map(VERTICAL_SPEC, axes, workers=1, chunk_size=256, margin=False))


def test_worker_processes_give_the_same_map(paper_robot, paper_map, tmp_path):
    ds = workspace_map(PAPER_SPEC, PAPER_AXES, workers=2, chunk_size=300, store=tmp_path / "p.zarr")
    _same(ds, paper_map)
    # worker processes write chunks: this one keeps none, and reads the map back
    assert "chunks" in ds["poc"].encoding


def test_a_map_whose_chunks_a_worker_wrote_is_read_back(paper_robot, tmp_path, monkeypatch):
    """A small map is returned from this process's memory only when this
    process wrote every chunk: a chunk a worker process wrote (through the
    store's picklable writer, as ``_run_processes`` has it) is not there,
    and the map is read back from the store."""
    import pickle

    import xarray as xr

    from cdpm.maps import _store

    own_write = _store.ZarrSink.write

    def write(sink, index, data):
        if index == 1:  # as a worker process writes its chunk
            pickle.loads(pickle.dumps(sink.writer)).write(index, data)
        else:
            own_write(sink, index, data)

    monkeypatch.setattr(_store.ZarrSink, "write", write)
    axes = {"q1": np.linspace(-3, 3, 16), "q2": np.linspace(0, 1, 8)}
    store = tmp_path / "m.zarr"
    ds = workspace_map(paper_robot, axes, workers=1, store=store, chunk_size=64)
    assert sorted(p.name for p in (store / ".cdpm" / "done").iterdir()) == ["0", "1"]
    assert "chunks" in ds["poc"].encoding  # read back
    xr.testing.assert_identical(ds, open_map(store))
    monkeypatch.undo()
    _same(ds, workspace_map(paper_robot, axes, workers=1))


def test_this_process_computes_while_its_worker_processes_start(paper_map, monkeypatch):
    """A local worker starts only once the fork server has imported its
    modules (about a second): the map's own process computes chunks
    meanwhile instead of waiting in its first submit. Here a pool of
    threads stands for the processes, and its first submit waits until
    the map's process has finished two chunks: waiting in it would time out.
    Once released, the map's process waits for the thread that starts the
    workers to end, so that the remaining chunks are handed out (on a busy
    machine the map's process finished them all before that thread ran)."""
    import concurrent.futures
    import threading

    from cdpm.maps import _workers

    released = threading.Event()
    order: list[str] = []

    class SlowToStart(concurrent.futures.ThreadPoolExecutor):
        def __init__(self, max_workers, mp_context=None, initializer=None, initargs=()):
            super().__init__(max_workers)
            self.first = True
            self.source, self.plan, self.job = initargs[:3]

        def submit(self, fn, *args):
            if self.first:
                self.first = False
                if not released.wait(timeout=10):
                    raise TimeoutError("the map's process waited for its workers to start")
            if fn is _workers._worker_ready:
                return super().submit(fn)
            robot = _workers._state(self.source)
            index = args[0]
            order.append("worker")
            return super().submit(
                lambda: (index, self.job.evaluate(robot, self.plan.natural(index)))
            )

    starters: list[threading.Thread] = []
    start_workers = _workers._start_worker_processes

    def recorded_start(*args):
        starters.append(start_workers(*args))
        return starters[-1]

    def progress(done, total, index):
        if index >= 0:
            order.append("here" if len(order) == order.count("here") else "done")
        if order.count("here") >= 2 and not released.is_set():
            released.set()
            starters[0].join(timeout=10)

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", SlowToStart)
    monkeypatch.setattr(_workers, "_start_fork_server", lambda ctx: None)  # none here
    monkeypatch.setattr(_workers, "_start_worker_processes", recorded_start)
    ds = workspace_map(PAPER_SPEC, PAPER_AXES, workers=2, chunk_size=148, progress=progress)
    _same(ds, paper_map)
    assert order[:2] == ["here", "here"] and "worker" in order


_UNGUARDED_SCRIPT = """
import sys, numpy as np, cdpm
axes = {"q1": np.linspace(-3.1, 3.1, 40), "q2": np.linspace(-3.1, 3.1, 40)}
cdpm.workspace_map(sys.argv[1], axes, workers=2, chunk_size=100, store=sys.argv[2])
print("finished")
"""


@pytest.mark.slow
def test_unguarded_script_with_workers_runs_on_one_process_and_says_why(paper_map, tmp_path):
    """Local workers import the main script (as Python's spawn does): a map
    call at a script's top level must not run again in them (it would
    replace the store being written). Such a script runs the map in its own
    process, says why and how to get workers (the main guard), and writes
    the whole map; the guarded script then finds it complete."""
    store = tmp_path / "u.zarr"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))

    def run_script(name: str, text: str) -> subprocess.CompletedProcess:
        script = tmp_path / name
        script.write_text(text)
        command = [sys.executable, str(script), str(PAPER_SPEC), str(store)]
        return subprocess.run(command, capture_output=True, text=True, timeout=300, env=env)

    run = run_script("unguarded.py", _UNGUARDED_SCRIPT)
    assert run.returncode == 0, run.stderr
    assert run.stdout.count("finished") == 1  # the script ran once, not again in workers
    assert 'if __name__ == "__main__":' in run.stderr and "workers=1" in run.stderr
    assert "Traceback" not in run.stderr
    body = _UNGUARDED_SCRIPT.strip().splitlines()
    guarded = body[:2] + ['if __name__ == "__main__":'] + ["    " + x for x in body[2:]]
    run = run_script("guarded.py", "\n".join(guarded))
    assert run.returncode == 0, run.stderr
    axes = {"q1": np.linspace(-3.1, 3.1, 40), "q2": np.linspace(-3.1, 3.1, 40)}
    _same(open_map(store), workspace_map(PAPER_SPEC, axes, workers=1))


def test_dask_cluster_gives_the_same_map(paper_robot, paper_map, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        host="127.0.0.1",
        protocol="tcp://",
        processes=False,
        n_workers=1,
        threads_per_worker=2,
        dashboard_address=":0",
    ) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        ds = workspace_map(
            paper_robot,
            PAPER_AXES,
            scheduler=cluster.scheduler_address,
            chunk_size=300,
            store=tmp_path / "d.zarr",
        )
        _same(ds, paper_map)
        with distributed.Client(cluster) as client:
            ds2 = workspace_map(paper_robot, PAPER_AXES, scheduler=client, chunk_size=300)
            _same(ds2, paper_map)


def test_robot_source_rebuilds_from_shipped_bytes(paper_robot, tmp_path):
    from cdpm.maps._workers import RobotSource

    folder = tmp_path / "model"
    shutil.copytree(PAPER_SPEC.parent, folder)
    robot = cdpm.load_robot(folder / PAPER_SPEC.name)
    source = RobotSource.from_robot(robot)
    shutil.rmtree(folder)  # a remote worker does not see the driver's files
    rebuilt = source.load()
    assert rebuilt.spec.sha256 == paper_robot.spec.sha256


@pytest.mark.parametrize("spec", [PAPER_SPEC, VERTICAL_SPEC])
def test_poses_evaluated_in_blocks_equal_one_batch(spec, monkeypatch):
    """evaluate_poses takes many poses in blocks (EVALUATE_BLOCK): the
    results are those of one batch, bit for bit, whatever the block."""
    import cdpm.pipeline.evaluate as evaluate

    robot = cdpm.load_robot(spec)
    natural = np.random.default_rng(4).uniform(-3.1, 3.1, (23, robot.nv))
    whole = cdpm.maps.evaluate_poses(robot, natural)
    monkeypatch.setattr(evaluate, "EVALUATE_BLOCK", 5)
    blocks = cdpm.maps.evaluate_poses(robot, natural)
    assert whole.keys() == blocks.keys()
    for name, value in whole.items():
        assert value.shape[0] == 23 and value.dtype == blocks[name].dtype, name
        np.testing.assert_array_equal(blocks[name], value, err_msg=name)
    assert (whole["poc"] == 1).any() and np.isfinite(whole["reach_margin"]).any()


def test_map_arguments_that_failed_deep_inside_are_refused_first():
    robot = cdpm.load_robot(MODELS / "two_link_vertical")
    for kwargs, message in (
        ({"progress": 5}, "progress must be True"),  # was: 'int' object is not callable
        ({"announce": 3}, "announce must be a callable"),
        ({"workers": True}, "workers must be a positive integer"),
    ):
        with pytest.raises(cdpm.InputError, match=message):
            cdpm.workspace_map(robot, {"q1": [0.0, 0.1]}, **kwargs)
    for quiet in (None, np.False_):  # as False
        assert cdpm.workspace_map(robot, {"q1": [0.0, 0.1]}, progress=quiet).poc.size == 2
    # override bounds are read as the spec's: no bools, -0 N is 0 N (printed "-0")
    with pytest.raises(cdpm.InputError, match=r"must be \(min, max\) in N, got \(True, 10\)"):
        cdpm.maps.override_robot(robot, tension_bounds=(True, 10))
    low = cdpm.maps.override_robot(robot, tension_bounds=(-0.0, 10)).tension_min
    assert np.all(np.copysign(1.0, low) == 1.0)
    # drawn before the check: a MemoryError
    with pytest.raises(cdpm.InputError, match=r"1,000,000,000,000 samples need 7,450\.6 GiB"):
        cdpm.sample_axes({"q1": (0.0, 1.0)}, 10**12)


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_folder_of_other_files_is_neither_written_nor_deleted(paper_robot, tmp_path, overwrite):
    """A non-empty folder that is not a zarr store is refused with the one
    fix that works (another path): --overwrite would not delete it either,
    so the message does not offer it."""
    folder = tmp_path / "results"
    folder.mkdir()
    (folder / "notes.txt").write_text("mine")
    axes = {"q1": np.linspace(-3, 3, 3), "q2": np.linspace(0, 1, 2)}
    with pytest.raises(InputError, match="folder of other files.*choose another output") as err:
        workspace_map(paper_robot, axes, workers=1, store=folder, overwrite=overwrite)
    assert "overwrite=True" not in str(err.value)
    assert [p.name for p in folder.iterdir()] == ["notes.txt"]


def test_regions_lost_from_a_finished_store_are_written_again(paper_robot, tmp_path):
    """A finished store whose regions no longer match its map (a rewrite of
    them stopped part-way, leaving their chunks dropped) gets them written
    again by the next run, which computes nothing else."""
    import zarr

    axes = {"q1": np.linspace(-3, 3, 9), "q2": np.linspace(0, 1, 7)}
    store = tmp_path / "m.zarr"
    first = workspace_map(paper_robot, axes, workers=1, store=store)
    assert first["poc_region"].values.max() > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        zarr.open_array(str(store / "poc_region"), mode="r+")[...] = 0
    again = workspace_map(paper_robot, axes, workers=1, store=store)
    np.testing.assert_array_equal(again["poc_region"].values, first["poc_region"].values)
    np.testing.assert_array_equal(open_map(store)["poc_region"].values, first["poc_region"].values)
