"""Median cost per POC decision of cdpm.analysis against a baseline.

Baseline: Theorem 1 sampled at 50 times with scipy.linalg.expm, then one
HiGHS LP deciding whether the sampled output vectors positively span.
Also prints the cost of a decision plus its margin (``result.margin``, read
per pose by the workspace maps), for the 12-state mechanical systems the
smallest speed-up over several random seeds, and decision vs decision +
margin over random gravity poses of models/two_link_vertical (n = 4, m = 4,
p = 2, the equilibrium's cone and all cables slack), as maps evaluate them.

BLAS is pinned to one thread (as map workers should be): on a loaded
machine a threaded OpenBLAS makes small-matrix calls 5-10x slower and
noisier. Numbers on a shared machine are noisy: re-run to compare.

Run: python benchmarks/bench_analysis.py [--quick]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.linalg import expm  # noqa: E402
from scipy.optimize import linprog  # noqa: E402

from cdpm.analysis import positive_output_controllability  # noqa: E402


def baseline(A, B, C, mask, T=10.0, samples=50):
    """Sampled Theorem 1: 50 expm evaluations and one LP (free inputs +-)."""
    ts = np.linspace(T / samples, T, samples)
    cols = []
    for t in ts:
        G = C @ expm(A * t) @ B
        cols += [G[:, mask], G[:, ~mask], -G[:, ~mask]]
    S = np.hstack(cols)
    S = S / (np.linalg.norm(S, axis=0) + 1e-300)
    p, k = S.shape
    res = linprog(
        np.r_[np.zeros(k), -1.0],
        A_ub=np.hstack([-np.eye(k), np.ones((k, 1))]),
        b_ub=np.zeros(k),
        A_eq=np.vstack([np.hstack([S, np.zeros((p, 1))]), np.r_[np.ones(k), 0.0]]),
        b_eq=np.r_[np.zeros(p), k],
        bounds=[(0, None)] * k + [(None, 1.0)],
        method="highs",
    )
    return res.status == 0 and -res.fun > 1e-9


def median_seconds(fn, repeat=200, min_time=0.2):
    times = []
    start = time.perf_counter()
    while len(times) < repeat or time.perf_counter() - start < min_time:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        if len(times) >= 20 * repeat:
            break
    return statistics.median(times)


def paper_system():
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    B = np.zeros((4, 4))
    B[2] = [0.500, -0.046, -0.337, -0.822]
    B[3] = [-1.000, 3.088, 0.674, 2.310]
    C = np.array([[-1.5, -1.0, 0.0, 0.0]])
    return A, B, C, np.ones(4, dtype=bool)


def mechanical_system(taut: int, p: int, seed: int = 1):
    """12 states (nv = 6): random SPD mass, symmetric cable + gravity
    stiffness at nonzero tension, 8 cables, the first ``taut`` free in sign."""
    rng = np.random.default_rng(seed)
    nv, m = 6, 8
    X = rng.normal(size=(nv, nv))
    M = X @ X.T + nv * np.eye(nv)
    H = rng.normal(size=(nv, nv))
    H = (H + H.T) / 2 + 3 * np.eye(nv)  # symmetric stiffness, mostly stable
    L = rng.normal(size=(m, nv))
    Minv = np.linalg.inv(M)
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    A[nv:, :nv] = -Minv @ H
    B = np.vstack([np.zeros((nv, m)), -Minv @ L.T])
    C = np.hstack([rng.normal(size=(p, nv)) if p < nv else np.eye(nv), np.zeros((p, nv))])
    mask = np.ones(m, dtype=bool)
    mask[:taut] = False
    return A, B, C, mask


def complex_system(seed: int = 2):
    """Random 8-state system with complex, damped modes; p = 2, m = 4."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(8, 8)) - 1.0 * np.eye(8)
    return A, rng.normal(size=(8, 4)), rng.normal(size=(2, 8)), np.ones(4, dtype=bool)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats and seeds")
    args = parser.parse_args()
    repeat, seeds = (30, 3) if args.quick else (200, 8)
    cases = [
        ("paper (n=4, m=4, p=1, nilpotent)", paper_system()),
        ("12-state mechanical, full pose, slack", mechanical_system(taut=0, p=6)),
        ("12-state mechanical, full pose, 2 taut", mechanical_system(taut=2, p=6)),
        ("12-state mechanical, p=3, slack", mechanical_system(taut=0, p=3)),
        ("random 8-state, complex modes", complex_system()),
    ]
    print(f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']} (pinned)")
    print(
        f"{'system':40s} {'verdict':>7s} {'method':>20s} {'decision':>10s} {'+margin':>10s} "
        f"{'baseline':>10s} {'ratio':>6s}"
    )
    for name, (A, B, C, mask) in cases:
        res = positive_output_controllability(A, B, C, mask)
        ours = median_seconds(
            lambda A=A, B=B, C=C, mask=mask: positive_output_controllability(A, B, C, mask),
            repeat=repeat,
        )
        both = median_seconds(
            lambda A=A, B=B, C=C, mask=mask: positive_output_controllability(A, B, C, mask).margin,
            repeat=max(repeat // 10, 5),
        )
        base = median_seconds(
            lambda A=A, B=B, C=C, mask=mask: baseline(A, B, C, mask), repeat=max(repeat // 10, 5)
        )
        print(
            f"{name:40s} {res.verdict.value:>7s} {res.method:>20s} {ours * 1e6:8.0f}us "
            f"{both * 1e6:8.0f}us {base * 1e6:8.0f}us {base / ours:5.1f}x"
        )
    print(
        f"\n12-state mechanical systems over seeds 1..{seeds} (per seed: median decision and "
        "baseline cost; then min / median / max over the seeds)"
    )
    for taut, p in ((0, 6), (2, 6), (0, 3)):
        ours_s, base_s, ratios = [], [], []
        for seed in range(1, seeds + 1):
            A, B, C, mask = mechanical_system(taut=taut, p=p, seed=seed)
            ours = median_seconds(
                lambda A=A, B=B, C=C, mask=mask: positive_output_controllability(A, B, C, mask),
                repeat=repeat // 2,
            )
            base = median_seconds(
                lambda A=A, B=B, C=C, mask=mask: baseline(A, B, C, mask),
                repeat=max(repeat // 20, 5),
            )
            ours_s.append(ours * 1e6)
            base_s.append(base * 1e6)
            ratios.append(base / ours)
        print(
            f"  taut={taut} p={p}: decision {_mmm(ours_s, 'us')}; baseline {_mmm(base_s, 'us')}; "
            f"speed-up {_mmm(ratios, 'x')}"
        )
    vertical_rows(12 if args.quick else 40, repeat=10 if args.quick else 30)


def vertical_systems(count: int):
    """(A, B, C, mask) of two_link_vertical under gravity at random feasible
    poses (min-norm equilibrium tension): taut cables free, slack ones not."""
    from pathlib import Path

    import cdpm

    robot = cdpm.load_robot(Path(__file__).resolve().parents[1] / "models" / "two_link_vertical")
    rng = np.random.default_rng(5)
    out = []
    while len(out) < count:
        try:
            lin = cdpm.linearise(robot, rng.uniform(-np.pi, np.pi, size=2))
        except cdpm.InfeasibleEquilibriumError:
            continue
        out.append((lin.A, lin.B_cone, lin.C, lin.sign_constrained.copy()))
    return out


def vertical_rows(count: int, repeat: int) -> None:
    """Median over poses of the per-pose median decision and decision + margin cost."""
    systems = vertical_systems(count)
    print(
        f"\ntwo_link_vertical (gravity, n=4, m=4, p=2) over {count} random feasible poses: "
        "median over poses of decision, decision + margin, margin alone"
    )
    poc = positive_output_controllability
    for label, cone in (("equilibrium cone", True), ("all cables slack", False)):
        dec, both = [], []
        for A, B, C, mask in systems:
            mk = mask if cone else np.ones_like(mask)
            dec.append(
                median_seconds(
                    lambda A=A, B=B, C=C, mk=mk: poc(A, B, C, mk), repeat=repeat, min_time=0.02
                )
            )
            both.append(
                median_seconds(
                    lambda A=A, B=B, C=C, mk=mk: poc(A, B, C, mk).margin,
                    repeat=repeat,
                    min_time=0.02,
                )
            )
        d, b = statistics.median(dec), statistics.median(both)
        print(
            f"  {label:18s}: decision {d * 1e6:6.0f}us; decision + margin {b * 1e6:6.0f}us; "
            f"margin {max(b - d, 0.0) * 1e6:6.0f}us ({b / d:.2f}x the decision)"
        )


def _mmm(values, unit):
    """'min / median / max' of a few numbers."""
    fmt = "{:.1f}" if unit == "x" else "{:.0f}"
    return " / ".join(
        fmt.format(v) + unit for v in (min(values), statistics.median(values), max(values))
    )


if __name__ == "__main__":
    main()
