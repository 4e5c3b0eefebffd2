"""Known answers for the analysis layer: hand-worked systems, the paper's
example (eqs 24-30), spans, wrench closure, ranks and input validation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdpm.analysis import (
    Verdict,
    controllability,
    output_controllability,
    positive_controllability,
    positive_output_controllability,
    positively_spans,
    wrench_closure,
)
from cdpm.errors import InputError
from tests.conftest import MODELS


def poc_checked(A, B, C, mask=None, **kw):
    """POC with its certificate re-checked on every YES / NO verdict."""
    res = positive_output_controllability(A, B, C, mask, **kw)
    if res.verdict is not Verdict.MARGINAL:
        assert res.certificate.verify(A, B, C), res
    assert (res.margin > 0) == (res.verdict is Verdict.YES)
    json.dumps(res.as_dict())
    return res


def second_order(k: float, d: float) -> np.ndarray:
    """x'' = k x - d x' as a first-order system."""
    return np.array([[0.0, 1.0], [k, -d]])


@pytest.fixture
def paper():
    """The paper's linearisation at (pi/6, pi/3), eqs 24-26."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    B = np.zeros((4, 4))
    B[2] = [0.500, -0.046, -0.337, -0.822]
    B[3] = [-1.000, 3.088, 0.674, 2.310]
    C = np.array([[-1.5, -1.0, 0.0, 0.0]])
    return A, B, C


POS = np.array([[1.0, 0.0]])


# ---------------------------------------------------------------- hand-worked


def test_double_integrator_one_pulling_input_is_not_poc():
    res = poc_checked(second_order(0, 0), [[0.0], [1.0]], POS)
    assert res.verdict is Verdict.NO and not res
    assert res.method == "nilpotent"
    # x(t) = t u only grows: v = -1 separates
    assert res.certificate.separator[0] < 0


def test_double_integrator_two_opposed_inputs_is_poc():
    res = poc_checked(second_order(0, 0), [[0.0, 0.0], [1.0, -1.0]], POS)
    assert res.verdict is Verdict.YES and bool(res)
    assert res.margin == pytest.approx(1.0, abs=1e-12)  # T = 1, |g| = t


def test_double_integrator_with_a_free_input_is_poc():
    res = poc_checked(second_order(0, 0), [[0.0, 0.0], [1.0, 2.0]], POS, [True, False])
    assert res.verdict is Verdict.YES
    assert res.method == "mixed-cone"
    assert set(res.certificate.signs) == {1.0, -1.0}


def test_undamped_oscillator_one_pulling_input_is_poc():
    res = poc_checked(second_order(-1, 0), [[0.0], [1.0]], POS)
    assert res.verdict is Verdict.YES
    assert res.method == "modal"
    # sin(t) reaches +1 and -1 within the horizon
    assert res.margin == pytest.approx(1.0, abs=1e-3)


def test_unstable_oscillator_is_not_poc():
    res = poc_checked(second_order(1, 0), [[0.0], [1.0]], POS)
    assert res.verdict is Verdict.NO
    assert res.method == "modal"
    assert res.certificate.proof["kappa"] == pytest.approx(1.0)


@pytest.mark.parametrize(("damping", "verdict"), [(0.3, Verdict.YES), (3.0, Verdict.NO)])
def test_underdamped_poc_overdamped_not(damping, verdict):
    res = poc_checked(second_order(-1, damping), [[0.0], [1.0]], POS)
    assert res.verdict is verdict
    assert res.method == "general"


def test_overdamped_no_certificate_has_all_three_bounds():
    res = poc_checked(second_order(-1, 3.0), [[0.0], [1.0]], POS)
    proof = res.certificate.proof["inputs"][0]
    assert proof["taylor_order"] == 1 and proof["taylor_coefficient"] < 0
    assert proof["t1"] > 0 and proof["grid_end"] > proof["t1"]
    assert proof["tail_bound"] < 0


def test_jordan_block_defective_a():
    # A = [[-1, 1], [0, -1]] with the input on the second state: x1 = t e^{-t} u * ...
    A = np.array([[-1.0, 1.0], [0.0, -1.0]])
    B = np.array([[0.0, 0.0], [1.0, -1.0]])
    res = poc_checked(A, B, POS)
    assert res.verdict is Verdict.YES
    res = poc_checked(A, B[:, :1], POS)
    # g(t) = t e^{-t} >= 0: not POC; a defective A has no certified tail bound
    assert res.verdict in (Verdict.NO, Verdict.MARGINAL)
    assert res.verdict is not Verdict.YES


def test_repeated_eigenvalue_brammer():
    # A = -I: every vector is an eigenvector of A^T; two pulling inputs along
    # e1, e2 leave -e1 - e2 unreachable
    A = -np.eye(2)
    res = positive_controllability(A, np.eye(2))
    assert res.verdict is Verdict.NO
    assert res.verify(A, np.eye(2))
    assert np.all(res.witness_products <= 1e-12)
    # adding -(e1 + e2) makes the three inputs positively span the eigenspace R^2
    B3 = np.array([[1.0, 0.0, -1.0], [0.0, 1.0, -1.0]])
    assert positive_controllability(A, B3).verdict is Verdict.YES
    res = positive_output_controllability(A, B3, np.eye(2))
    assert res.verdict is Verdict.YES and res.method == "full-rank-brammer"
    assert res.certificate.verify(A, B3, np.eye(2))


# ---------------------------------------------------------------- the paper


def test_paper_poc_yes(paper):
    A, B, C = paper
    res = poc_checked(A, B, C)
    assert res.verdict is Verdict.YES and res.method == "nilpotent"
    # eq 28: C e^{At} B = t [0.250 -3.018 -0.169 -1.077]
    np.testing.assert_allclose(C @ A @ B, [[0.250, -3.018, -0.169, -1.077]], atol=1.5e-3)
    # the certificate pairs a positive and a negative output: inputs 1 and 2
    assert sorted(res.certificate.inputs.tolist()) == [0, 1]
    assert res.output_rank == 1 and res.output_controllable


def test_paper_positive_controllability_no_with_remark_11_witness(paper):
    A, B, _ = paper
    res = positive_controllability(A, B)
    assert res.verdict is Verdict.NO and res.method == "brammer"
    assert res.kalman_rank == 4
    v = res.witness / res.witness[3] * -1.0  # scale to (0, 0, -2, -1)
    np.testing.assert_allclose(v, [0, 0, -2, -1], atol=1e-9)
    # eq 30: v^T B = (0, -2.995, 0, -0.666) for v = (0, 0, -2, -1)
    prods = res.witness_products / res.witness[3] * -1.0
    np.testing.assert_allclose(prods, [0, -2.995, 0, -0.666], atol=1.5e-3)
    assert np.all(res.witness_products <= 1e-12)
    assert res.verify(A, B)
    assert "witness" in str(res)
    json.dumps(res.as_dict())


def test_paper_ranks(paper):
    A, B, C = paper
    assert controllability(A, B).rank == 4
    assert output_controllability(A, B, C).rank == 1
    assert controllability(A, B[:, :1]).rank == 2
    assert not controllability(A, B[:, :1])


def test_paper_scaled_keeps_verdicts(paper):
    A, B, C = paper
    D = np.diag([1e-3, 1e3, 1e-3, 1e3])
    Di = np.linalg.inv(D)
    As, Bs, Cs = Di @ A @ D, Di @ B * 1e3, C @ D * 1e-3
    assert poc_checked(As, Bs, Cs).verdict is Verdict.YES
    assert positive_controllability(As, Bs).verdict is Verdict.NO


def test_result_strings_and_html(paper):
    A, B, C = paper
    res = poc_checked(A, B, C)
    assert "YES" in str(res) and "nilpotent" in str(res)
    assert "<table>" in res._repr_html_()
    assert str(Verdict.MARGINAL) == "MARGINAL"


# ---------------------------------------------------------------- scaling


@pytest.mark.parametrize("seed", range(6))
def test_scaling_does_not_change_verdicts(seed):
    rng = np.random.default_rng(seed)
    n, m, p = 4, 3, 2
    A = rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    C = rng.normal(size=(p, n))
    base = positive_output_controllability(A, B, C)
    d = 10.0 ** rng.choice([-3, 3], size=n)
    D, Di = np.diag(d), np.diag(1 / d)
    As, Bs, Cs = Di @ A @ D * 1e3, Di @ B * 1e-3, C @ D * 1e3
    scaled = positive_output_controllability(As, Bs, Cs)
    if scaled.verdict is not Verdict.MARGINAL:
        assert scaled.certificate.verify(As, Bs, Cs)
    assert scaled.verdict is base.verdict
    # g_s(t) = g(1e3 t): on the same physical horizon the margin is the same
    # (the default horizon is in units of 1/|A|_2, which such coordinates
    # inflate by ~1e6: a documented limit)
    T = base.margin_horizon
    fixed = positive_output_controllability(As, Bs, Cs, horizon=T / 1e3)
    assert fixed.margin == pytest.approx(base.margin, rel=1e-6, abs=1e-12)
    assert (fixed.margin > 0) == (base.verdict is Verdict.YES)
    assert controllability(As, Bs).rank == controllability(A, B).rank
    assert output_controllability(As, Bs, Cs).rank == output_controllability(A, B, C).rank


# ---------------------------------------------------------------- spans


@pytest.mark.parametrize(
    ("vectors", "verdict"),
    [
        ([[1.0, -2.0]], Verdict.YES),
        ([[1.0, 2.0, 0.0]], Verdict.NO),
        ([[0.0, 0.0]], Verdict.NO),
        ([[1.0, 0.0, -1.0], [0.0, 1.0, -1.0]], Verdict.YES),
        ([[1.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0]], Verdict.NO),  # half-plane
        ([[1.0, -1.0, 2.0], [0.0, 0.0, 0.0]], Verdict.NO),  # rank 1
        ([[1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, -1.0], [0.0, 0.0, 1.0, -1.0]], Verdict.YES),
        ([[1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, -1.0], [0.0, 0.0, 1.0, 0.0]], Verdict.NO),
        ([[1.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0]], Verdict.NO),
    ],
)
def test_positively_spans_known_cases(vectors, verdict):
    res = positively_spans(vectors)
    assert res.verdict is verdict
    assert res.verify()
    assert (res.margin > 0) == (verdict is Verdict.YES)
    json.dumps(res.as_dict())
    assert str(res)


def test_positively_spans_margin_is_inradius():
    # the square's vertices (+-1, +-1): inradius about 0 is 1 (exact for p <= 3)
    S = np.array([[1.0, -1.0, -1.0, 1.0], [1.0, 1.0, -1.0, -1.0]])
    assert positively_spans(S).margin == pytest.approx(1.0)
    assert positively_spans(S).margin_bracket == pytest.approx((1.0, 1.0))
    # shifted away by 3 along x: distance from 0 to the square is 2
    assert positively_spans(S + [[3.0], [0.0]]).margin == pytest.approx(-2.0)


def test_positively_spans_margin_brackets_the_inradius_in_4d():
    # the 4-cube's vertices (+-1, ...): inradius 1; the largest cross-polytope
    # |y|_1 <= r inside has r = 1, so the margin is 1/sqrt(4) and hi >= 1
    S = np.array(np.meshgrid(*[[-1.0, 1.0]] * 4)).reshape(4, -1)
    lo, hi = positively_spans(S).margin_bracket
    assert lo == pytest.approx(0.5, rel=1e-7)
    assert hi >= 1.0 * (1 - 1e-7)
    # the cross-polytope |y|_1 <= 2 itself: the index is exact, 2/sqrt(4)
    D = np.hstack([2 * np.eye(4), -2 * np.eye(4)])
    lo, hi = positively_spans(D).margin_bracket
    assert lo == pytest.approx(1.0, rel=1e-7) and 1.0 - 1e-7 <= hi <= 2.0 + 1e-7


def test_positively_spans_separator_is_a_witness():
    S = np.array([[1.0, 0.5, 0.2], [0.1, 1.0, -0.3], [0.3, 0.2, 1.0]])
    res = positively_spans(S)
    assert res.verdict is Verdict.NO
    assert np.all(res.certificate.separator @ S <= 1e-12)


def test_span_certificate_rejects_wrong_vectors():
    res = positively_spans([[1.0, 0.0, -1.0], [0.0, 1.0, -1.0]])
    assert not res.certificate.verify([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])


# ---------------------------------------------------------------- wrench closure


def test_wrench_closure_planar_point_four_cables():
    # a point mass pulled by four cables towards the square's corners
    corners = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    L = -corners / np.linalg.norm(corners, axis=1, keepdims=True)  # l' = -u . x'
    res = wrench_closure(L)
    assert res.verdict is Verdict.YES and res.verify()
    res = wrench_closure(L[:3])
    assert res.verdict is Verdict.NO and res.verify()
    # two cables can never close a planar wrench space
    assert wrench_closure(L[:2]).verdict is Verdict.NO


def test_wrench_closure_needs_nv_plus_one_cables():
    rng = np.random.default_rng(3)
    L = rng.normal(size=(3, 3))
    assert wrench_closure(L).verdict is Verdict.NO


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.zeros((3, 3)), np.zeros((2, 1)), np.zeros((1, 3))), r"B has 2 rows, expected n=3"),
        ((np.zeros((3, 2)), np.zeros((3, 1)), np.zeros((1, 3))), r"A must be square"),
        ((np.zeros((3, 3)), np.zeros((3, 1)), np.zeros((1, 2))), r"C has 2 columns"),
        ((np.full((2, 2), np.nan), np.zeros((2, 1)), np.zeros((1, 2))), r"A contains non-finite"),
        ((np.zeros((2, 2)), [["a"], ["b"]], np.zeros((1, 2))), r"B must be a numeric matrix"),
    ],
)
def test_input_validation(args, match):
    with pytest.raises(InputError, match=match):
        positive_output_controllability(*args)


def _complex_inputs(robot):
    """name -> a call of the public API with one complex argument."""
    import cdpm

    z = np.array([0.1j, 0.2])
    c = np.complex128(2.0)
    m = robot.n_cables
    return {
        "spans": lambda: cdpm.positively_spans(np.array([[1, -1, 0, 0], [0, 0, 1j, -1]])),
        "poc": lambda: positive_output_controllability(np.eye(2) * 1j, np.eye(2), np.eye(2)),
        "scale": lambda: positive_output_controllability(
            np.eye(2), np.eye(2), np.eye(2), input_scale=[1j, 1.0]
        ),
        "pose": lambda: cdpm.analyze_pose(robot, z),
        "linearise": lambda: cdpm.linearise(robot, z),
        "poses": lambda: cdpm.evaluate_poses(robot, z[None]),
        "axis": lambda: cdpm.workspace_map(robot, {"q1": z, "q2": [0.0, 0.1]}),
        "tension": lambda: cdpm.check_equilibrium(robot, [0.1, 0.2], [1j] + [1.0] * (m - 1)),
        "target": lambda: cdpm.steer(robot, [0.1, 0.2], target=[1j, 0.1]),
        "profile": lambda: cdpm.simulate(robot, [0.1, 0.2], tension=[1j] * m, duration=0.1),
        "v0": lambda: cdpm.simulate(robot, [0.1, 0.2], [1j, 0], tension=[1.0] * m, duration=0.1),
        "verify": lambda: cdpm.positively_spans(np.eye(2)[:, [0, 0, 1, 1]] * [1, -1, 1, -1]).verify(
            np.eye(2)[:, [0, 0, 1, 1]] * [1, -1, 1, -1] + 1j
        ),
        # numpy complex scalars (np.complex128 is no Python float)
        "tol": lambda: cdpm.positively_spans(np.eye(2), tol=c),
        "horizon": lambda: positive_output_controllability(
            np.eye(2), np.eye(2), np.eye(2), horizon=c
        ),
        "pretension": lambda: cdpm.analyze_pose(robot, [0.1, 0.2], pretension=c),
        "reach horizon": lambda: cdpm.analyze_pose(robot, [0.1, 0.2], horizon=c),
        "budget": lambda: cdpm.analyze_pose(robot, [0.1, 0.2], tension_budget=c),
        "radius": lambda: cdpm.poc_neighbourhood(robot, [0.1, 0.2], radius=c),
        "duration": lambda: cdpm.steer(robot, [0.1, 0.2], target=[0.1], duration=c),
        "tolerance": lambda: cdpm.steer(robot, [0.1, 0.2], target=[0.1], tolerance=c),
        "cap": lambda: cdpm.best_tension(robot, [0.1, 0.2], tension_cap=c),
        "range": lambda: cdpm.sample_axes({"q1": (0.0, c)}, 10),
    }


COMPLEX_CALLS = [
    "spans", "poc", "scale", "pose", "linearise", "poses", "axis", "tension", "target", "profile",
    "v0", "verify", "tol", "horizon", "pretension", "reach horizon", "budget", "radius",
    "duration", "tolerance", "cap", "range",
]  # fmt: skip


@pytest.mark.parametrize("call", COMPLEX_CALLS)
def test_complex_input_is_refused_by_name(paper_robot, call):
    """Complex numbers raise an InputError that says so, not numpy's
    ComplexWarning with the imaginary parts dropped (warnings are errors
    here: none may be emitted first)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match=r"complex numbers are not accepted|real|np.complex"):
            _complex_inputs(paper_robot)[call]()


