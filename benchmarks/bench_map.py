"""Benchmark of workspace maps: per-pose cost against a baseline and a floor.

Prints, on the same random poses:

- ours: :func:`cdpm.maps.evaluate_poses` per pose (everything a map stores;
  for the gravity model also without the POC margin, ``margin=False``);
- baseline: a straightforward Theorem 1 check written here: linearise, then
  C e^{At} B at 50 times with scipy.linalg.expm, then one HiGHS LP deciding
  whether the 50 m output vectors, scaled to unit length, positively span
  R^p; and how often its verdicts agree with cdpm's on the poses it timed;
- floor: the bare Pinocchio work per pose (computeJointJacobians, the frame
  Jacobians of the frames carrying cable points and outputs, crba);

for the paper model (zero tension, nilpotent) and two_link_vertical
(gravity, full linearisation + general analyser); then the throughput of a
map written to zarr with 1 and 2 local worker processes (a 10^6-pose paper
map and a 65536-pose gravity map, each in a fresh Python process: while
chunks run, and end to end with the imports and the store's creation;
the best of 3 interleaved runs, 1 with ``--quick``),
and the peak memory (RSS) of a 10^6-pose map run in a subprocess.

Timings are minima over repeats, with ours and the floor interleaved, so a
busy machine inflates both alike; still, numbers on a shared machine are
noisy. ``--quick`` uses fewer poses, smaller throughput maps and a
2*10^5-pose memory run.

Run: ``python benchmarks/bench_map.py [--quick]``
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "models" / "two_link_planar" / "two_link_planar.yaml"
VERTICAL = ROOT / "models" / "two_link_vertical" / "two_link_vertical.yaml"
#: the other shipped models, mapped near their named poses (their full
#: coordinate ranges are mostly poses without an equilibrium)
NEAR_NAMED = [
    ROOT / "models" / name / f"{name}.yaml"
    for name in ("double_pendulum_cables", "multilink_arm", "spatial_8cable")
]


def poses(robot, n: int, seed: int = 0, near_named: bool = False) -> np.ndarray:
    """n random poses (natural coordinates): uniform in [-pi, pi], or within
    0.3 (rad or m) of the spec's named poses."""
    rng = np.random.default_rng(seed)
    if not near_named:
        return rng.uniform(-np.pi, np.pi, (n, robot.nv))
    named = np.array([robot.to_natural(q) for q in robot.poses.values()])
    return named[rng.integers(len(named), size=n)] + rng.uniform(-0.3, 0.3, (n, robot.nv))


