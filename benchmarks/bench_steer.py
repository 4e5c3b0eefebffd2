"""Benchmark of the nonlinear robot: simulate, steer and verify_pose per model.

Prints, per model at one named pose (two_link_planar nominal,
two_link_vertical nominal, double_pendulum_cables leaning, spatial_8cable
centre, multilink_arm reach, and two_link_two_cables nominal, a NO pose):

- simulate: the cost of one :func:`cdpm.simulate` of 1 s under the
  equilibrium tension f* held constant, at rest (as asked) and, because a
  robot at rest barely exercises the integrator, also from v0 = 0.1 rad/s
  (or m/s) on every coordinate; with the number of right-hand-side (RHS)
  evaluations (counted by wrapping cdpm's private ``_Dynamics.acceleration``
  in an untimed warm-up run) and the cost per evaluation, next to the
  Pinocchio floor for the same number of evaluations (a tight loop of
  ``pin.aba`` + ``computeJointJacobians``, ``updateFramePlacements`` and the
  Jacobians of the frames carrying cable points, over the simulated states)
  and the ratio;
- baseline: the same dynamics written plainly (q'' from ``pin.aba`` with
  tau = -L(q)^T f - D q' - w_ext, L from ``robot.cable_jacobian(q)`` per
  call) integrated in one scipy ``solve_ivp`` call (RK45, rtol 1e-8, atol
  1e-10), for the models whose configuration space is a vector space
  (nq == nv); its cost, its RHS evaluations, base/ours, cdpm.simulate's
  cost at the baseline's tolerances (``@8``: separates the cost of cdpm's
  tighter default tolerance from that of its one-solve_ivp-per-sample
  integration), and the largest difference of the final states (q, v)
  between the two simulations (a correctness check: cdpm integrates at
  rtol 1e-10), next to the largest real part of the linearisation's
  eigenvalues (at an unstable equilibrium round-off grows, so the two
  rest simulations part by more than their tolerances);
- steer: the cost of one :func:`cdpm.steer` to y0 + R e_1 with R = 5 mm,
  its nonlinear simulations, RHS evaluations, the share of its time spent
  in :func:`cdpm.simulate`, and miss/R;
- verify: the cost of one :func:`cdpm.verify_pose` at R = 5 mm (2p steers
  at a YES pose, the blocked-direction attempt at the NO pose), with its
  simulations, all_reached, the worst miss/R and, at the NO pose, the best
  attempt's progress max v.(y - y0) / R along the blocked direction.

Simulation timings are minima over repeats, with ours and the floor
interleaved, so a busy machine inflates both alike; steer timings are minima
over repeats; verify runs once. Counting the simulations and RHS evaluations
of steer and verify wraps functions in the timed runs (well under 1 % of
their cost). Numbers on a shared machine are noisy. ``--quick`` runs three
models (two_link_vertical, spatial_8cable, two_link_two_cables) with fewer
repeats.

Run: ``python benchmarks/bench_steer.py [--quick]``
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: (model, pose) benchmarked; the last one is a NO pose
MODELS = [
    ("two_link_planar", "nominal"),
    ("two_link_vertical", "nominal"),
    ("double_pendulum_cables", "leaning"),
    ("spatial_8cable", "centre"),
    ("multilink_arm", "reach"),
    ("two_link_two_cables", "nominal"),
]
QUICK_MODELS = ("two_link_vertical", "spatial_8cable", "two_link_two_cables")
#: distance of the steering targets [m]
RADIUS = 5e-3
#: simulated time [s] and start speed of the moving simulations [rad/s or m/s]
DURATION = 1.0
START_SPEED = 0.1
#: the baseline integrator's tolerances
BASE_RTOL, BASE_ATOL = 1e-8, 1e-10


class _Counter:
    """Counts the calls of (and the time spent in) a wrapped function."""

    def __init__(self, fn):
        self.fn, self.calls, self.seconds = fn, 0, 0.0

    def __call__(self, *args, **kwargs):
        self.calls += 1
        t = time.perf_counter()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.seconds += time.perf_counter() - t


@contextlib.contextmanager
def counting():
    """Count RHS evaluations (``_Dynamics.acceleration``) and the simulations
    steer runs (``cdpm.steering.shooting.simulate``) while the block runs. Yields
    (rhs, simulations) counters; rhs is None when cdpm's private dynamics
    class is not there to wrap."""
    from cdpm.dynamics import simulation
    from cdpm.steering import shooting as steering

    dynamics = getattr(simulation, "_Dynamics", None)
    original_acc = getattr(dynamics, "acceleration", None)
    rhs = None
    if original_acc is not None:
        rhs = _Counter(original_acc)

        def acceleration(self, q, v, f):
            return rhs(self, q, v, f)

        dynamics.acceleration = acceleration
    original_sim = steering.simulate
    sims = _Counter(original_sim)
    steering.simulate = sims
    try:
        yield rhs, sims
    finally:
        steering.simulate = original_sim
        if original_acc is not None:
            dynamics.acceleration = original_acc


def best_of(fn, repeats: int) -> tuple[float, object]:
    """(least seconds over repeats, the last result)."""
    best, out = float("inf"), None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def floor_loop(robot, qs: np.ndarray, vs: np.ndarray, n: int):
    """The bare Pinocchio work of n dynamics evaluations, as a callable:
    ABA plus the rigid-body part of the cable Jacobian (joint Jacobians,
    frame placements, the LOCAL_WORLD_ALIGNED Jacobian of every frame that
    carries a cable point), over the states (qs, vs) in turn."""
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    frames = {p.frame for c in robot.spec.cables for p in c.route}
    ids = [model.getFrameId(f) for f in sorted(frames) if model.existFrame(f)]
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    idx = np.arange(n) % qs.shape[0]
    states = [(qs[i], vs[i]) for i in idx]
    tau = np.zeros(robot.nv)
    aba, jacobians = pin.aba, pin.computeJointJacobians
    placements, frame_jacobian = pin.updateFramePlacements, pin.getFrameJacobian

    def run():
        for q, v in states:
            aba(model, data, q, v, tau)
            jacobians(model, data, q)
            placements(model, data)
            for f in ids:
                frame_jacobian(model, data, f, world)

    return run


def baseline_simulate(robot, q0: np.ndarray, v0: np.ndarray, f: np.ndarray, duration: float):
    """The dynamics written plainly, one solve_ivp call: returns
    (final q, final v, RHS evaluations). Only for nq == nv (q' = v)."""
    import pinocchio as pin
    from scipy.integrate import solve_ivp

    model = robot.model
    data = model.createData()
    nv = robot.nv
    damping, w_ext = robot.joint_damping, robot.external_wrench

    def rhs(t, x):
        q, v = x[:nv], x[nv:]
        L = robot.cable_jacobian(q)
        a = pin.aba(model, data, q, v, -L.T @ f - damping * v - w_ext)
        return np.concatenate([v, a])

    sol = solve_ivp(
        rhs,
        (0.0, duration),
        np.concatenate([q0, v0]),
        method="RK45",
        rtol=BASE_RTOL,
        atol=BASE_ATOL,
    )
    if not sol.success:
        raise RuntimeError(f"baseline integration failed: {sol.message}")
    return sol.y[:nv, -1], sol.y[nv:, -1], int(sol.nfev)


def simulation_rows(robot, pose: str, f0: np.ndarray, repeats: int) -> list[dict]:
    """Ours, floor and baseline for the rest and moving starts."""
    import cdpm

    q0 = robot.as_q(pose)
    rows = []
    for start, v0 in (("rest", np.zeros(robot.nv)), ("moving", np.full(robot.nv, START_SPEED))):

        def ours(v0=v0):
            return cdpm.simulate(robot, q0, v0, tension=f0, duration=DURATION)

        with counting() as (rhs, _):
            traj = ours()  # warm-up, counted
        evals = rhs.calls if rhs is not None else None
        n = evals if evals is not None else traj.t.size
        floor = floor_loop(robot, traj.q, traj.v, n)
        ours_t, floor_t = [], []
        for _ in range(repeats):  # interleaved: load affects both alike
            ours_t.append(best_of(ours, 1)[0])
            floor_t.append(best_of(floor, 1)[0])
        row = {
            "start": start,
            "ours": min(ours_t),
            "evals": evals,
            "samples": traj.t.size,
            "floor": min(floor_t),
        }
        if robot.nq == robot.nv:
            base_t, (qb, vb, nfev) = best_of(
                lambda v0=v0: baseline_simulate(robot, q0, v0, f0, DURATION), repeats
            )

            def ours_loose(v0=v0):
                return cdpm.simulate(
                    robot, q0, v0, tension=f0, duration=DURATION, rtol=BASE_RTOL, atol=BASE_ATOL
                )

            with counting() as (rhs, _):
                ours_loose()
            row |= {
                "loose": best_of(ours_loose, repeats)[0],
                "loose_evals": rhs.calls if rhs is not None else None,
                "base": base_t,
                "base_evals": nfev,
                "dq": float(np.abs(qb - traj.q[-1]).max()),
                "dv": float(np.abs(vb - traj.v[-1]).max()),
            }
        rows.append(row)
    return rows


def steer_row(robot, pose: str, y0: np.ndarray, repeats: int) -> dict:
    import cdpm

    target = y0 + RADIUS * np.eye(robot.n_outputs)[0]
    best = None
    for _ in range(repeats):
        with counting() as (rhs, sims):
            seconds, res = best_of(lambda: cdpm.steer(robot, pose, target), 1)
        if best is None or seconds < best["seconds"]:
            best = {
                "seconds": seconds,
                "sims": sims.calls,
                "sim_share": sims.seconds / seconds,
                "evals": rhs.calls if rhs is not None else None,
                "result": res,
            }
    return best


def verify_row(robot, pose: str) -> dict:
    import cdpm

    with counting() as (rhs, sims):
        seconds, rep = best_of(lambda: cdpm.verify_pose(robot, pose, RADIUS), 1)
    return {
        "seconds": seconds,
        "sims": sims.calls,
        "sim_share": sims.seconds / seconds,
        "evals": rhs.calls if rhs is not None else None,
        "report": rep,
    }


def _count(n: int | None) -> str:
    return "?" if n is None else f"{n:,}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="three models, fewer repeats")
    args = parser.parse_args(argv)
    import cdpm

    started = time.perf_counter()
    sim_repeats = 2 if args.quick else 3
    steer_repeats = 1 if args.quick else 2
    models = [(m, p) for m, p in MODELS if not args.quick or m in QUICK_MODELS]
    print(
        f"cdpm simulate / steer / verify_pose benchmark ({'quick' if args.quick else 'full'}); "
        f"machine load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs: "
        f"timings are noisy when busy\ncdpm from {Path(cdpm.__file__).parent}\n"
    )

    sim_lines, base_lines, steer_lines, verify_lines = [], [], [], []
    for name, pose in models:
        label = f"{name} ({pose})"
        try:
            robot = cdpm.load_robot(ROOT / "models" / name / f"{name}.yaml")
        except ImportError as exc:  # e.g. example-robot-data not installed
            sim_lines.append(f"{label:<36} skipped: {exc}")
            continue
        lin = cdpm.linearise(robot, pose)
        # an unstable equilibrium amplifies round-off: the rest rows then differ
        growth = float(np.max(np.linalg.eigvals(lin.A).real))
        for r in simulation_rows(robot, pose, lin.tension, sim_repeats):
            per_eval = r["ours"] / (r["evals"] or r["samples"]) * 1e6
            floor_per = r["floor"] / (r["evals"] or r["samples"]) * 1e6
            sim_lines.append(
                f"{label:<36} {r['start']:<7} {r['ours'] * 1e3:9.1f} {_count(r['evals']):>9} "
                f"{per_eval:9.1f} {r['floor'] * 1e3:9.1f} {floor_per:9.2f} "
                f"{r['ours'] / r['floor']:8.1f}x"
            )
            if "base" in r:
                base_lines.append(
                    f"{label:<36} {r['start']:<7} {r['ours'] * 1e3:9.1f} {_count(r['evals']):>9} "
                    f"{r['loose'] * 1e3:9.1f} {_count(r['loose_evals']):>9} "
                    f"{r['base'] * 1e3:9.1f} {r['base_evals']:>9,} {r['base'] / r['ours']:8.3f}x "
                    f"{r['dq']:10.2e} {r['dv']:10.2e} {growth:9.3g}"
                )
            else:
                base_lines.append(
                    f"{label:<36} {r['start']:<7} no baseline (nq = {robot.nq} != nv = {robot.nv})"
                )
        s = steer_row(robot, pose, lin.output, steer_repeats)
        res = s["result"]
        steer_lines.append(
            f"{label:<36} {res.duration:7.3f} {s['seconds']:8.2f} {s['sims']:5d} "
            f"{_count(s['evals']):>8} {s['sim_share'] * 100:6.0f}% {res.miss / RADIUS:10.2e} "
            f"{'yes' if res.reached else 'NO':>7}"
        )
        v = verify_row(robot, pose)
        rep = v["report"]
        progress = rep.blocked_progress()
        verify_lines.append(
            f"{label:<36} {rep.verdict:>7} {len(rep.runs):6d} {v['seconds']:8.2f} {v['sims']:5d} "
            f"{_count(v['evals']):>8} {v['sim_share'] * 100:6.0f}% "
            f"{'yes' if rep.all_reached else 'NO':>11} {rep.worst_relative_miss:10.2e}"
            + ("" if progress is None else f"   max v.(y - y0) = {progress:.2e} R")
        )

    print(
        f"simulate: {DURATION:g} s under the constant equilibrium tension f*, from rest and from "
        f"v0 = {START_SPEED:g} on every coordinate\n(cdpm: DOP853, rtol 1e-10, atol 1e-12, one "
        "solve_ivp per output sample; floor: aba + joint and cable-frame Jacobians per "
        "evaluation, same count)"
    )
    print(
        f"{'model (pose)':<36} {'start':<7} {'ours [ms]':>9} {'RHS evals':>9} {'us/eval':>9} "
        f"{'floor[ms]':>9} {'fl us/ev':>9} {'vs floor':>9}"
    )
    print("\n".join(sim_lines) + "\n")
    print(
        f"simulate against the baseline: one solve_ivp (RK45, rtol {BASE_RTOL:g}, atol "
        f"{BASE_ATOL:g}) on q'' = aba(q, v, -L(q)^T f - D v - w_ext); final-state difference "
        "max|q_ours - q_base|, max|v_ours - v_base|;\n@8: cdpm.simulate at the baseline's "
        "tolerances (what the per-sample restarts cost without the tighter tolerance);\n"
        "maxRe(A) [1/s]: the linearisation's fastest growth rate; when > 0 the equilibrium "
        "is unstable and round-off grows like e^(maxRe t), so the rest rows' |dq| is not an error"
    )
    print(
        f"{'model (pose)':<36} {'start':<7} {'ours [ms]':>9} {'RHS evals':>9} {'@8 [ms]':>9} "
        f"{'@8 RHS':>9} {'base [ms]':>9} {'base RHS':>9} {'base/ours':>10} {'|dq|':>10} "
        f"{'|dv|':>10} {'maxRe(A)':>9}"
    )
    print("\n".join(base_lines) + "\n")
    print(f"steer to y0 + R e_1, R = {RADIUS * 1e3:g} mm (default duration T, 20 intervals)")
    print(
        f"{'model (pose)':<36} {'T [s]':>7} {'time [s]':>8} {'sims':>5} {'RHS':>8} "
        f"{'in sim':>7} {'miss/R':>10} {'reached':>7}"
    )
    print("\n".join(steer_lines) + "\n")
    print(f"verify_pose at R = {RADIUS * 1e3:g} mm (2p steers at YES, the blocked direction at NO)")
    print(
        f"{'model (pose)':<36} {'verdict':>7} {'steers':>6} {'time [s]':>8} {'sims':>5} "
        f"{'RHS':>8} {'in sim':>7} {'all_reached':>11} {'worst m/R':>10}"
    )
    print("\n".join(verify_lines) + "\n")
    print(f"total {time.perf_counter() - started:.0f} s; load average now {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
