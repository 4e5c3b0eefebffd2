"""The batched least-norm tension solver (cdpm.dynamics.equilibrium.newton, compiled
kernel in cdpm.dynamics.equilibrium._newton_kernel): known answers, the exact QP on
random problems, and a pose's result independent of its batch."""

from __future__ import annotations

import numpy as np
import pytest

from cdpm.dynamics.equilibrium.newton import min_norm_tensions
from cdpm.dynamics.equilibrium.qp import min_norm_in_bounds


def test_one_joint_two_cables_known_answers():
    """L^T = [1, -1]: f1 - f2 = load. Unbounded the least-norm tension is
    (load/2, -load/2); with f >= 0 it is (load, 0); with f1 <= 0.8 a load
    of 1 N has no tension (v = 1: v.load = 1 > max f1 - f2 = 0.8)."""
    LT = np.array([[[1.0, -1.0]]] * 2)
    load = np.array([[1.0], [-3.0]])
    f, solved, infeasible = min_norm_tensions(
        LT, load, np.full(2, -np.inf), np.full(2, np.inf), force=1.0
    )
    np.testing.assert_allclose(f, [[0.5, -0.5], [-1.5, 1.5]], rtol=0, atol=1e-14)
    assert solved.tolist() == [True, True] and not infeasible.any()
    f, solved, infeasible = min_norm_tensions(LT, load, np.zeros(2), np.full(2, np.inf), force=1.0)
    np.testing.assert_allclose(f, [[1.0, 0.0], [0.0, 3.0]], rtol=0, atol=1e-14)
    assert solved.tolist() == [True, True] and not infeasible.any()
    f, solved, infeasible = min_norm_tensions(
        LT, load, np.zeros(2), np.array([0.8, np.inf]), force=1.0
    )
    assert solved.tolist() == [False, True]
    assert infeasible.tolist() == [True, False]
    np.testing.assert_allclose(f[1], [0.0, 3.0], rtol=0, atol=1e-14)


def test_interior_optimum_is_the_pseudo_inverse():
    """Bounds not touched: f = L (L^T L)^-1 load, the unbounded least norm."""
    rng = np.random.default_rng(4)
    LT = rng.normal(size=(50, 3, 7))
    load = rng.normal(size=(50, 3))
    f, solved, infeasible = min_norm_tensions(
        LT, load, np.full(7, -1e6), np.full(7, 1e6), force=1.0
    )
    lam = np.linalg.solve(LT @ np.swapaxes(LT, 1, 2), load[..., None])
    expected = (np.swapaxes(LT, 1, 2) @ lam)[..., 0]
    assert solved.all() and not infeasible.any()
    np.testing.assert_allclose(f, expected, rtol=1e-10, atol=1e-10)


SPREAD = {4: 3.0, 6: 1.0, 8: 1.0, 10: 1.0}


@pytest.mark.parametrize(("nv", "m"), [(2, 4), (3, 6), (6, 8), (6, 10)])
def test_decided_poses_agree_with_the_qp(nv, m):
    """Random problems, many infeasible: a solved pose has the QP's optimum
    (bounds met, statics to round-off); an infeasible one has no QP solution.
    Any iterate's Farkas proof decides a pose (the iterations stop there), so
    at most a fifth of the poses are left to the per-pose QP (a proof only
    at the last iterate left three fifths undecided at nv = 6, m = 8)."""
    rng = np.random.default_rng(nv * 100 + m)
    k = 300
    LT = rng.normal(size=(k, nv, m))
    lower = rng.uniform(0.0, 1.0, m)
    upper = np.where(rng.uniform(size=m) < 0.5, np.inf, lower + rng.uniform(1.0, 5.0, m))
    # loads of tensions partly outside the bounds: some held, some not
    load = (LT @ rng.uniform(-SPREAD[m], 3.0, (k, m, 1)))[..., 0]
    f, solved, infeasible = min_norm_tensions(LT, load, lower, upper, force=1.0)
    assert not (solved & infeasible).any()
    assert solved.sum() >= 0.09 * k and infeasible.sum() >= 0.09 * k
    assert (solved | infeasible).sum() >= 0.8 * k
    assert np.all(f[solved] >= lower) and np.all(f[solved] <= upper)
    for i in np.flatnonzero(solved | infeasible):
        x, _ = min_norm_in_bounds(LT[i], load[i], lower, upper, force=1.0)
        if solved[i]:
            np.testing.assert_allclose(f[i], x, rtol=1e-8, atol=1e-8)
            np.testing.assert_allclose(LT[i] @ f[i], load[i], rtol=0, atol=1e-9)
        else:
            assert x is None


def test_a_pose_does_not_depend_on_its_batch():
    """Each pose alone (a batch of one, the per-pose API) gives the very same
    bits as within a batch, and a strided L^T the same as a contiguous one."""
    rng = np.random.default_rng(7)
    L = rng.normal(size=(40, 8, 6))
    LT = np.swapaxes(L, 1, 2)  # not C-contiguous
    load = rng.normal(scale=2.0, size=(40, 6))
    lower, upper = np.full(8, 0.5), np.full(8, 20.0)
    f, solved, infeasible = min_norm_tensions(LT, load, lower, upper, force=1.0)
    assert solved.any() and infeasible.any()
    for i in range(40):
        fi, si, ii = min_norm_tensions(
            np.ascontiguousarray(LT[i : i + 1]), load[i : i + 1], lower, upper, force=1.0
        )
        np.testing.assert_array_equal(fi[0], f[i])
        assert (si[0], ii[0]) == (solved[i], infeasible[i])


def test_empty_batch_and_undecidable_poses():
    """No poses: empty results. A NaN load is neither solved nor proved
    infeasible (left to the per-pose solver), without an exception."""
    f, solved, infeasible = min_norm_tensions(
        np.zeros((0, 2, 3)), np.zeros((0, 2)), np.zeros(3), np.ones(3), force=1.0
    )
    assert f.shape == (0, 3) and solved.shape == infeasible.shape == (0,)
    LT = np.array([[[1.0, 0.0, -1.0], [0.0, 1.0, -1.0]]])
    f, solved, infeasible = min_norm_tensions(
        LT, np.array([[np.nan, 1.0]]), np.zeros(3), np.full(3, np.inf), force=1.0
    )
    assert not solved[0] and not infeasible[0]