def best_of(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def floor_cost(robot, natural: np.ndarray) -> callable:
    """The bare Pinocchio work per pose, as a callable over all poses."""
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    frames = {p.frame for c in robot.spec.cables for p in c.route}
    frames |= {o.frame for o in robot.spec.outputs}
    ids = [model.getFrameId(f) for f in sorted(frames) if model.existFrame(f)]
    qs = np.array([robot.from_natural(x) for x in natural])
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    def run():
        for q in qs:
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            for f in ids:
                pin.getFrameJacobian(model, data, f, world)
            pin.crba(model, data, q)

    return run


def baseline_verdicts(robot, natural: np.ndarray, tension=None) -> list[bool | None]:
    """Theorem 1 sampled at 50 times (expm) + one HiGHS LP per pose.

    Written independently of cdpm's analyser (cdpm only linearises): True
    when the sampled output vectors C e^{At} b positively span R^p, False
    when not, None when the pose has no equilibrium (or another CdpmError).
    """
    from scipy.linalg import expm
    from scipy.optimize import linprog

    from cdpm.errors import CdpmError
    from cdpm.linearisation import linearise

    out = []
    times = np.linspace(0.0, 5.0, 50)
    for x in natural:
        try:
            lin = linearise(robot, robot.from_natural(x), tension=tension)
        except CdpmError:
            out.append(None)
            continue
        A, B, C = lin.A, getattr(lin, "B_cone", lin.B), lin.C
        mask = lin.sign_constrained
        cols = []
        for t in times:
            G = C @ expm(A * t) @ B
            G = np.hstack([G[:, mask], G[:, ~mask], -G[:, ~mask]])
            norms = np.linalg.norm(G, axis=0)
            # Unit columns: positive scaling keeps the positive span, and
            # without it fast modes (large t) drown the other samples. A
            # column is dropped when it is zero or round-off next to the
            # longest one of the same sample.
            keep = norms > 1e-10 * norms.max(initial=0.0)
            cols.append(G[:, keep] / norms[keep])
        S = np.hstack(cols)
        p, k = S.shape
        if k == 0 or np.linalg.matrix_rank(S) < p:
            out.append(False)
            continue
        # max s  s.t.  S w = 0, w >= s, sum w = 1: s > 0 iff positive span
        c = np.zeros(k + 1)
        c[-1] = -1.0
        a_eq = np.zeros((p + 1, k + 1))
        a_eq[:p, :k] = S
        a_eq[p, :k] = 1.0
        b_eq = np.zeros(p + 1)
        b_eq[p] = 1.0
        a_ub = np.hstack([-np.eye(k), np.ones((k, 1))])
        res = linprog(
            c,
            A_ub=a_ub,
            b_ub=np.zeros(k),
            A_eq=a_eq,
            b_eq=b_eq,
            bounds=[(0, None)] * k + [(None, 1.0)],
            method="highs",
        )
        out.append(bool(res.status == 0 and -res.fun > 1e-9))
    return out


def per_pose_costs(
    path: Path,
    n_ours: int,
    n_base: int,
    repeats: int,
    tension=None,
    margin: bool = True,
    near_named: bool = False,
) -> dict:
    import cdpm
    from cdpm.maps import evaluate_poses

    robot = cdpm.load_robot(path)
    natural = poses(robot, n_ours, near_named=near_named)
    floor = floor_cost(robot, natural)
    evaluate_poses(robot, natural[:8], tension, margin=margin)  # imports, caches
    ours_t, floor_t = [], []
    for _ in range(repeats):  # interleaved: load affects both alike
        ours_t.append(best_of(lambda: evaluate_poses(robot, natural, tension, margin=margin), 1))
        floor_t.append(best_of(floor, 1))
    base_poses = natural[:n_base]
    baseline_verdicts(robot, base_poses[:2], tension)  # imports
    base: list[bool | None] = []
    base_t = best_of(lambda: base.extend(baseline_verdicts(robot, base_poses, tension)), 1)
    ours = min(ours_t) / n_ours
    return {
        "ours": ours,
        "floor": min(floor_t) / n_ours,
        "baseline": base_t / n_base,
        "agreement": agreement(
            base_poses, evaluate_poses(robot, base_poses, tension, margin=False)["poc"], base
        ),
    }


def agreement(natural: np.ndarray, poc: np.ndarray, baseline: list[bool | None]) -> str:
    """One line: how often the baseline's verdicts match cdpm's map verdicts
    (``poc`` codes) on the same poses. The baseline's True / False / None
    (no equilibrium) match yes / no / not analysed; cdpm's marginal poses
    are left out (the baseline has no such verdict)."""
    from cdpm.maps import VERDICT_CODES

    names = {code: name for name, code in VERDICT_CODES.items()}
    expected = {VERDICT_CODES["yes"]: True, VERDICT_CODES["no"]: False}
    expected[VERDICT_CODES["not_analysed"]] = None
    marginal = VERDICT_CODES["marginal"]
    compared, agree, disagreements = 0, 0, []
    for i, (code, verdict) in enumerate(zip(poc.tolist(), baseline, strict=True)):
        if code == marginal:
            continue
        compared += 1
        if code in expected and expected[code] is verdict:
            agree += 1
        else:
            pose = ", ".join(f"{v:.3f}" for v in natural[i])
            disagreements.append(
                f"pose {i} [{pose}] cdpm {names.get(code, code)}, baseline {verdict}"
            )
    line = f"baseline agrees with cdpm on {agree}/{compared} poses"
    if compared < len(baseline):
        line += f" ({len(baseline) - compared} marginal for cdpm, not compared)"
    if disagreements:
        shown = "; ".join(disagreements[:5])
        more = f"; ... {len(disagreements) - 5} more" if len(disagreements) > 5 else ""
        line += f"; disagreements: {shown}{more}"
    return line


_THROUGHPUT_CHILD = """
import sys, time, numpy as np, cdpm.maps
side, workers = int(sys.argv[2]), int(sys.argv[3])
axes = {"q1": np.linspace(-3.1, 3.1, side), "q2": np.linspace(-3.1, 3.1, side)}
marks = []
def progress(done, total, index):
    if not marks or done >= total:
        marks.append(time.perf_counter())
t = time.perf_counter()
cdpm.maps.workspace_map(
    sys.argv[1], axes, workers=workers, store=sys.argv[4], overwrite=True, progress=progress
)
end = time.perf_counter()
print(side * side / (end - t), side * side / (marks[-1] - marks[0]))
"""


def throughput(path: Path, n_side: int, workers: int) -> tuple[float, float]:
    """Poses per second of an n_side x n_side grid map written to a zarr
    store with ``workers`` local processes, in a fresh Python process (as a
    user's script or the CLI runs it): (end to end, from the call to the
    returned dataset; while chunks run, from the first chunk handed out to
    the last one written, i.e. without the imports and the store's
    creation)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(
            [
                sys.executable,
                "-c",
                _THROUGHPUT_CHILD,
                str(path),
                str(n_side),
                str(workers),
                os.path.join(tmp, "map.zarr"),
            ],
            check=True,
            capture_output=True,
            text=True,
        )
    whole, running = out.stdout.strip().splitlines()[-1].split()
    return float(whole), float(running)


_MEMORY_CHILD = """
import sys, numpy as np, cdpm.maps, cdpm
n = int(sys.argv[1])
side = int(round(n ** 0.5))
axes = {"q1": np.linspace(-3.1, 3.1, side), "q2": np.linspace(-3.1, 3.1, side)}
ds = cdpm.maps.workspace_map(sys.argv[2], axes, workers=1, store=sys.argv[3], overwrite=True)
print(int((ds.status == 0).sum()))
"""


def peak_memory(path: Path, n: int) -> tuple[float, int, float]:
    """(peak RSS [MiB], poses mapped, seconds) of a map run in a subprocess."""
    with tempfile.TemporaryDirectory() as tmp:
        store = os.path.join(tmp, "big.zarr")
        t = time.perf_counter()
        out = subprocess.run(
            [sys.executable, "-c", _MEMORY_CHILD, str(n), str(path), store],
            check=True,
            capture_output=True,
            text=True,
        )
        seconds = time.perf_counter() - t
    peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return peak_kib / 1024.0, int(out.stdout.strip().splitlines()[-1]), seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer poses, smaller memory run")
    parser.add_argument(
        "--per-pose-only",
        action="store_true",
        help="only the per-pose table (no throughput or memory runs)",
    )
    args = parser.parse_args(argv)
    import cdpm

    n_ours = 4096 if args.quick else 16384
    n_base = 40 if args.quick else 200
    repeats = 3 if args.quick else 7
    print(
        f"cdpm map benchmark ({'quick' if args.quick else 'full'}"
        f"{', per-pose costs only' if args.per_pose_only else ''}); machine load average "
        f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs: timings are noisy when busy\n"
        f"cdpm from {Path(cdpm.__file__).parent}\n"
    )

    print("per-pose cost [us/pose] on the same random poses")
    print(f"{'model':<34} {'ours':>9} {'floor':>9} {'baseline':>10} {'vs base':>9} {'vs floor':>9}")
    rows = [("two_link_planar (zero tension)", PAPER, n_ours, n_base, repeats, True, False)]
    n_grav = 256 if args.quick else 1024  # a map chunk under load has up to 1024
    if VERTICAL.is_file():  # the analyser per pose: few poses, few repeats
        rows.append(("two_link_vertical (gravity)", VERTICAL, n_grav, 20, 2, True, False))
        rows.append(("two_link_vertical, margin=False", VERTICAL, n_grav, 20, 2, False, False))
    for path in NEAR_NAMED:
        if path.is_file():
            rows.append((f"{path.stem} (near named)", path, n_grav, 20, 2, True, True))
    from cdpm.maps._runner import single_threaded_blas

    agreements = []
    for label, path, n1, n2, reps, margin, near in rows:
        with single_threaded_blas():  # as maps run (baseline and floor alike)
            try:
                r = per_pose_costs(path, n1, n2, reps, margin=margin, near_named=near)
            except ImportError as exc:  # e.g. example-robot-data not installed
                print(f"{label:<34} skipped: {exc}")
                continue
        print(
            f"{label:<34} {r['ours'] * 1e6:9.2f} {r['floor'] * 1e6:9.2f} "
            f"{r['baseline'] * 1e6:10.1f} {r['baseline'] / r['ours']:8.0f}x "
            f"{r['ours'] / r['floor']:8.2f}x"
        )
        agreements.append(f"  {label}: {r['agreement']}")
    print("verdicts of the baseline against cdpm's (poc) on the poses the baseline timed")
    print("\n".join(agreements))
    print(
        "targets: paper >= 100x cheaper than the baseline and <= 2x the floor; "
        "two_link_vertical >= 20x cheaper than the baseline\n"
    )
    if args.per_pose_only:
        return 0

    runs = [("paper model (zero tension)", PAPER, 400 if args.quick else 1000)]
    if VERTICAL.is_file():
        runs.append(("two_link_vertical (gravity)", VERTICAL, 96 if args.quick else 256))
    for label, path, side in runs:
        best: dict[int, tuple[float, float]] = {1: (0.0, 0.0), 2: (0.0, 0.0)}
        for _ in range(1 if args.quick else 3):  # interleaved: load affects both alike
            for workers in (1, 2):
                whole, running = throughput(path, side, workers)
                best[workers] = (max(best[workers][0], whole), max(best[workers][1], running))
        (w1, r1), (w2, r2) = best[1], best[2]
        print(
            f"map throughput, {label}, {side}x{side} grid to zarr [poses/s]: while chunks run "
            f"1 worker {r1:,.0f}, 2 workers {r2:,.0f}: {r2 / r1:.2f}x (target >= 1.7x); "
            f"end to end (imports and store creation included) {w1:,.0f} vs {w2:,.0f}: "
            f"{w2 / w1:.2f}x"
        )
    print()

    n_mem = 200_000 if args.quick else 1_000_000
    rss, mapped, seconds = peak_memory(PAPER, n_mem)
    print(
        f"peak memory of a {mapped:,}-pose map to zarr (subprocess, 1 worker): "
        f"{rss:,.0f} MiB in {seconds:.1f} s (target < 1024 MiB)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
