"""Property tests of the POC analyser on random small systems (hypothesis,
derandomised): every YES / NO certificate re-checks, verdicts agree with a
brute-force dense-sampling reference wherever the reference is conclusive,
and MARGINAL is rare (its rate is printed; run with -s)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.linalg import expm
from scipy.optimize import linprog

from cdpm.analysis import Verdict, positive_output_controllability, positively_spans

COUNTS = {"yes": 0, "no": 0, "marginal": 0, "ref_conclusive": 0}


def random_system(seed: int, n: int, m: int, p: int, kind: str):
    """A random (A, B, C, mask): real, complex, mechanical or nilpotent spectra."""
    rng = np.random.default_rng(seed)
    if kind == "real":
        V = rng.normal(size=(n, n)) + 2 * np.eye(n)
        A = V @ np.diag(rng.uniform(-2, 1, size=n)) @ np.linalg.inv(V)
    elif kind == "complex":
        A = rng.normal(size=(n, n))
    elif kind == "mechanical" and n >= 2:
        h = n // 2
        H = rng.normal(size=(h, h))
        K = -(H @ H.T) / h + rng.uniform(-0.5, 0.5) * np.eye(h)
        A = np.zeros((2 * h, 2 * h))
        A[:h, h:] = np.eye(h)
        A[h:, :h] = K
        A[h:, h:] = -rng.uniform(0, 0.5) * np.eye(h)
        n = 2 * h
    else:
        A = np.zeros((n, n))
        A[: n // 2, n - n // 2 :] = np.eye(n // 2)
    B = rng.normal(size=(n, m))
    C = rng.normal(size=(min(p, n), n))
    mask = rng.uniform(size=m) > 0.2
    return A, B, C, mask


def reference(A, B, C, mask):
    """Brute force: dense samples of g_j(t) on [0, T] (expm stepping) plus
    far-tail samples; conclusive YES when the samples (free ones with both
    signs) positively span with an LP margin > 1e-6, conclusive NO when a
    separating v has every normalised sample at least 1e-3 on its negative
    side. Returns Verdict or None (inconclusive)."""
    lam = np.linalg.eigvals(A)
    T = 40.0 / max(np.abs(lam).max(), 0.05)
    stable = lam.real.max() < -1e-3
    if stable:
        # see the slowest decay and oscillation, so a NO is not just "too early"
        T = max(T, 10.0 / np.abs(lam.real).min())
        osc = np.abs(lam.imag)[np.abs(lam.imag) > 1e-9]
        if osc.size:
            T = max(T, 6 * np.pi / osc.min())
        T = min(T, 2000.0)
    # v.g may be a slow mode under a fast one: beyond a mode spread of e^18
    # double precision cannot tell its sign, so stop there
    spread = lam.real.max() - lam.real.min()
    if spread > 0:
        T = min(T, 18.0 / spread)
    ts = np.linspace(0, T, 1501)
    E = expm(A * (ts[1] - ts[0]))
    X, cols = B.copy(), []
    for _ in ts:
        cols.append(C @ X)
        X = E @ X
    if stable and spread == 0:
        for t in T * np.array([2.0, 4.0, 8.0]):
            cols.append(C @ expm(A * t) @ B)
    G = np.array(cols)  # (N, p, m)
    # thin out times (never inputs) to keep the LPs small
    G = G[:: max(1, G.shape[0] // 400)]
    p = C.shape[0]
    S = [G[:, :, mask].transpose(1, 0, 2).reshape(p, -1)]
    if (~mask).any():
        F = G[:, :, ~mask].transpose(1, 0, 2).reshape(p, -1)
        S += [F, -F]
    S = np.hstack(S)
    norms = np.linalg.norm(S, axis=0)
    if not np.isfinite(S).all() or norms.max() == 0:
        return None
    U = S[:, norms > 1e-9 * norms.max()] / norms[norms > 1e-9 * norms.max()]
    k = U.shape[1]
    # max s: U w = 0, w >= s, sum w = k
    res = linprog(
        np.r_[np.zeros(k), -1.0],
        A_ub=np.hstack([-np.eye(k), np.ones((k, 1))]),
        b_ub=np.zeros(k),
        A_eq=np.vstack([np.hstack([U, np.zeros((p, 1))]), np.r_[np.ones(k), 0.0]]),
        b_eq=np.r_[np.zeros(p), k],
        bounds=[(0, None)] * k + [(None, 1.0)],
        method="highs",
    )
    if res.status == 0 and -res.fun > 1e-6:
        return Verdict.YES
    # strict separation: max_{|v|<=1} min_i -v.u_i > 1e-3 (LP over a box)
    res = linprog(
        np.r_[np.zeros(p), -1.0],
        A_ub=np.hstack([U.T, np.ones((k, 1))]),
        b_ub=np.zeros(k),
        bounds=[(-1, 1)] * p + [(None, 1.0)],
        method="highs",
    )
    if stable and res.status == 0 and -res.fun > 1e-3 * np.sqrt(p):
        # only for stable A: growing modes may change sign after the samples
        return Verdict.NO
    return None


@settings(
    derandomize=True,
    max_examples=120,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(1, 8),
    m=st.integers(1, 6),
    p=st.integers(1, 3),
    kind=st.sampled_from(["real", "complex", "mechanical", "nilpotent"]),
)
@pytest.mark.slow
def test_random_systems_certificates_and_reference(seed, n, m, p, kind):
    A, B, C, mask = random_system(seed, n, m, p, kind)
    res = positive_output_controllability(A, B, C, mask)
    COUNTS[res.verdict.value] += 1
    if res.verdict is not Verdict.MARGINAL:
        assert res.certificate.verify(A, B, C), (res, seed, n, m, p, kind)
    assert (res.margin > 0) == (res.verdict is Verdict.YES)
    ref = reference(A, B, C, mask)
    if ref is not None:
        COUNTS["ref_conclusive"] += 1
        assert res.verdict is ref or res.verdict is Verdict.MARGINAL, (res, ref, seed, kind)


def test_marginal_rate_is_small():
    """Runs after the property test (file order); prints and bounds the rate."""
    total = COUNTS["yes"] + COUNTS["no"] + COUNTS["marginal"]
    if total == 0:
        pytest.skip("the property test did not run")
    rate = COUNTS["marginal"] / total
    print(f"\nPOC verdicts on random systems: {COUNTS}; MARGINAL rate {rate:.1%}")
    assert rate <= 0.05


@settings(derandomize=True, max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    p=st.integers(1, 4),
    k=st.integers(0, 9),
)
def test_random_span_certificates(seed, p, k):
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(p, k))
    if k and rng.uniform() < 0.3:
        S[:, 0] = 0.0  # a zero vector never changes the answer
    res = positively_spans(S)
    assert res.verify()
    assert (res.margin > 0) == (res.verdict is Verdict.YES)
    # brute force over many directions: a YES has no separating direction
    V = rng.normal(size=(4000, p))
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    worst = (V @ S).max(axis=1).min() if k else -1.0
    if res.verdict is Verdict.YES:
        assert worst > 0
    # the continuous margin upper-bounds the sampled inner value min_v max_i
    if k:
        assert res.margin <= worst + 1e-9
