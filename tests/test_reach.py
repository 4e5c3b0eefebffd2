"""The reach margin r_T: hand-worked values, independent references,
continuity, one horizon per map, and the CLI options."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial import ConvexHull

import cdpm
from cdpm.analysis.reach import reach_margin, zonotope_inradii
from cdpm.cli import main
from cdpm.dynamics.reach import reach_bounds, reach_margins_at, reach_settings
from cdpm.errors import InputError
from cdpm.pipeline.evaluate import evaluate_batch
from tests.conftest import MODELS, PAPER_SPEC
from tests.paper_model import paper_L, paper_M, paper_tip_x_gradient

VERTICAL = MODELS / "two_link_vertical" / "two_link_vertical.yaml"


@pytest.fixture(scope="module")
def vertical():
    return cdpm.load_robot(VERTICAL)


# --------------------------------------------------------------------------
# the zonotope inradius against a convex hull of its vertices


@pytest.mark.parametrize("p", [2, 3])
def test_zonotope_inradius_equals_the_hull_of_its_vertices(p):
    rng = np.random.default_rng(p)
    for _ in range(5):
        D = rng.normal(size=(p, 6))
        c = 0.3 * rng.normal(size=p)
        signs = np.array(list(itertools.product([-1.0, 1.0], repeat=6)))  # (64, 6)
        hull = ConvexHull(c + signs @ D.T)
        # 0 inside: the least distance to a facet plane (n.x + off <= 0 inside)
        expected = max(0.0, float(-hull.equations[:, -1].max()))
        got = zonotope_inradii(D[None], c[None])[0]
        assert got == pytest.approx(expected, rel=1e-10, abs=1e-12)


def _inradius_by_every_facet(D, c):
    """Reference: the plain search over every (p-1)-subset of generators,
    normals from the SVD, no bounds, no sweep; (k,) before clipping."""
    k, p, N = D.shape
    out = np.full(k, np.inf)
    for s in range(k):
        for subset in itertools.combinations(range(N), p - 1):
            S = D[s][:, subset]
            if p > 1 and np.linalg.matrix_rank(S, tol=1e-9 * np.abs(S).max()) < p - 1:
                continue
            n = np.linalg.svd(S.T)[2][-1] if p > 1 else np.ones(1)
            out[s] = min(out[s], np.abs(n @ D[s]).sum() - abs(n @ c[s]))
    return np.maximum(out, 0.0)


@pytest.mark.parametrize("p", [2, 3, 4, 6])
def test_the_compiled_facet_search_equals_the_plain_one(p):
    """The kernel's sweep (p = 2), run and ceiling bounds (p = 3) and
    pruned enumeration (p >= 4) return the plain search's least facet, on
    awkward generator sets: parallel and antiparallel pairs, zero
    generators, generators on the axes, centres inside and outside, and
    every run length (``group``)."""
    rng = np.random.default_rng(10 + p)
    N = {2: 24, 3: 18, 4: 12, 6: 9}[p]
    k = 40
    D = rng.normal(size=(k, p, N)) * rng.uniform(0.01, 5.0, size=(k, 1, N))
    D[:8, :, 1] = 2.0 * D[:8, :, 0]  # parallel
    D[8:16, :, 3] = -0.5 * D[8:16, :, 2]  # antiparallel
    D[16:20, :, 4] = 0.0  # a zero generator
    D[20:24, 1:, :3] = 0.0  # on the first axis
    D[24:28, 0, 5:8] = 0.0  # in the other coordinates' plane
    # centres up to about the zonotope's size: 0 inside some, outside others
    reach = np.linalg.norm(D, axis=1).sum(axis=1, keepdims=True) / p
    c = rng.normal(size=(k, p)) * rng.uniform(0.0, 1.5, size=(k, 1)) * reach
    c[:4] = 0.0
    expected = _inradius_by_every_facet(D, c)
    assert (expected > 0).sum() >= 5 and (expected == 0).sum() >= 3  # both kinds
    for group in [g for g in range(1, N + 1) if N % g == 0]:
        got = zonotope_inradii(D, c, group=group)
        np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)


def test_flat_and_shifted_zonotopes_have_zero_inradius():
    D = np.array([[[1.0, 2.0, -1.0], [0.0, 0.0, 0.0]]])  # all on the x axis
    assert zonotope_inradii(D, np.zeros((1, 2)))[0] == 0.0
    D3 = np.array([[[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]])  # spans a plane only
    assert zonotope_inradii(D3, np.zeros((1, 3)))[0] == 0.0
    # 0 outside: the box [1, 3] x [-1, 1] does not contain 0
    D = np.array([[[1.0, 0.0], [0.0, 1.0]]])
    assert zonotope_inradii(D, np.array([[2.0, 0.0]]))[0] == 0.0


# --------------------------------------------------------------------------
# hand-worked values


@pytest.mark.parametrize("p", [2, 3])
def test_margins_do_not_depend_on_the_batch_they_are_computed_in(p, monkeypatch):
    """A system's r_T is the same to the last bit alone, in a batch and in
    the quadrature's blocks (QUADRATURE_BLOCK_BYTES): a map stores the
    per-pose function's value whatever its chunk. The zonotope's centre was
    summed by einsum, whose order depends on the batch size: one system in
    a block of its own differed from the batch in its last bit."""
    import cdpm.analysis.reach as reach

    rng = np.random.default_rng(p)
    k, n, m = 11, 4, 5
    A = rng.normal(size=(k, n, n)) - 2.0 * np.eye(n)
    B, C = rng.normal(size=(k, n, m)), rng.normal(size=(k, p, n))
    lower, upper = -rng.random((k, m)), rng.random((k, m))
    whole = reach.reach_margins(A, B, C, lower, upper, 0.7)
    alone = [
        reach.reach_margins(*(x[i : i + 1] for x in (A, B, C, lower, upper)), 0.7) for i in range(k)
    ]
    nodes = reach.reach_nodes(p) + 1
    # blocks of 3 systems: 4 blocks, the last of 2
    monkeypatch.setattr(reach, "QUADRATURE_BLOCK_BYTES", 3 * 8 * n * nodes * m)
    blocks = reach.reach_margins(A, B, C, lower, upper, 0.7)
    assert np.all(whole.value > 0) and np.all(whole.error < whole.value)
    np.testing.assert_array_equal(blocks.value, whole.value)
    np.testing.assert_array_equal(blocks.error, whole.error)
    for i, one in enumerate(alone):
        np.testing.assert_array_equal(one.value, whole.value[i : i + 1])
        np.testing.assert_array_equal(one.error, whole.error[i : i + 1])


def test_double_integrator_by_hand():
    # x'' = u, y = x, u in [-1, 2]: y(T) ranges over [-T^2/2, T^2]: r = T^2/2
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0]])
    r, err = reach_margin(A, B, C, [-1.0], [2.0], 3.0)
    assert r == pytest.approx(4.5, rel=1e-12) and err == 0.0
    # pulling only (u in [0, 2]): y(T) >= 0, no ball about 0
    assert reach_margin(A, B, C, [0.0], [2.0], 3.0)[0] == 0.0


def test_first_order_system_by_hand():
    # x' = -a x + u, y = x, u in [-1, 1]: y(T) in +-(1 - e^{-aT}) / a
    a, T = 2.0, 0.7
    r, err = reach_margin(np.array([[-a]]), np.array([[1.0]]), np.array([[1.0]]), [-1.0], [1.0], T)
    exact = (1 - np.exp(-a * T)) / a
    assert abs(r - exact) <= max(err, 1e-12)
    assert r == pytest.approx(exact, rel=1e-8)


def test_paper_nominal_pose_equals_its_closed_form():
    """Zero tension, A^2 = 0: r_T = (T^2/2) F min(sum c_j^+, sum c_j^-) with
    c = d(tip x)/dq M^-1 (-L^T) of the paper's eqs 14-17 (Table I), every
    cable pulling 0..F."""
    robot = cdpm.load_robot(PAPER_SPEC)
    q = np.array([np.pi / 6, np.pi / 3])
    c = paper_tip_x_gradient(q) @ np.linalg.solve(paper_M(q), -paper_L(q).T)  # (4,)
    settings = reach_settings(robot)
    T, F = settings.horizon, settings.tension_budget
    expected = T * T / 2 * F * min(c[c > 0].sum(), -c[c < 0].sum())
    report = cdpm.analyze_pose(robot, "nominal")
    value, error = report.reach_margin
    assert value == pytest.approx(expected, rel=1e-6)
    assert error == 0.0
    # the model's defaults: 2 kg, no gravity (a = 1 m/s^2), size 3 m (anchors
    # at y = +-1.5): F = 2 N, T = sqrt(2 * 0.3 / 1) s
    assert (F, T) == (2.0, float(f"{np.sqrt(0.6):.3g}"))
    assert "Reach margin r_T = 0.1501 m (exact)" in str(report)


# --------------------------------------------------------------------------
# an independent reference: the support function integrated on a fine grid


def _support_min(A, B, C, lower, upper, T, directions=7200, nodes=4001):
    """min over unit v of int_0^T sum_j max(upper_j s, lower_j s) dt,
    s = v^T C e^{At} b_j, by the trapezoidal rule on a fine grid and many
    directions (an upper bound of the exact minimum, close to it)."""
    t = np.linspace(0.0, T, nodes)
    G = np.stack([C @ expm(A * ti) @ B for ti in t])  # (nodes, p, m)
    ang = np.linspace(0.0, 2 * np.pi, directions, endpoint=False)
    V = np.stack([np.cos(ang), np.sin(ang)], axis=1)  # p = 2
    S = np.einsum("dp,tpm->dtm", V, G)
    integrand = np.maximum(S * upper, S * lower).sum(axis=2)
    return float(np.trapezoid(integrand, t, axis=1).min())


@pytest.mark.slow
def test_gravity_poses_match_a_brute_force_reference(vertical):
    settings = reach_settings(vertical)
    rng = np.random.default_rng(5)
    natural = vertical.poses["nominal"] + rng.uniform(-0.4, 0.4, size=(12, 2))
    batch = evaluate_batch(vertical, natural, reach=settings)
    lin = batch.linearisation
    got = reach_margins_at(vertical, lin, settings)
    lower, upper = reach_bounds(vertical, lin.tension, settings.tension_budget)
    checked = 0
    for i in range(min(4, lin.A.shape[0])):
        ref = _support_min(lin.A[i], lin.B[i], lin.C[i], lower[i], upper[i], settings.horizon)
        # the reference over-estimates the minimum by at most ~1e-4 relative
        # (direction spacing); the quadrature estimate bounds the rest
        tol = got.error[i] + 2e-4 * max(ref, 1e-12) + 1e-12
        assert abs(got.value[i] - ref) <= tol, (i, got.value[i], ref, got.error[i])
        # the estimate is not absurdly pessimistic
        assert got.error[i] <= 0.05 * max(got.value[i], 1e-9) or got.value[i] == 0
        checked += 1
    assert checked >= 3


def test_positive_exactly_when_poc_within_T_on_the_paper_map():
    ds = cdpm.workspace_map(
        PAPER_SPEC, {"q1": np.linspace(-3, 3, 25), "q2": np.linspace(-3, 3, 25)}, workers=1
    )
    poc, r = ds["poc"].values, ds["reach_margin"].values
    assert np.array_equal(r > 0, poc == 1)
    assert ds.attrs["reach_horizon"] == reach_settings(cdpm.load_robot(PAPER_SPEC)).horizon


# --------------------------------------------------------------------------
# continuity and range


@pytest.mark.parametrize("spec,fixed", [(PAPER_SPEC, np.pi / 3), (VERTICAL, np.pi / 3)])
def test_reach_margin_is_continuous_along_a_sweep(spec, fixed):
    """Along q1 at fixed q2, the jump between neighbours shrinks with the step
    (no jumps: halving the step halves the largest jump, about). The sweep
    stops short of q1 = 1.06, where cable c2's attachment passes within
    1 cm of its anchor and the cable's direction (so B) turns fast."""
    robot = cdpm.load_robot(spec)
    settings = reach_settings(robot)
    jumps = []
    for n in (401, 801):
        q1 = np.linspace(-0.2, 0.9, n)
        natural = np.stack([q1, np.full(n, fixed)], axis=1)
        r = cdpm.evaluate_poses(robot, natural, reach=settings)["reach_margin"]
        both = np.isfinite(r[1:]) & np.isfinite(r[:-1])  # neighbours both analysed
        assert both.sum() > 0.3 * n and np.nanmax(r) > 0
        jumps.append(np.abs(np.diff(r))[both].max())
    assert jumps[1] <= 0.6 * jumps[0]
    assert jumps[1] <= 0.01 * np.nanmax(r)