@pytest.mark.parametrize(
    ("q", "match"),
    [
        (None, "None is not a number"),
        ([None, 0.1], "None is not a number"),
        ([True, False], "booleans are not numbers"),
        ([[0.1], [0.2, 0.3]], "rows of different lengths"),
    ],
)
def test_non_numbers_are_named_not_read_as_nan_or_1(paper_robot, q, match):
    """None was read as nan ("q[0] = nan: ..."), True as 1, and a ragged
    list gave numpy's words; each is now named."""
    import cdpm

    with pytest.raises(InputError, match=match):
        cdpm.analyze_pose(paper_robot, q)
    with pytest.raises(InputError, match=match):
        cdpm.evaluate_poses(paper_robot, [q] if q is not None else q)


def test_a_pose_may_be_given_by_coordinate_names(paper_robot):
    """{coordinate: value} (numbers or arithmetic strings, as in a spec)
    is the same pose as the vector; an unknown name is refused by name."""
    import cdpm

    named = cdpm.analyze_pose(paper_robot, {"q1": 0.5, "q2": "pi/4"}, margin=False)
    vector = cdpm.analyze_pose(paper_robot, [0.5, np.pi / 4], margin=False)
    np.testing.assert_array_equal(named.linearisation.q, vector.linearisation.q)
    assert named.poc.verdict is vector.poc.verdict
    with pytest.raises(InputError, match="'q9' is not a joint or coordinate; valid: q1, q2"):
        cdpm.analyze_pose(paper_robot, {"q9": 1.0})
    # values as numpy, fractions or decimals give them; any Mapping will do
    import types
    from decimal import Decimal
    from fractions import Fraction

    q = paper_robot.as_q({"q1": 0.5, "q2": 0.25})
    for v in (np.float32(0.5), np.array(0.5), Fraction(1, 2), Decimal("0.5")):
        np.testing.assert_array_equal(paper_robot.as_q({"q1": v, "q2": 0.25}), q)
    np.testing.assert_array_equal(
        paper_robot.as_q(types.MappingProxyType({"q1": 0.5, "q2": 0.25})), q
    )
    with pytest.raises(InputError, match="q1: True is a boolean"):
        paper_robot.as_q({"q1": np.True_})


