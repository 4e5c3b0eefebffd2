"""No decision depends on the robot's units: statics are judged relative
to the robot's own force scale, never to an absolute newton.

With tension bounds [0, inf) (or bounds and pretension scaled with the
masses) a robot whose masses are all multiplied by a factor, or whose
lengths are, has the same equilibria up to that factor, and the same
verdicts: positive output controllability (POC) is invariant. A 37 x 37
map of each scaled copy (masses 1e-9 to 1e9 times, lengths 1e-3 to 1e3
times those of the shipped model, within the model range cdpm documents)
must equal the unit robot's pose for pose.
"""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.model.coordinates import coordinate_units
from tests.conftest import MODELS
from tests.scaled_models import scaled_copy, scaled_pose

#: the verdicts and cable counts a scaled copy must share with the unit robot
VERDICTS = (
    "poc",
    "output_controllable",
    "positive_controllable",
    "wrench_closure",
    "static_feasible",
    "status",
    "n_taut",
)

#: a point mass in a vertical plane held by four cables from the corners of
#: a 4 m square, tensions in [0, 12] N: feasible in the upper middle only
POINT_URDF = """<robot name="point_mass"><link name="world"/>
  <link name="carriage"/>
  <link name="mass"><inertial><mass value="1"/>
    <inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial></link>
  <joint name="x" type="prismatic"><parent link="world"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="100" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="carriage"/><child link="mass"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="100" velocity="1"/></joint>
</robot>
"""

POINT_SPEC = """description: point mass in a vertical plane, four cables
urdf: point_mass.urdf
gravity: [0, 0, -9.81]
cables:
  - name: ul
    tension: [0, 12]
    route: [{frame: world, point: [-2, 0, 2]}, {frame: mass, point: [0, 0, 0]}]
  - name: ur
    tension: [0, 12]
    route: [{frame: world, point: [2, 0, 2]}, {frame: mass, point: [0, 0, 0]}]
  - name: ll
    tension: [0, 12]
    route: [{frame: world, point: [-2, 0, -2]}, {frame: mass, point: [0, 0, 0]}]
  - name: lr
    tension: [0, 12]
    route: [{frame: world, point: [2, 0, -2]}, {frame: mass, point: [0, 0, 0]}]
outputs:
  - {name: px, frame: mass, component: x}
  - {name: pz, frame: mass, component: z}
"""


@pytest.fixture(scope="module")
def point_mass(tmp_path_factory):
    folder = tmp_path_factory.mktemp("point_mass")
    (folder / "point_mass.urdf").write_text(POINT_URDF)
    (folder / "point_mass.yaml").write_text(POINT_SPEC)
    return folder / "point_mass.yaml", folder / "point_mass.urdf"


def _arm():
    spec = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
    return spec, MODELS / "two_link_vertical" / "two_link_vertical.urdf"


def _pendulum():
    spec = MODELS / "double_pendulum_cables" / "double_pendulum_cables.yaml"
    return spec, cdpm.load_spec(spec).urdf_path


def _map(spec_path, length: float, n: int = 37):
    robot = cdpm.load_robot(spec_path)
    units = coordinate_units(robot.model)
    axes = {}
    for name, unit in zip(robot.coordinate_names[:2], units[:2], strict=True):
        low, high = (-1.9 * length, 1.9 * length) if unit == "m" else (-np.pi, np.pi)
        axes[name] = np.linspace(low, high, n)
    return cdpm.workspace_map(robot, axes, workers=1, margin=False)


def _differences(ref, ds) -> dict[str, int]:
    return {
        k: int(np.count_nonzero(np.asarray(ds[k]) != np.asarray(ref[k])))
        for k in VERDICTS
        if np.any(np.asarray(ds[k]) != np.asarray(ref[k]))
    }


def _check(tmp_path, files, equilibrium, scales, min_feasible):
    spec, urdf = files
    unit = _map(scaled_copy(spec, urdf, tmp_path / "unit", 1.0, 1.0, equilibrium), 1.0)
    feasible = int(np.count_nonzero(np.asarray(unit.static_feasible) == 1))
    infeasible = int(np.count_nonzero(np.asarray(unit.static_feasible) == 0))
    # the map has both kinds of pose, so that a shift either way shows
    assert feasible >= min_feasible and infeasible >= min_feasible
    wrong = {}
    for mass, length in scales:
        folder = tmp_path / f"m{mass:g}_l{length:g}"
        path = scaled_copy(spec, urdf, folder, mass, length, equilibrium)
        diff = _differences(unit, _map(path, length))
        if diff:
            wrong[mass, length] = diff
    assert not wrong, f"verdicts that change with the robot's units: {wrong}"


