"""One rule for given equilibrium tensions at the cable bounds.

``cdpm.linearise``, ``cdpm.evaluate_poses``, ``cdpm.workspace_map`` and
``cdpm.check_equilibrium`` take tensions [N] from the caller. They judge
them alike (:func:`cdpm.dynamics.equilibrium.checked_tensions`): a tension
beyond its cable's bound by at most GIVEN_TENSION_BOUND_RTOL times
max(F, the largest given tension) is round-off (F the robot's force
scale, its weight) and sits on the bound;
farther beyond, non-finite entries and wrong lengths are InputErrors with
the same message on every path, and accepted tensions give the same
verdicts on every path.
"""

from __future__ import annotations

import numpy as np
import pytest

import cdpm
from cdpm.maps import VERDICT_CODES, override_robot
from cdpm.numerics import GIVEN_TENSION_BOUND_RTOL
from tests.conftest import MODELS, PAPER_SPEC

#: the rule's relative tolerance, pinned here: a change of it is a decision
RTOL = 1e-9
#: how far inside and outside the tolerance the cases lie (round-off of the
#: tolerance itself, which scales with the given tensions, stays far below)
INSIDE, OUTSIDE = 0.5, 2.0
#: how every refusal of a tension beyond its bound begins
BOUNDS = "tension outside the cable bounds: "


def test_tolerance_is_the_pinned_one():
    assert GIVEN_TENSION_BOUND_RTOL == RTOL


def _tol(f, force: float) -> float:
    """The rule's tolerance [N] for tensions f of a robot of force scale ``force``."""
    return RTOL * max(force, float(np.max(np.abs(f))))


def _with(f, **entries):
    """f (a copy) with entries by cable index: ``_with(f, c1=...)``."""
    out = np.array(f, dtype=float)
    for name, value in entries.items():
        out[int(name[1:]) - 1] = value
    return out


@pytest.fixture(scope="module")
def planar():
    """The paper's arm: no gravity, bounds [0, inf), f* = 0 at the nominal pose."""
    robot = cdpm.load_robot(PAPER_SPEC)
    return robot, "nominal", np.zeros(robot.n_cables)