def test_a_free_flyer_pose_may_be_a_numpy_array():
    """{joint: array of its six natural coordinates} is the list's pose."""
    import cdpm

    robot = cdpm.load_robot(MODELS / "spatial_8cable" / "spatial_8cable.yaml")
    six = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    np.testing.assert_array_equal(
        robot.as_q({"platform_joint": np.array(six)}), robot.as_q({"platform_joint": six})
    )


def test_tensions_that_miss_the_statics_by_round_off_say_so(paper_robot):
    """Tensions with a few digits dropped (as printed) fail the statics by
    round-off; the refusal says how to give them instead."""
    import cdpm

    robot = cdpm.load_robot(MODELS / "two_link_vertical" / "two_link_vertical.yaml")
    f = cdpm.equilibrium_tension(robot, "horizontal").tension
    with pytest.raises(InputError, match="miss by round-off: give them to full precision"):
        cdpm.linearise(robot, "horizontal", tension=np.round(f, 6))
    with pytest.raises(InputError) as far:
        cdpm.linearise(robot, "horizontal", tension=2 * f)
    assert "round-off" not in str(far.value)


def test_out_of_range_arguments_are_refused_by_name(paper_robot):
    """Values whose arithmetic would over- or underflow, or that make no
    sense for the argument, give an InputError naming the limit, never a
    verdict on meaningless numbers (a pose at q1 = 1e300 was POC YES) or an
    error from inside numpy."""
    import cdpm

    robot, q = paper_robot, [0.5, 1.0]
    I2 = np.eye(2)
    B = np.hstack([I2, -I2])
    cases = [
        (lambda: cdpm.evaluate_poses(robot, [[1e300, 0.2]]), "magnitude above 100000"),
        (lambda: cdpm.workspace_map(robot, {"q1": [0.1, 1e300], "q2": [0.2]}), "above 100000"),
        (lambda: cdpm.sample_axes({"q1": (0.0, 1e300)}, 10), "within \\+-100000"),
        (lambda: cdpm.analyze_pose(robot, q, horizon=1e300), "at most 1e\\+06 s"),
        (lambda: cdpm.analyze_pose(robot, q, tension_budget=1e300), "at most 1e\\+12 N"),
        (lambda: cdpm.steer(robot, q, target=[0.1], duration=1e300), "from 1e-06 to 1e\\+06 s"),
        (lambda: cdpm.simulate(robot, q, tension=[1.0] * 4, duration=1e300), "to 1e\\+06 s"),
        (lambda: cdpm.positively_spans(B, tol=np.nan), "tol must be an angle in \\(0, 1\\)"),
        (lambda: cdpm.positively_spans(B, tol=10), "tol must be an angle"),
        (lambda: positive_output_controllability(I2, B, I2, tol=-1), "tol must be an angle"),
        (lambda: positive_output_controllability(I2, B, None), "C \\(the output matrix"),
        (lambda: positive_output_controllability(I2, 1e-200 * B, I2), "largest entry is 1e-200"),
        (lambda: positive_output_controllability(1e200 * I2, B, I2), "largest entry is 1e\\+200"),
        (lambda: cdpm.output_controllability(I2, 1e160 * I2, I2), "express the model in other"),
        (lambda: cdpm.positively_spans(B).verify(B[:, :3]), "do not fit this certificate"),
        (lambda: cdpm.workspace_map(robot, {"q1": [0.1, np.ones(2)], "q2": [0.2]}), "ragged"),
    ]
    for call, match in cases:
        with pytest.raises(InputError, match=match):
            call()
    # inside the range the verdicts do not depend on the scale
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    for s in (1e-99, 1e99):
        assert positive_output_controllability(A, s * B, I2).verdict is Verdict.YES
        assert positive_output_controllability(s * A, B, I2).verdict is Verdict.YES