@pytest.mark.slow
def test_vertical_map_margins_span_fewer_than_six_orders(vertical):
    ds = cdpm.workspace_map(
        vertical,
        {"q1": np.linspace(-np.pi, np.pi, 61), "q2": np.linspace(-np.pi, np.pi, 61)},
        workers=2,
    )
    r = ds["reach_margin"].values
    positive = r[r > 0]
    assert positive.size > 0.5 * np.isfinite(r).sum()
    assert np.log10(positive.max() / positive.min()) < 6
    # r_T > 0 only where the verdict is YES (POC within T implies POC)
    assert np.all(ds["poc"].values[r > 0] == 1)


# --------------------------------------------------------------------------
# settings and errors


def test_settings_are_checked_and_stored(vertical):
    s = reach_settings(vertical, "0.5", 10)
    assert (s.horizon, s.tension_budget) == (0.5, 10.0)
    assert not s.horizon_default and not s.budget_default
    for bad in (0, -1, "nan", "inf", "x"):
        with pytest.raises(InputError, match="horizon"):
            reach_settings(vertical, bad)
        with pytest.raises(InputError, match="budget"):
            reach_settings(vertical, None, bad)
    # r_T grows with the horizon and the budget
    base = cdpm.analyze_pose(vertical, "nominal").reach_margin[0]
    longer = cdpm.analyze_pose(vertical, "nominal", horizon=0.5).reach_margin[0]
    richer = cdpm.analyze_pose(vertical, "nominal", tension_budget=40).reach_margin[0]
    assert 0 < base < longer and base < richer