#: (mass factor, length factor): each alone over its whole range, and the
#: corners the model range allows (moments of inertia up to 1e12 kg m^2)
SWEEP = [
    (1e-9, 1.0),
    (1e-7, 1.0),
    (1e-3, 1.0),
    (1e3, 1.0),
    (1e9, 1.0),
    (1.0, 1e-3),
    (1.0, 3e-3),
    (1.0, 1e3),
    (1e-9, 1e-3),
    (1e-9, 1e3),
    (1e9, 1e-3),
]


def test_point_mass_sweep_fast(tmp_path, point_mass):
    """The extreme corners on the bounded point mass (fast tier)."""
    _check(tmp_path, point_mass, None, [(1e-9, 1e-3), (1e9, 1e-3), (1e-9, 1e3)], 100)


@pytest.mark.slow
def test_point_mass_sweep(tmp_path, point_mass):
    _check(tmp_path, point_mass, None, SWEEP, 100)


@pytest.mark.slow
@pytest.mark.parametrize(
    "equilibrium",
    [{"method": "min_norm"}, {"method": "pretension", "pretension": 10.0}],
    ids=["min_norm", "pretension"],
)
def test_gravity_arm_sweep(tmp_path, equilibrium):
    _check(tmp_path, _arm(), equilibrium, SWEEP, 8)


@pytest.mark.slow
def test_pendulum_with_damping_sweep(tmp_path):
    """double_pendulum_cables: bounded tensions and joint damping (scaled so
    that the dynamics keep their shape)."""
    _check(tmp_path, _pendulum(), None, [s for s in SWEEP if s[0] >= 1e-7], 8)


@pytest.mark.slow
def test_tension_range_and_best_tension_scale(tmp_path, point_mass):
    """The tension range's LPs (HiGHS, absolute tolerances) and the search
    of the best tension solve in units of the robot's force scale: the
    same feasibility, ranges scaled by the mass factor, the same verdict."""
    spec, urdf = point_mass
    unit = cdpm.load_robot(scaled_copy(spec, urdf, tmp_path / "unit", 1.0, 1.0))
    poses = np.random.default_rng(3).uniform(-1.9, 1.9, (12, 2))
    expected = [cdpm.tension_range(unit, q) for q in poses]
    best = [
        cdpm.best_tension(unit, q).verdict
        for q, r in zip(poses, expected, strict=True)
        if r.feasible
    ]
    assert 3 <= sum(r.feasible for r in expected) < len(poses)
    for mass, length in [(1e-9, 1e-3), (1e9, 1e-3), (1e-9, 1e3)]:
        path = scaled_copy(spec, urdf, tmp_path / f"m{mass:g}_l{length:g}", mass, length)
        robot = cdpm.load_robot(path)
        got_best = []
        for q, ref in zip(poses, expected, strict=True):
            r = cdpm.tension_range(robot, scaled_pose(robot, q, length))
            assert r.feasible == ref.feasible, (mass, length, q)
            if ref.feasible:
                np.testing.assert_allclose(r.least / mass, ref.least, rtol=1e-6, atol=1e-9)
                np.testing.assert_allclose(r.greatest / mass, ref.greatest, rtol=1e-6, atol=1e-9)
                assert r.cable_states() == ref.cable_states()
                got_best.append(cdpm.best_tension(robot, scaled_pose(robot, q, length)).verdict)
        assert got_best == best, (mass, length)


def test_a_pretension_below_a_heavy_robots_resolution_stays_as_asked(tmp_path):
    """A 2e9 kg arm with a 10 N pretension: 10 N is within the bound test's
    round-off of 0 (1e-9 of the 2e10 N force scale), so those cables count
    as on their lower bound, but their tension stays the 10 N asked for."""
    spec, urdf = _arm()
    heavy = cdpm.load_robot(scaled_copy(spec, urdf, tmp_path / "heavy", 1e9, 1.0))
    eq = cdpm.equilibrium_tension(heavy, [0.2, 0.4], method="pretension", pretension=10.0)
    assert eq.feasible and np.all(eq.tension >= 10.0)
    assert np.any(eq.tension == 10.0)