def test_mask_validation():
    with pytest.raises(InputError, match=r"sign_constrained has shape \(3,\), expected"):
        positive_output_controllability(
            np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((1, 2)), [True, False, True]
        )
    with pytest.raises(InputError, match="input_scale must be finite and strictly positive"):
        positive_output_controllability(
            np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((1, 2)), input_scale=[1.0, -1.0]
        )
    with pytest.raises(InputError, match="horizon must be a positive"):
        positive_output_controllability(
            np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((1, 2)), horizon=0.0
        )
    with pytest.raises(InputError, match="L must be 2-D"):
        wrench_closure(np.zeros(3))


def test_caller_arrays_are_not_mutated(paper):
    A, B, C = paper
    copies = [X.copy() for X in (A, B, C)]
    positive_output_controllability(A, B, C).margin  # noqa: B018
    positive_controllability(A, B)
    for X, Y in zip((A, B, C), copies, strict=True):
        np.testing.assert_array_equal(X, Y)


def test_lapack_helpers_agree_with_numpy():
    from cdpm.analysis._common import eigh, qr_pivots, svd, svdvals

    rng = np.random.default_rng(7)
    for shape in ((6, 16), (16, 6), (3, 3), (1, 5)):
        X = rng.normal(size=shape)
        np.testing.assert_allclose(svdvals(X), np.linalg.svd(X, compute_uv=False), rtol=1e-12)
        U, s, Vt = svd(X)
        np.testing.assert_allclose((U * s) @ Vt, X, atol=1e-12)
        U, s, Vt = svd(X, full_matrices=True)
        assert U.shape == (shape[0], shape[0]) and Vt.shape == (shape[1], shape[1])
        w, V = eigh(X @ X.T)
        np.testing.assert_allclose((V * w) @ V.T, X @ X.T, atol=1e-10)
        piv, r = qr_pivots(X)
        assert sorted(piv.tolist()) == list(range(shape[1]))
        assert np.all(np.diff(r) <= 1e-12)  # non-increasing |R_kk|
        # the first pivots span the column space
        k = min(shape)
        assert np.linalg.matrix_rank(X[:, piv[:k]]) == np.linalg.matrix_rank(X)
    assert svdvals(np.zeros((3, 0))).size == 0


