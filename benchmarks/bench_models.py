"""Model library numbers: load time, equilibrium residuals and the agreement
of the analytic linearisation with finite differences, per shipped model.

    python benchmarks/bench_models.py           # 10 poses per model
    python benchmarks/bench_models.py --quick   # 3 poses per model

Timings are wall-clock on whatever machine runs this (noisy when the cores
are shared); each load is timed in a fresh process-free way: spec parse +
URDF + robot set-up, best of 3.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 poses per model instead of 10")
    args = parser.parse_args()
    import cdpm
    from cdpm.dynamics.equilibrium import equilibrium_tension
    from cdpm.dynamics.linearisation import linearise
    from tests.test_linearise_full import (
        equilibrium_poses,
        fd_input_matrix,
        fd_state_matrix,
        relative_error,
    )

    n = 3 if args.quick else 10
    print(
        f"{'model':<24} {'load [s]':>9} {'max rel err A':>14} {'max rel err B':>14} "
        f"{'max residual':>13} {'linearise [ms]':>15}"
    )
    for spec in sorted((ROOT / "models").glob("*/*.yaml")):
        loads = []
        for _ in range(3):
            t0 = time.perf_counter()
            robot = cdpm.load_robot(spec)
            loads.append(time.perf_counter() - t0)
        err_a = err_b = resid = 0.0
        times = []
        for q in equilibrium_poses(robot, n=n):
            t0 = time.perf_counter()
            lin = linearise(robot, q, tension="min_norm")
            times.append(time.perf_counter() - t0)
            err_a = max(err_a, relative_error(lin.A, fd_state_matrix(robot, q, lin.tension)))
            err_b = max(err_b, relative_error(lin.B, fd_input_matrix(robot, q, lin.tension)))
            resid = max(resid, equilibrium_tension(robot, q).residual)
        print(
            f"{spec.stem:<24} {min(loads):>9.3f} {err_a:>14.2e} {err_b:>14.2e} "
            f"{resid:>13.2e} {1e3 * np.median(times):>15.2f}"
        )


if __name__ == "__main__":
    main()