@pytest.fixture(scope="module")
def capped():
    """two_link_vertical at elbow_up (c1 alone holds the arm, about 33 N),
    with c1's maximum set to that tension: c1 on its upper bound, the
    others slack on their lower bound 0, and a tension scale of 33 N
    (tolerance 3.3e-8 N, above an absolute 1e-9 N)."""
    robot = cdpm.load_robot(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
    f0 = cdpm.equilibrium_tension(robot, "elbow_up").tension
    assert f0[0] > 10 and not np.any(f0[1:])
    robot = override_robot(robot, tension_bounds={"c1": (0.0, float(f0[0]))})
    assert robot.tension_max[0] == f0[0] and np.isinf(robot.tension_max[1])
    return robot, "elbow_up", f0


def _cases(f0, lower_cable: str, upper_cable: str | None, force: float = 1.0):
    """(id, tension, expected): expected is the tension accepted (clipped
    onto the bounds) or the regex of the InputError."""
    tol = _tol(f0, force)
    lo = int(lower_cable[1:]) - 1
    cases = [
        ("as_given", f0, f0),
        (
            "below_min_inside",
            _with(f0, **{lower_cable: -INSIDE * tol}),
            f0,
        ),
        (
            "below_min_outside",
            _with(f0, **{lower_cable: -OUTSIDE * tol}),
            rf"{BOUNDS}{lower_cable}=-[0-9.e-]+ N is "
            rf"[0-9.e-]+ N below its tension_min 0 N; give tensions within",
        ),
        (
            "below_min_far",
            _with(f0, **{lower_cable: -1.0}),
            rf"{BOUNDS}{lower_cable}=-1 N is 1 N below",
        ),
        (
            "nan",
            _with(f0, **{lower_cable: np.nan}),
            rf"tension entry {lower_cable}=nan is not a finite tension of at most 1e\+12 N; "
            r"give 4 finite tensions \[N\]",
        ),
        (
            "inf",
            _with(f0, **{lower_cable: np.inf}),
            rf"tension entry {lower_cable}=inf is not a finite tension",
        ),
        (
            "too_short",
            f0[:3],
            r"tension has 3 entries, expected one per cable \(4: c1, c2, c3, c4\)",
        ),
        ("too_long", np.append(f0, 0.0), r"tension has 5 entries, expected one per cable"),
        ("matrix", np.reshape(f0, (2, 2)), r"tension has shape \(2, 2\), expected \(4,\)"),
        ("not_numbers", ["a", 0, 0, 0], r"tension must be numbers: 'a' is not a number"),
    ]
    assert lo >= 0
    if upper_cable is not None:
        up = int(upper_cable[1:]) - 1
        cases += [
            (
                "above_max_inside",
                _with(f0, **{upper_cable: f0[up] + INSIDE * tol}),
                f0,
            ),
            (
                "above_max_outside",
                _with(f0, **{upper_cable: f0[up] + OUTSIDE * tol}),
                rf"{BOUNDS}{upper_cable}=[0-9.e-]+ N is "
                rf"[0-9.e-]+ N above its tension_max [0-9.]+ N",
            ),
        ]
    return cases


PLANAR_CASES = [c[0] for c in _cases(np.zeros(4), "c1", None)] + [
    "round_off_everywhere",  # the reported case: every cable 1e-10 N below its minimum
    "round_off_everywhere_outside",
]
CAPPED_CASES = [c[0] for c in _cases(np.ones(4), "c2", "c1")]


def _case(robot_case, case_id):
    robot, pose, f0 = robot_case
    loaded = bool(f0.any())
    lower_cable, upper_cable = ("c2", "c1") if loaded else ("c1", None)
    cases = {c[0]: c[1:] for c in _cases(f0, lower_cable, upper_cable, robot.force_scale)}
    if case_id == "round_off_everywhere":
        cases[case_id] = (robot.tension_min - 1e-10, robot.tension_min.copy())
    elif case_id == "round_off_everywhere_outside":
        cases[case_id] = (
            robot.tension_min - 1e-8,
            rf"{BOUNDS}c1=-1e-08 N is 1e-08 N below .*c4=-1e-08",
        )
    return robot, pose, *cases[case_id]


def _poc_of(lin) -> int:
    result = cdpm.positive_output_controllability(
        lin.A, lin.B_cone, lin.C, sign_constrained=lin.sign_constrained
    )
    return VERDICT_CODES[result.verdict.value]


def _same_on_every_path(robot, pose, tension, expected, with_map: bool):
    q = robot.kinematics(pose).q
    if isinstance(expected, str):
        with pytest.raises(cdpm.InputError, match=expected):
            cdpm.linearise(robot, pose, tension=tension)
        with pytest.raises(cdpm.InputError, match=expected):
            cdpm.evaluate_poses(robot, [pose], tension=tension, margin=False)
        if with_map:
            with pytest.raises(cdpm.InputError, match=expected):
                cdpm.workspace_map(
                    robot, {"q1": [q[0]]}, base=pose, tension=tension, workers=1, margin=False
                )
        # check_equilibrium answers "does not hold" for tensions beyond the
        # bounds, and refuses what is not one finite tension per cable
        if expected.startswith(BOUNDS):
            eq = cdpm.check_equilibrium(robot, pose, tension)
            assert not eq.feasible
            assert "the given tensions leave the cable bounds" in eq.message
        else:
            with pytest.raises(cdpm.InputError, match=expected):
                cdpm.check_equilibrium(robot, pose, tension)
        return
    expected = np.asarray(expected, dtype=float)
    lin = cdpm.linearise(robot, pose, tension=tension)
    np.testing.assert_array_equal(lin.tension, expected)  # on the bound, exactly
    assert np.all(lin.tension >= robot.tension_min) and np.all(lin.tension <= robot.tension_max)
    eq = cdpm.check_equilibrium(robot, pose, tension)
    assert eq.feasible, eq.message
    np.testing.assert_array_equal(eq.tension, expected)
    given = cdpm.evaluate_poses(robot, [pose], tension=tension, margin=False)
    clipped = cdpm.evaluate_poses(robot, [pose], tension=expected, margin=False)
    for name, values in clipped.items():
        np.testing.assert_array_equal(given[name], values, err_msg=name)
    assert given["status"][0] == cdpm.STATUS_CODES["ok"]
    assert given["static_feasible"][0] == VERDICT_CODES["yes"]
    assert given["poc"][0] == _poc_of(lin)
    np.testing.assert_allclose(given["tension_max"][0], lin.tension.max(), rtol=0, atol=0)
    np.testing.assert_allclose(given["tension_min"][0], lin.tension.min(), rtol=0, atol=0)
    if with_map:
        # a tiny map: the pose and one beside it (which the given tensions
        # need not hold), against evaluate_poses at the same poses
        axis = [float(q[0]), float(q[0]) + 0.1]
        ds = cdpm.workspace_map(
            robot, {"q1": axis}, base=pose, tension=tension, workers=1, margin=False
        )
        poses = [{**dict(zip(robot.coordinate_names, q, strict=True)), "q1": a} for a in axis]
        direct = cdpm.evaluate_poses(robot, poses, tension=expected, margin=False)
        for name in ("poc", "status", "static_feasible"):
            np.testing.assert_array_equal(np.asarray(ds[name].values).reshape(-1), direct[name])
        assert ds["poc"].values.reshape(-1)[0] == _poc_of(lin)


@pytest.mark.parametrize("case_id", PLANAR_CASES)
def test_planar_paths_agree(planar, case_id):
    robot, pose, tension, expected = _case(planar, case_id)
    _same_on_every_path(robot, pose, tension, expected, with_map=case_id in MAP_CASES)


@pytest.mark.parametrize("case_id", CAPPED_CASES)
def test_capped_paths_agree(capped, case_id):
    robot, pose, tension, expected = _case(capped, case_id)
    _same_on_every_path(robot, pose, tension, expected, with_map=case_id in MAP_CASES)


#: the cases also run through a tiny workspace_map (a map costs more)
MAP_CASES = {
    "below_min_inside",
    "below_min_outside",
    "above_max_inside",
    "above_max_outside",
    "nan",
    "round_off_everywhere",
}


def test_tolerance_scales_with_the_tensions(capped):
    # 1e-8 N below a bound: round-off next to 33 N (the tolerance is
    # 3.3e-8 N), not next to 1 N (1e-9 N)
    robot, pose, f0 = capped
    lin = cdpm.linearise(robot, pose, tension=_with(f0, c2=-1e-8))
    assert lin.tension[1] == 0.0
    small = cdpm.load_robot(PAPER_SPEC)
    with pytest.raises(cdpm.InputError, match=r"c2=-1e-08 N is 1e-08 N below"):
        cdpm.linearise(small, "nominal", tension=[0.0, -1e-8, 0.0, 0.0])


def test_rule_in_one_home(capped):
    from cdpm.dynamics.equilibrium import checked_tensions, onto_bounds, tension_bound_tolerance

    robot, _, f0 = capped
    F = robot.force_scale
    assert tension_bound_tolerance(f0, F) == pytest.approx(RTOL * max(F, f0[0]), rel=1e-15)
    # no absolute newton: the floor is the robot's force scale (its weight)
    assert tension_bound_tolerance(np.zeros(4), F) == RTOL * F
    assert F == pytest.approx(robot.mass * 9.81)
    f = _with(f0, c1=f0[0] + 0.5 * _tol(f0, F), c2=-0.5 * _tol(f0, F))
    clipped, beyond = onto_bounds(f, robot.tension_min, robot.tension_max, F)
    np.testing.assert_array_equal(clipped, f0)
    assert not beyond.any()
    np.testing.assert_array_equal(checked_tensions(robot, f), f0)
    out = checked_tensions(robot, [int(x) for x in np.zeros(4)])
    assert out.dtype == np.float64 and out.shape == (4,)