def test_batch_rank_exit_matches_the_singular_value_ratio():
    """The exits' exact rank test (the SVD of the column-normalised matrix)
    decides as the singular-value ratio against RANK_RATIO does: on
    matrices whose ratio is within 2% of the threshold (two unit columns at
    angle theta have the ratio tan(theta / 2)), clearly deficient and
    clearly full ones, zero ones and ones with a negligible column."""
    from cdpm.analysis.exits import _full_rank
    from cdpm.numerics import KRYLOV_COLUMN_NEGLIGIBLE, RANK_RATIO

    rng = np.random.default_rng(3)
    for r in [2, 4, 12]:
        k = 400
        ratio = RANK_RATIO * np.exp(rng.uniform(-0.02, 0.02, k))
        ratio[:40] *= 1e-3  # clearly deficient
        ratio[40:80] *= 1e3  # clearly full
        theta = 2 * np.arctan(ratio)
        S = np.tile(np.eye(r), (k, 1, 1))
        S[:, 0, 1], S[:, 1, 1] = np.cos(theta), np.sin(theta)
        S = np.linalg.qr(rng.normal(size=(k, r, r)))[0] @ S  # rotated: same ratio
        S *= rng.uniform(0.5, 2.0, size=(k, 1, r))  # column scales: normalised away
        S[80:90] = 0.0
        S[90:100, :, 0] *= 0.1 * KRYLOV_COLUMN_NEGLIGIBLE  # a negligible column
        norms = np.linalg.norm(S, axis=1)
        keep = norms > KRYLOV_COLUMN_NEGLIGIBLE * norms.max(axis=1, keepdims=True)
        Sn = np.where(keep[:, None], S / np.where(keep, norms, 1.0)[:, None], 0.0)
        sv = np.linalg.svd(Sn, compute_uv=False)
        expected = sv[:, -1] > RANK_RATIO * sv[:, 0]
        assert 50 < expected[100:].sum() < 250  # both sides of the threshold
        assert expected[40:80].all() and not expected[:40].any() and not expected[80:100].any()
        np.testing.assert_array_equal(_full_rank(S), expected)