def test_bounds_use_the_budget_only_without_an_upper_bound(vertical):
    lower, upper = reach_bounds(vertical, np.array([[30.0, 0.0, 5.0, 0.0]]), 10.0)
    np.testing.assert_array_equal(lower, [[-10.0, 0.0, -5.0, 0.0]])
    np.testing.assert_array_equal(upper, [[10.0, 10.0, 10.0, 10.0]])
    spatial = cdpm.load_robot(MODELS / "spatial_8cable" / "spatial_8cable.yaml")
    lower, upper = reach_bounds(spatial, np.full((1, 8), 100.0), 10.0)
    np.testing.assert_array_equal(lower, -100.0)
    np.testing.assert_array_equal(upper, 620.0)  # f_max = 720 N


def test_cli_options(tmp_path, capsys):
    analyze = ["analyze", str(VERTICAL), "--pose", "nominal"]
    assert main([*analyze, "--horizon", "0.5", "--tension-budget", "10"]) == 0
    out = capsys.readouterr().out
    assert "within T = 0.5 s" in out and "+-10 N" in out
    assert main([*analyze, "--horizon", "-1"]) != 0
    err = capsys.readouterr().err
    assert "horizon must be a positive" in err and "Traceback" not in err
    store = tmp_path / "m.zarr"
    mapped = ["map", str(PAPER_SPEC), "--axis", "q1=0:1:3", "--out", str(store)]
    assert main([*mapped, "--workers", "1", "--horizon", "2"]) == 0
    assert "reach margin: T = 2 s (set)" in capsys.readouterr().out
    assert cdpm.open_map(store).attrs["reach_horizon"] == 2.0


