"""The POC margin: continuity in (A, B, C), its horizon rule, the exact
signed inradius of the sampled hull, known values and its bracket."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial import ConvexHull

import cdpm
from cdpm.analysis import Verdict, positive_output_controllability
from cdpm.analysis._span_hull import min_norm_separator
from cdpm.analysis.margin import (
    margin_horizon,
    margin_horizons,
    planar_signed_inradii,
    signed_inradius,
)
from cdpm.analysis.poc import poc_margins
from tests.conftest import MODELS
from tests.test_analysis_properties import random_system

#: the mixed-cone YES pose whose old margin moved between 0.014 and 0.094
#: with 1e-15 relative changes of A (horizon picked by QR pivots)
POSE = np.array([1.97433856, -2.56406776])


def perturbed(X, rng, rel):
    return X * (1.0 + rel * rng.normal(size=X.shape))


def margin_change(A, B, C, mask, rel, seeds=4):
    """Largest relative change of the margin over ``seeds`` perturbations of
    every entry of A, B and C by ``rel`` (relative)."""
    base = positive_output_controllability(A, B, C, mask)
    m0 = base.margin
    worst = 0.0
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        res = positive_output_controllability(
            perturbed(A, rng, rel), perturbed(B, rng, rel), perturbed(C, rng, rel), mask
        )
        if res.verdict is not base.verdict:
            # the verdict itself is not continuous (clipping to <= 0 for NO)
            continue
        worst = max(worst, abs(res.margin - m0) / max(abs(m0), 1e-12))
    return base, worst


@pytest.fixture(scope="module")
def vertical():
    return cdpm.load_robot(MODELS / "two_link_vertical")


def test_margin_is_continuous_at_the_reported_pose(vertical):
    lin = cdpm.linearise(vertical, POSE)
    A, B, C, mask = lin.A, lin.B_cone, lin.C, lin.sign_constrained
    for rel in (1e-15, 1e-12):
        base, worst = margin_change(A, B, C, mask, rel, seeds=8)
        assert base.verdict is Verdict.YES and base.method == "mixed-cone"
        assert base.margin > 0
        assert worst < 1e-6, (rel, worst)


@pytest.mark.parametrize("kind", ["real", "complex", "mechanical", "nilpotent"])
@pytest.mark.parametrize("p", [1, 2, 3, 4])
def test_margin_is_continuous_at_random_systems(kind, p):
    for seed in range(4):
        A, B, C, mask = random_system(100 + seed, 6, 4, p, kind)
        base, worst = margin_change(A, B, C, mask, 1e-12, seeds=2)
        assert worst < 1e-6, (seed, kind, p, base.verdict, base.margin, worst)


def test_margin_is_continuous_at_two_link_vertical_poses(vertical):
    rng = np.random.default_rng(11)
    seen = 0
    for q in rng.uniform(-math.pi, math.pi, size=(12, 2)):
        try:
            lin = cdpm.linearise(vertical, q)
        except cdpm.InfeasibleEquilibriumError:
            continue
        seen += 1
        for mask in (lin.sign_constrained, None):
            base, worst = margin_change(lin.A, lin.B_cone, lin.C, mask, 1e-12, seeds=2)
            assert worst < 1e-6, (q, base.verdict, base.method, base.margin, worst)
            assert (base.margin > 0) == (base.verdict is Verdict.YES), (q, base)
    assert seen >= 5


# ---------------------------------------------------------------- horizon


def test_horizon_of_zero_tension_mechanical_system_is_one():
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    B = np.vstack([np.zeros((2, 3)), np.random.default_rng(0).normal(size=(2, 3))])
    C = np.hstack([np.random.default_rng(1).normal(size=(2, 2)), np.zeros((2, 2))])
    assert margin_horizon(A, B, C) == 1.0
    assert margin_horizon(A) == 1.0


def test_horizon_is_continuous_as_a_stiffness_vanishes():
    # x'' = k x: period 2 pi / sqrt(-k) (k < 0), time constant 1 / sqrt(k);
    # slow modes (|lambda| < 3 pi / 1000 |A|) count as integrators: T -> 1
    def T(k):
        return margin_horizon(np.array([[0.0, 1.0], [k, 0.0]]))

    assert T(-1.0) == pytest.approx(6 * math.pi)  # three periods
    assert T(0.0) == 1.0
    for k in (1e-8, -1e-8, 1e-12, -1e-14):
        assert T(k) == pytest.approx(1.0, abs=1e-12)
    ks = -np.geomspace(1e-7, 1e-3, 400)
    Ts = np.array([T(k) for k in ks])
    # the taper: no jump between neighbouring stiffnesses
    assert np.max(np.abs(np.diff(Ts))) < 0.05 * Ts.max()
    assert Ts.max() == pytest.approx(1000.0, rel=1e-2)


def test_horizon_sees_the_sign_change_of_a_nilpotent_curve():
    # g(t) = C b + t C A b = 4 - t: the curve crosses 0 at t = 4
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[4.0, 1.0], [-1.0, 0.0]])
    C = np.array([[1.0, 0.0]])
    assert margin_horizon(A, B, C) == pytest.approx(8.0)
    res = positive_output_controllability(A, B, C)
    assert res.verdict is Verdict.YES
    # hull of g_1 on [0, 8] = [-4, 4], g_2 = 1 - 0 t = 1: margin 4
    assert res.margin == pytest.approx(4.0)


def test_horizon_stops_growth_at_1e8():
    # stiffness -0.01 (period 20 pi) next to +1 (growth rate 1)
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 0], A[3, 1] = -0.01, 1.0
    assert margin_horizon(A) == pytest.approx(math.log(1e8))
    A[3, 1] = 0.0  # without the growing mode: three periods of the slow one
    assert margin_horizon(A) == pytest.approx(60 * math.pi)


# ---------------------------------------------------------------- known values


def test_paper_margin_is_a_quarter():
    # g = t CAB with CAB = (0.25, -3.019, -0.1685, -1.077) (eqs 24-26), T = 1
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    B = np.zeros((4, 4))
    B[2] = [0.500, -0.046, -0.337, -0.822]
    B[3] = [-1.000, 3.088, 0.674, 2.310]
    C = np.array([[-1.5, -1.0, 0.0, 0.0]])
    res = positive_output_controllability(A, B, C)
    assert res.margin_horizon == 1.0
    assert res.margin == pytest.approx(0.25, abs=1e-12)
    assert res.margin_bracket == pytest.approx((0.25, 0.25), abs=1e-12)
    # and linear in a fixed horizon
    assert positive_output_controllability(A, B, C, horizon=3.0).margin == pytest.approx(0.75)


def test_double_integrator_with_opposed_inputs_hand_worked():
    # g_1 = (t, 1), g_2 = (-t, -1) with output (x, x')
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0, 0.0], [1.0, -1.0]])
    res = positive_output_controllability(A, B, np.eye(2))
    assert res.verdict is Verdict.YES
    assert res.margin_horizon == pytest.approx(2.0)  # 2 |C b| / |C A b|
    # on T = 2: vertices (0, +-1), (+-2, +-1): the edge from (0, 1) to
    # (-2, -1) is at distance |(-2)(1) - (0)(-1)| / sqrt(8) = 1 / sqrt 2
    assert res.margin == pytest.approx(1 / math.sqrt(2), abs=1e-12)
    pos = positive_output_controllability(A, B, np.array([[1.0, 0.0]]))
    assert pos.margin == pytest.approx(1.0, abs=1e-12)  # |g| = t on [0, 1]


def test_free_inputs_count_with_both_signs():
    # x'' = u, output x: g = t; pulling only: NO (margin 0: g(0) = 0 is in
    # the hull); free in sign: +-t on [0, 1], margin 1
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0]])
    res = positive_output_controllability(A, B, C)
    assert res.verdict is Verdict.NO and res.margin == 0.0
    res = positive_output_controllability(A, B, C, [False])
    assert res.verdict is Verdict.YES
    assert res.margin == pytest.approx(1.0, abs=1e-12)
    # input scales multiply the curve (tension bounds), output weights its rows
    res = positive_output_controllability(A, B, C, [False], input_scale=[3.0], output_weight=[2.0])
    assert res.margin == pytest.approx(6.0, abs=1e-12)


# ---------------------------------------------------------------- geometry


def _qhull_signed(P):
    hull = ConvexHull(P.T)
    off = hull.equations[:, -1]
    if np.all(off < 0):
        return float(-off.max())
    sep = min_norm_separator(P)
    return 0.0 if sep is None else -float(sep[1])


@pytest.mark.parametrize("p", [2, 3])
def test_signed_inradius_matches_qhull_and_min_norm(p):
    rng = np.random.default_rng(p)
    for shift in np.linspace(0.0, 3.0, 12):
        for k in (5, 40, 300):
            P = rng.normal(size=(p, k)) + shift
            lo, hi = signed_inradius(P)
            assert lo == hi
            assert lo == pytest.approx(_qhull_signed(P), abs=1e-10), (shift, k)


def test_planar_inradius_of_long_thin_hulls():
    # points along a growing direction (as a fast unstable mode makes them)
    t = np.linspace(0.0, 1.0, 400)
    u = np.array([1.0, 4.5]) / math.hypot(1.0, 4.5)
    w = np.array([-u[1], u[0]])
    P = np.hstack(
        [
            np.outer(u, np.exp(12 * t)) + np.outer(w, np.sin(5 * t)),
            -np.outer(u, np.exp(12 * t)) - np.outer(w, np.cos(3 * t)),
        ]
    )
    assert signed_inradius(P)[0] == pytest.approx(_qhull_signed(P), rel=1e-9)


def test_batched_planar_inradii_equal_qhull_and_degenerate_hulls():
    """planar_signed_inradii (quickhull over many clouds at once) against
    Qhull on random clouds of different sizes, offsets and aspect ratios,
    and on hulls Qhull cannot take: a point, a segment, collinear points."""
    rng = np.random.default_rng(7)
    clouds = []
    for shift in np.linspace(0.0, 3.0, 7):
        for aspect in (1.0, 1e-3, 1e3):
            P = rng.normal(size=(2, 60)) * np.array([[1.0], [aspect]]) + shift
            clouds.append(P)
    t = np.linspace(0.0, 2 * np.pi, 1000, endpoint=False)
    clouds.append(np.stack([np.cos(t), np.sin(t)]) + 0.3)  # every point a vertex
    clouds.append(np.repeat(rng.normal(size=(2, 5)), 12, axis=1)[:, :60])  # duplicates
    got = planar_signed_inradii(np.stack([c[:, :60] for c in clouds]))
    for g, P in zip(got, clouds, strict=True):
        assert g == pytest.approx(_qhull_signed(P[:, :60]), rel=1e-9, abs=1e-12)
    circle = planar_signed_inradii(clouds[-2][None])[0]
    assert circle == pytest.approx(1.0 - 0.3 * math.sqrt(2.0), rel=1e-5)
    point = np.array([[[1.0, 1.0], [2.0, 2.0]]])
    assert planar_signed_inradii(point)[0] == pytest.approx(-math.hypot(1.0, 2.0))
    through_zero = np.array([[[1.0, -1.0, 0.5], [1.0, -1.0, 0.5]]])
    assert planar_signed_inradii(through_zero)[0] == pytest.approx(0.0, abs=1e-15)
    off_line = np.array([[[1.0, 2.0, 3.0], [1.0, 1.0, 1.0]]])
    assert planar_signed_inradii(off_line)[0] == pytest.approx(-math.sqrt(2.0))


def test_batched_margins_equal_the_analyser_one_system_at_a_time():
    """poc_margins (horizons, curves and hulls for many systems at once)
    equals POCResult.margin system by system, for p = 1, 2, 3, mixed cones
    and verdicts of every kind."""
    checked = {}
    for p in (1, 2, 3):
        systems = [random_system(seed, 4, 4, p, "mechanical") for seed in range(12)]
        A, B, C, mask = (np.stack(x) for x in zip(*systems, strict=True))
        results = [positive_output_controllability(*s[:3], s[3]) for s in systems]
        yes = np.array([r.verdict is Verdict.YES for r in results])
        got = poc_margins(A, B, C, mask, yes)
        want = np.array([r.margin for r in results])
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14)
        checked[p] = (int(yes.sum()), int((~mask.all(axis=1)).sum()))
    assert all(n_yes > 0 for n_yes, _ in checked.values()), checked
    assert any(mixed > 0 for _, mixed in checked.values()), checked


def test_batched_horizons_equal_the_scalar_rule():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(20, 4, 4))
    A[:5] = np.triu(A[:5], 1)  # nilpotent
    A[5] = 0.0
    B, C = rng.normal(size=(20, 4, 3)), rng.normal(size=(20, 2, 4))
    got = margin_horizons(A, B, C)
    for i in range(20):
        assert got[i] == margin_horizon(A[i], B[i], C[i])


def test_p4_bracket_contains_the_inradius_of_a_cube():
    P = np.hstack([np.eye(4), -np.eye(4)]) * 2.0  # cross-polytope: inradius 2 / 2 = 1
    lo, hi = signed_inradius(P)
    assert lo <= 1.0 + 1e-9 <= hi + 2e-9
    assert lo == pytest.approx(1.0)  # r1 = 2, r1 / sqrt(4) = 1


def test_bracket_contains_a_dense_estimate():
    checked = 0
    for seed in range(40):
        A, B, C, mask = random_system(seed, 4, 4, 2, "complex")
        if not mask.all():
            continue
        res = positive_output_controllability(A, B, C, mask)
        if res.verdict is not Verdict.YES:
            continue
        T = res.margin_horizon
        ts = np.linspace(0.0, T, 63 * 64 + 1)  # contains the margin's 64 grid times
        E = expm(A * (ts[1] - ts[0]))
        X, G = B.copy(), []
        for _ in ts:
            G.append(C @ X)
            X = E @ X
        dense = signed_inradius(np.hstack(G))[0]
        lo, hi = res.margin_bracket
        tol = 1e-7 * abs(dense)  # round-off of 4000 steps of a growing system
        assert lo <= dense + tol and dense <= hi + tol, (seed, lo, dense, hi)
        checked += 1
    assert checked >= 3


def test_a_given_horizon_beyond_what_the_margin_resolves_is_refused_with_the_longest():
    # x' = 0.5 x grows by e^500 within 1000: the margin used to come out NaN
    # through numpy's overflow warnings
    A = np.diag([0.5, -1.0])
    B = np.array([[1.0, -1.0], [1.0, 1.0]])
    longest = math.log(1e8) / 0.5  # growth 1e8 with two outputs
    with pytest.raises(cdpm.InputError, match=r"at most 36\.84"):
        positive_output_controllability(A, B, np.eye(2), horizon=1e3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        at_bound = positive_output_controllability(A, B, np.eye(2), horizon=longest)
        assert np.isfinite(at_bound.margin)
    # a system that does not grow: at most 1e6 of its time units (here 1:
    # |A|_2 = 1 and A^2 = 0), where a horizon of 1e200 overflowed
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0, 0.0], [1.0, -1.0]])
    with pytest.raises(cdpm.InputError, match=r"at most 1e\+06"):
        positive_output_controllability(A, B, np.eye(2), horizon=1e200)
    # both bounds passed: the message names the smaller (what is accepted)
    with pytest.raises(cdpm.InputError, match=r"at most 36\.84"):
        positive_output_controllability([[0.5]], [[1.0, -1.0]], [[1.0]], horizon=1e9)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isfinite(positive_output_controllability(A, B, np.eye(2), horizon=1e6).margin)
    # A = 0: the responses are constant, any horizon is fine
    assert positive_output_controllability(
        np.zeros((1, 1)), np.array([[1.0, -1.0]]), np.eye(1), horizon=1e300
    ).margin == pytest.approx(1.0)