def test_batched_matrix_exponential_matches_scipy():
    """expm_batch (Pade [13/13] with scaling and squaring over a stack)
    equals scipy.linalg.expm to round-off on random, nilpotent, defective,
    zero, diagonal and mechanical (A = [[0, I], [-K, -D]]) matrices of sizes
    1 to 12 and norms from 1e-8 to about 1e3 (relative to the largest entry;
    the exponential's own conditioning grows with the norm)."""
    from scipy.linalg import expm

    from cdpm.analysis._common import expm_batch

    rng = np.random.default_rng(7)
    for n in (1, 2, 4, 7, 12):
        A = rng.normal(size=(60, n, n)) * np.logspace(-8, 2, 60)[:, None, None]
        A[0] = 0.0
        A[1] = np.triu(rng.normal(size=(n, n)), 1)  # nilpotent
        A[2] = 0.7 * np.eye(n) + np.eye(n, k=1)  # defective (Jordan block)
        A[3] = np.diag(rng.uniform(-20, 5, n))
        if n % 2 == 0:
            h = n // 2
            K, D = rng.uniform(0, 50, (h, h)), rng.uniform(0, 2, (h, h))
            A[4] = np.block([[np.zeros((h, h)), np.eye(h)], [-(K @ K.T), -(D @ D.T)]])
        expected = expm(A)
        got = expm_batch(A)
        scale = np.abs(expected).max(axis=(1, 2), keepdims=True)
        norm = np.abs(A).sum(axis=1).max(axis=1)[:, None, None]
        error = (np.abs(got - expected) / scale).max(axis=(1, 2))
        np.testing.assert_array_less(error, 1e-13 * (1.0 + norm[:, 0, 0]))
    assert expm_batch(np.zeros((0, 3, 3))).shape == (0, 3, 3)