def test_long_horizons_give_nan_not_zero_and_no_warnings(vertical):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning reaches the user
        short = cdpm.analyze_pose(vertical, [0.3, 0.5], horizon=1.0)
        long = cdpm.analyze_pose(vertical, [0.3, 0.5], horizon=30.0)
        no = cdpm.analyze_pose(vertical, "horizontal", horizon=30.0)
    assert short.poc.verdict is cdpm.Verdict.YES and short.reach_margin[0] > 0
    assert np.isnan(long.reach_margin[0]) and "not resolvable" in str(long)
    assert no.reach_margin == (0.0, 0.0)  # NO: exactly 0, whatever T


def test_tiny_horizons_give_tiny_positive_margins():
    robot = cdpm.load_robot(PAPER_SPEC)
    value, error = cdpm.analyze_pose(robot, "nominal", horizon=1e-9).reach_margin
    # r_T = (T^2 / 2) F min(...) scales exactly with T^2 in the nilpotent case
    assert value == pytest.approx(0.15012364849 * (1e-9 / 0.775) ** 2, rel=1e-6)
    assert error == 0.0
    # the folded arm: output Jacobian of round-off size, r_T reads 0
    assert cdpm.analyze_pose(robot, [0.0, np.pi]).reach_margin[0] == 0.0


