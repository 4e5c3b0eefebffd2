"""The tension range and the equilibrium solver judge feasibility by one rule.

A point mass in a horizontal plane held by three cables: at y = 0.3 cables a
and b are exactly opposed, and c pulls up (+y) from y = 2. Just below that
line (y = 0.3 - 1e-9) a, b and c all pull towards +y, so the only feasible
tension is zero, and cable c moves by less than 1e-9 per newton along the
null space of L^T. HiGHS drops such tiny matrix entries, and with them c's
bounds, and the tension range used to call these poses infeasible although
the equilibrium solver holds them with zero tension.
"""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.cli import main
from cdpm.dynamics.equilibrium.statics import holds

URDF = """<robot name="point_mass"><link name="world"/>
  <link name="carriage"><inertial><mass value="1e-3"/>
    <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial></link>
  <link name="mass"><inertial><mass value="0.1"/>
    <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial></link>
  <joint name="slide_x" type="prismatic"><parent link="world"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="slide_y" type="prismatic"><parent link="carriage"/><child link="mass"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
</robot>
"""

SPEC = """description: point mass in a horizontal plane, three cables
urdf: point_mass.urdf
gravity: [0, 0, -9.81]      # normal to the plane of motion: G(q) = 0
cables:
  - name: a
    route: [{frame: world, point: [-3, 0.3, 0]}, {frame: mass, point: [0, 0, 0]}]
  - name: b
    route: [{frame: world, point: [1, 0.3, 0]}, {frame: mass, point: [0, 0, 0]}]
  - name: c
    route: [{frame: world, point: [0, 2, 0]}, {frame: mass, point: [0, 0, 0]}]
outputs:
  - {name: px, frame: mass, component: x}
  - {name: py, frame: mass, component: y}
"""

#: poses in the band about the line y = 0.3 where a and b are opposed
BAND = [np.array([x, 0.3 - 1e-9]) for x in np.linspace(-0.9, -0.7, 39)]


@pytest.fixture(scope="module")
def spec(tmp_path_factory):
    folder = tmp_path_factory.mktemp("point_mass")
    (folder / "point_mass.urdf").write_text(URDF)
    path = folder / "point_mass.yaml"
    path.write_text(SPEC)
    return path


@pytest.fixture(scope="module")
def robot(spec):
    return cdpm.load_robot(spec)


def test_the_band_is_where_two_cables_are_opposed(robot):
    # the null space of L^T moves cable c by less than 1e-9 per newton: the
    # case HiGHS cannot see
    from cdpm.dynamics.tension_choice.range import pose_statics

    for q in BAND[::6]:
        _, LT, load = pose_statics(robot, q)
        np.testing.assert_allclose(load, 0.0, atol=1e-12)
        _, _, Vt = np.linalg.svd(LT)
        assert 0 < abs(Vt[-1, 2]) < 1e-9


def test_range_and_solver_agree_in_the_band(robot):
    for q in BAND:
        eq = cdpm.equilibrium_tension(robot, q)
        assert eq.feasible
        np.testing.assert_allclose(eq.tension, 0.0, atol=1e-12)
        rng = cdpm.tension_range(robot, q)
        assert rng.feasible, f"tension range infeasible at q={q.tolist()}"
        # c cannot pull (it would lift the mass off the line): fixed slack
        assert rng.least[2] == 0.0 and rng.greatest[2] == 0.0
        assert rng.must_be_slack.tolist() == [False, False, True]
        assert np.all(rng.interior >= rng.tension_min)


def test_best_tension_holds_the_pose_in_the_band(robot):
    from cdpm.dynamics.tension_choice.range import pose_statics

    for q in BAND[::19]:
        best = cdpm.best_tension(robot, q)
        assert best.tension_range.feasible
        f = best.tension
        assert np.all(f >= robot.tension_min)
        _, LT, load = pose_statics(robot, q)
        assert holds(LT[None], load[None], f[None], robot.force_scale)[0]


def test_analyze_best_tension_in_the_band(spec, capsys):
    code = main(["analyze", str(spec), "--q", "-0.8", "0.299999999", "--tension", "best"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "Tension search: none" not in out