def test_compiled_rank_exits_decide_as_the_singular_value_ratio():
    """free_controllable and output_controllable (the compiled Krylov rank
    test, _full_rank where it is unsure) decide as _full_rank on the Krylov
    matrices built with numpy: on Krylov matrices [S, 0, ...] (A = 0) whose
    singular-value ratio is within 2% of RANK_RATIO, and on random systems,
    controllable, uncontrollable (a mode untouched by the inputs) and with
    sign-constrained, zero and negligible inputs."""
    from cdpm.analysis.exits import _full_rank, free_controllable, output_controllable
    from cdpm.numerics import RANK_RATIO
    from cdpm.verdicts import YES

    rng = np.random.default_rng(5)
    for r in [2, 4, 12]:
        k = 300
        ratio = RANK_RATIO * np.exp(rng.uniform(-0.02, 0.02, k))
        theta = 2 * np.arctan(ratio)
        S = np.tile(np.eye(r), (k, 1, 1))
        S[:, 0, 1], S[:, 1, 1] = np.cos(theta), np.sin(theta)
        Q = np.linalg.qr(rng.normal(size=(k, r, r)))[0]
        S = (Q @ S) * rng.uniform(0.5, 2.0, size=(k, 1, r))
        expected = _full_rank(S)
        assert 50 < expected.sum() < 250
        A, mask = np.zeros((k, r, r)), np.zeros((k, r), dtype=bool)
        np.testing.assert_array_equal(free_controllable(A, S, mask) == YES, expected)
        C = np.linalg.qr(rng.normal(size=(k, r, r)))[0]  # rotates: the same ratio
        np.testing.assert_array_equal(output_controllable(A, S, C) == YES, expected)

    def krylov(A, W, C=None):
        blocks = []
        for _ in range(A.shape[1]):
            blocks.append(W if C is None else C @ W)
            W = A @ W
        return np.concatenate(blocks, axis=2)

    k, n, m, p = 400, 6, 3, 2
    A = rng.normal(size=(k, n, n))
    B = rng.normal(size=(k, n, m))
    C = rng.normal(size=(k, p, n))
    mask = rng.random((k, m)) < 0.4
    B[::7, :, 0] = 0.0
    B[1::7, :, 1] *= 1e-14
    # a mode the inputs do not reach: A block triangular, B zero below
    A[:100, n - 2 :, : n - 2] = 0.0
    B[:100, n - 2 :] = 0.0
    C[:50, :, : n - 2] = 0.0  # ... and outputs that see only it
    free = np.any(~mask & np.any(B != 0, axis=1), axis=1)
    yes = free_controllable(A, B, mask) == YES
    expected = np.zeros(k, dtype=bool)
    expected[free] = _full_rank(krylov(A[free], (B * ~mask[:, None])[free]))
    np.testing.assert_array_equal(yes, expected)
    assert 100 < yes.sum() < 300 and not yes[:100].any()
    for W in (B, B * ~mask[:, None]):
        out = output_controllable(A, W, C) == YES
        np.testing.assert_array_equal(out, _full_rank(krylov(A, W, C)))
        assert not out[:50].any() and out[50:].sum() > 200