def test_spectral_abscissae_of_undamped_systems_from_half_the_eigenproblem():
    """The growth check's largest real part of an eigenvalue: undamped
    mechanical A = [[0, I], [F, 0]] from the eigenvalues of F (+-sqrt),
    others from A's; equal to A's eigenvalues to round-off of the
    frequency scale, on symmetric, unsymmetric, stable and unstable F."""
    from cdpm.analysis._common import spectral_abscissae

    rng = np.random.default_rng(12)
    n, k = 6, 900
    K = rng.normal(size=(k, n, n)) * rng.uniform(0.1, 1e4, (k, 1, 1))
    K[::3] += np.swapaxes(K[::3], 1, 2)  # symmetric: real frequencies or real growth
    K[1::3] = K[1::3] @ np.swapaxes(K[1::3], 1, 2)  # positive definite: oscillatory, abscissa 0
    A = np.zeros((k, 2 * n, 2 * n))
    A[:, :n, n:] = np.eye(n)
    A[:, n:, :n] = -K
    A[2::9, n:, n:] = -np.eye(n)  # damped: the full eigenproblem
    expected = np.linalg.eigvals(A).real.max(axis=1)
    scale = np.sqrt(np.abs(np.linalg.eigvals(K)).max(axis=1)) + 1.0
    got = spectral_abscissae(A)
    assert np.all(np.abs(got - expected) <= 1e-12 * scale)
    assert (got[1::3] <= 1e-9 * scale[1::3]).all() and (got[::3] > 1.0).any()
    odd = rng.normal(size=(4, 5, 5))
    np.testing.assert_array_equal(spectral_abscissae(odd), np.linalg.eigvals(odd).real.max(axis=1))
    assert spectral_abscissae(np.zeros((0, 4, 4))).shape == (0,)
    assert spectral_abscissae(np.zeros((2, 0, 0))).tolist() == [-np.inf, -np.inf]


# --------------------------------------------------------------------------
# a default horizon that resolves


def test_default_horizon_is_shortened_for_a_fast_growing_mode(monkeypatch):
    """two_link_vertical's pose 'nominal' (its first) has a mode growing at
    5.15 1/s: e^{5.15 * 0.247} = 3.6 within the default T. With the default
    growth capped at 2 (here), T is shortened to ln 2 / 5.15 s and says so;
    a given horizon is kept."""
    import cdpm.dynamics.reach as reach

    monkeypatch.setattr(reach, "REACH_DEFAULT_GROWTH", 2.0)
    robot = cdpm.load_robot(VERTICAL)
    s = reach_settings(robot)
    assert s.shortened_from == 0.247 and s.growth_pose == "nominal"
    assert s.growth_rate == pytest.approx(5.148, abs=1e-3)
    assert s.horizon == 0.134  # ln 2 / 5.148 = 0.1346, rounded down
    assert "model default, shortened from 0.247 s" in s.describe()
    assert s.as_dict()["horizon_shortened_from"] == 0.247
    given = reach_settings(robot, 0.247)
    assert given.horizon == 0.247 and given.shortened_from is None
    assert "shortened" not in given.describe()


def test_repository_models_keep_their_default_horizons():
    # no mode of their first poses grows by REACH_DEFAULT_GROWTH in T
    robot = cdpm.load_robot(VERTICAL)
    s = reach_settings(robot)
    assert s.horizon == 0.247 and s.shortened_from is None
    assert reach_settings(cdpm.load_robot(PAPER_SPEC)).horizon == 0.775


@pytest.mark.slow
def test_sjtusnake_default_horizon_resolves(tmp_path):
    """SJTUSnake (CASPR) at its pose 'initial': a mode grows at 229 1/s, by
    e^{229 * 0.143} = 2e14 within the model's first T, past the 1e8 a
    margin resolves. The default T is shortened until it resolves; a given
    horizon keeps today's answer, NaN with the reason."""
    import warnings

    from cdpm.caspr import CasprWarning, import_caspr
    from tests.conftest import caspr_models

    library, missing = caspr_models()
    if missing:
        pytest.skip(missing)
    folder = library / "MCDM" / "SJTUSnake"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasprWarning)
        result = import_caspr(
            folder / "SJTUSnake_bodies.xml", folder / "SJTUSnake_cables.xml", tmp_path / "s"
        )
    robot = cdpm.load_robot(result.spec_path)
    report = cdpm.analyze_pose(robot, "initial")
    r, err = report.reach_margin
    assert np.isfinite(r) and r > 0 and np.isfinite(err)
    assert report.reach.shortened_from == 0.143
    assert report.reach.horizon == pytest.approx(np.log(1e4) / 229.1, rel=1e-2)
    assert "shortened from 0.143 s" in str(report)
    given = cdpm.analyze_pose(robot, "initial", horizon=0.143)
    assert np.isnan(given.reach_margin[0]) and "not resolvable" in str(given)
