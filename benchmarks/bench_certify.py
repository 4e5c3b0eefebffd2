"""Benchmark of certified boxes and certified maps: per-box cost, the paper
arm's certified torus against its sampled map, and the coverage table.

Prints, in one run (the machine's load average at its start and end):

1. per-box cost of :func:`cdpm.certify.box.certify_boxes` on the cells of a
   122 x 122 grid of the paper arm's torus (``--quick``: 61 x 61), batched as
   certified maps run them, as a ratio to the Pinocchio floor per pose
   (``bench_map.floor_cost``: joint and frame Jacobians and crba at one
   pose, measured on the cells' centres in the same run) and to the
   straightforward baseline: the same proofs one box at a time
   (:func:`cdpm.certify_box` in a loop, on 200 of the cells);
2. the paper arm's certified map from 61 x 61 initial cells over
   [-pi, pi]^2 (default least box: 1/16 of a cell) against the sampled
   181 x 181 map (:func:`cdpm.workspace_map`, reach margin included), both
   workers=1 in this process, minima of repeats; then both commands end to
   end in fresh processes (``cdpm map ... --out`` and ``cdpm certify ...
   --out``: start-up, model loading and the zarr store included);
3. the coverage table: certified fractions of the volume (YES, NO,
   undecided) on the shipped models, beside the sampled map's YES fraction
   on a grid over the same range (4 samples per cell and axis), with the
   time and the disagreements found by sampling poses inside every decided
   box (``--samples`` per box, corners included) and analysing them with
   :func:`cdpm.evaluate_poses`: a disagreement is a defect.

Run: ``python benchmarks/bench_certify.py [--quick] [--samples N] [--coverage [MODEL ...]]``
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
MODELS = ROOT / "models"
PAPER = MODELS / "two_link_planar" / "two_link_planar.yaml"

#: the issue's target: a certified 61 x 61 map within this many times the sampled 181 x 181 map
MAP_RATIO_TARGET = 20.0
#: the issue's target: certified fraction of the paper arm's torus
COVERAGE_TARGET = 0.95


def _grid(n: int, low: float = -np.pi, high: float = np.pi) -> tuple[np.ndarray, np.ndarray]:
    edges = np.linspace(low, high, n + 1)
    idx = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    return edges[idx], edges[idx + 1]


def _best(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def per_box(quick: bool) -> None:
    from bench_map import floor_cost

    import cdpm
    from cdpm.certify.box import certify_boxes
    from cdpm.pipeline.evaluate import single_threaded_blas

    robot = cdpm.load_robot(PAPER)
    n = 61 if quick else 122
    lo, hi = _grid(n)
    print(
        f"1. per-box cost, paper arm, {n} x {n} cells of [-pi, pi]^2 "
        f"(width {hi[0, 0] - lo[0, 0]:.3g} rad)"
    )
    with single_threaded_blas():
        certify_boxes(robot, lo[:16], hi[:16])  # warm
        ours = _best(lambda: certify_boxes(robot, lo, hi), 1 if quick else 2) / len(lo)
        floor = floor_cost(robot, 0.5 * (lo + hi)[:2000])
        floor_s = _best(floor, 3) / 2000
        some = np.random.default_rng(0).choice(len(lo), 200, replace=False)
        base = _best(lambda: [cdpm.certify_box(robot, lo[k], hi[k]) for k in some], 1) / 200
    print(
        f"   batched certify_boxes {1e6 * ours:8.1f} us/box   Pinocchio floor {1e6 * floor_s:6.2f} "
        f"us/pose   x floor {ours / floor_s:7.1f}   one box at a time {1e6 * base:8.1f} us/box "
        f"(batched is {base / ours:.1f}x faster)"
    )


def _cli(args: list[str]) -> float:
    t = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-m", "cdpm", *args], capture_output=True, text=True, cwd=ROOT
    )
    elapsed = time.perf_counter() - t
    if out.returncode not in (0, 1, 4):
        raise SystemExit(f"cdpm {' '.join(args)} failed ({out.returncode}):\n{out.stderr}")
    return elapsed


def paper_map(quick: bool) -> tuple[float, float]:
    import cdpm
    from cdpm.pipeline.evaluate import single_threaded_blas

    robot = cdpm.load_robot(PAPER)
    print(
        "\n2. the paper arm's torus: certified from 61 x 61 cells vs sampled 181 x 181, workers=1"
    )
    edges = np.linspace(-np.pi, np.pi, 62)
    samples = np.linspace(-np.pi, np.pi, 181)
    with single_threaded_blas():
        cdpm.workspace_map(robot, {"q1": samples[:5]}, workers=1)  # warm
        sampled = _best(
            lambda: cdpm.workspace_map(robot, {"q1": samples, "q2": samples}, workers=1), 3
        )
        holder = {}

        def certify():
            holder["map"] = cdpm.certify_map(robot, {"q1": edges, "q2": edges}, workers=1)

        certified = _best(certify, 1 if quick else 2)
    cmap = holder["map"]
    f = cmap.fractions()
    ratio = certified / sampled
    verdict = "PASS" if ratio <= MAP_RATIO_TARGET else "MISS"
    print(
        f"   sampled 181^2 map {sampled:7.2f} s   certified map {certified:7.2f} s "
        f"({len(cmap.verdict)} boxes, {1e6 * certified / len(cmap.verdict):.0f} us per final box)"
        f"   ratio {ratio:6.1f} (target <= {MAP_RATIO_TARGET:g}: {verdict})"
    )
    cover = f["yes"] + f["no"]
    print(
        f"   certified YES {100 * f['yes']:.2f}%  NO {100 * f['no']:.2f}%  undecided "
        f"{100 * f['undecided']:.2f}%: decided {100 * cover:.2f}% (target >= "
        f"{100 * COVERAGE_TARGET:g}%: {'PASS' if cover >= COVERAGE_TARGET else 'MISS'})"
    )
    with tempfile.TemporaryDirectory() as tmp:
        spec = str(PAPER.relative_to(ROOT))
        cli_sampled = min(
            _cli(
                [
                    "map",
                    spec,
                    "--axis",
                    "q1=-pi:pi:181",
                    "--axis",
                    "q2=-pi:pi:181",
                    "--workers",
                    "1",
                    "--out",
                    os.path.join(tmp, f"s{i}.zarr"),
                ]
            )
            for i in range(2)
        )
        cli_certified = _cli(
            [
                "certify",
                spec,
                "--axis",
                "q1=-pi:pi:61",
                "--axis",
                "q2=-pi:pi:61",
                "--workers",
                "1",
                "--out",
                os.path.join(tmp, "c.zarr"),
            ]
        )
    cli_ratio = cli_certified / cli_sampled
    print(
        f"   end to end: cdpm map {cli_sampled:6.2f} s   cdpm certify {cli_certified:6.2f} s   "
        f"ratio {cli_ratio:5.1f} (target <= {MAP_RATIO_TARGET:g}: "
        f"{'PASS' if cli_ratio <= MAP_RATIO_TARGET else 'MISS'})"
    )
    return ratio, cli_ratio


def _disagreements(robot, boxes, samples: int) -> tuple[int, int]:
    """(poses checked, disagreements) over every decided box."""
    import cdpm
    from cdpm.verdicts import MARGINAL

    decided = np.flatnonzero(boxes.verdict != MARGINAL)
    if decided.size == 0:
        return 0, 0
    rng = np.random.default_rng(0)
    lo, hi = boxes.lower[decided], boxes.upper[decided]
    u = rng.uniform(size=(decided.size, samples, lo.shape[1]))
    qs = np.concatenate([lo[:, None] + u * (hi - lo)[:, None], lo[:, None], hi[:, None]], axis=1)
    wrong = 0
    for s in range(0, decided.size, 4096):  # in pieces: bounded memory
        part = qs[s : s + 4096]
        poc = np.asarray(cdpm.evaluate_poses(robot, part.reshape(-1, lo.shape[1]))["poc"])
        wrong += int(
            np.sum(poc.reshape(part.shape[:2]) != boxes.verdict[decided][s : s + 4096, None])
        )
    return int(qs.shape[0] * qs.shape[1]), wrong


#: the coverage table's rows: model, pose of the other coordinates, axes
#: (coordinate, low, high, cells), least box (fraction of a cell)
ROWS = [
    ("two_link_planar", None, [("q1", -np.pi, np.pi, 61), ("q2", -np.pi, np.pi, 61)], 1 / 16),
    ("two_link_two_cables", None, [("q1", -np.pi, np.pi, 61), ("q2", -np.pi, np.pi, 61)], 1 / 16),
    ("two_link_vertical", None, [("q1", -np.pi, np.pi, 61), ("q2", -np.pi, np.pi, 61)], 1 / 4),
    (
        "multilink_arm",
        # a pose where 8 of its 10 cables are taut (the named ones have fewer
        # taut cables than joints: their taut sets change at them)
        [0.081, 0.211, -0.056, -0.405, 0.016, -0.617],
        [
            ("shoulder_y", 0.171, 0.251, 8),
            ("elbow", -0.445, -0.365, 8),
            ("wrist_y", -0.657, -0.577, 8),
        ],
        1 / 4,
    ),
    (
        "spatial_8cable",
        "centre",  # the platform at (0, 0, 1) m, level; its position within 4 cm
        [
            ("platform_joint.x", -0.04, 0.04, 4),
            ("platform_joint.y", -0.04, 0.04, 4),
            ("platform_joint.z", 0.96, 1.04, 4),
        ],
        1 / 4,
    ),
]


def coverage(quick: bool, samples: int, models: list[str] | None = None) -> None:
    import cdpm
    from cdpm.errors import CdpmError
    from cdpm.verdicts import YES

    print("\n3. coverage: certified fractions of the volume, the sampled map's YES fraction")
    print(
        f"   {'model':<20} {'axes':<34} {'boxes':>7} {'YES %':>7} {'NO %':>6} {'undec %':>8} "
        f"{'sampled YES %':>13} {'time s':>7} {'poses checked':>13} {'disagree':>8}"
    )
    for name, pose, axes, least in ROWS:
        if models and name not in models:
            continue
        robot = cdpm.load_robot(MODELS / name / f"{name}.yaml")
        scale = 2 if quick and axes[0][3] > 20 else 1
        edges = {c: np.linspace(a, b, n // scale + 1) for c, a, b, n in axes}
        label = ", ".join(f"{c} {n // scale}" for c, _, _, n in axes)
        t = time.perf_counter()
        try:
            cmap = cdpm.certify_map(robot, edges, base=pose, min_fraction=least, workers=1)
        except CdpmError as exc:
            print(f"   {name:<20} {label:<34} not certified: {exc}")
            continue
        elapsed = time.perf_counter() - t
        f = cmap.fractions()
        grid = {
            c: (e[:-1, None] + np.diff(e)[:, None] * (np.arange(4) + 0.5)[None] / 4).ravel()
            for c, e in edges.items()
        }
        smap = cdpm.workspace_map(robot, grid, base=pose, workers=1, margin=False)
        sampled_yes = float(np.mean(np.asarray(smap["poc"]) == YES))
        checked, wrong = _disagreements(robot, cmap.boxes, samples)
        print(
            f"   {name:<20} {label:<34} {len(cmap.verdict):>7} {100 * f['yes']:>7.2f} "
            f"{100 * f['no']:>6.2f} {100 * f['undecided']:>8.2f} {100 * sampled_yes:>13.2f} "
            f"{elapsed:>7.1f} {checked:>13} {wrong:>8}"
        )
        if f["undecided"] == 1.0:
            reasons = sorted(set(cmap.boxes.reason.tolist()))
            print(f"   {'':<20} why: {reasons[0]}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller grids")
    parser.add_argument("--samples", type=int, default=8, help="poses checked per decided box")
    parser.add_argument(
        "--coverage",
        nargs="*",
        metavar="MODEL",
        default=None,
        help="only the coverage table (of these models, default all)",
    )
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f}")
    if args.coverage is None:
        per_box(args.quick)
        paper_map(args.quick)
    coverage(args.quick, args.samples, args.coverage)
    print(f"\nload average at end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
