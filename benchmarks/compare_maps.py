"""Compare workspace maps computed by two code trees on the same poses.

For every shipped model (``models/*/*.yaml``) a fixed, seeded set of poses
(the named poses, a grid over two coordinates, poses near the named poses
and poses uniform within the coordinates' ranges) goes through
:func:`cdpm.evaluate_poses` (``tension=None``, ``margin=True``) with two code
trees: the working tree this script lives in and a reference tree (default
``/tmp/before``; ``--reference PATH``, or ``--reference-rev REV`` to export a
git revision with ``git archive``). Each tree runs in its own Python
process (``PYTHONPATH=<tree>``) and saves every returned array to an .npz
file; the reference process draws the poses and the other reads them, so
both trees see the very same inputs. Both read the model files of the
working tree.

The parent compares the arrays: integer arrays (verdict and status codes)
must be identical, float arrays (margins, tensions, ``y``, positions) equal
to ``--rtol`` (default 1e-9) relative, NaN equal to NaN. The relative
difference of two values a, b is ``|a - b| / max(|a|, |b|, 1e-6 * scale)``,
``scale`` being the variable's largest finite magnitude in either map, so
that values at round-off level near zero count on the variable's scale.
It prints a table per model and variable (poses, mismatching poses, largest
relative difference) and exits with 1 on any mismatch or failed run.
Variables only one tree returns (new criteria) are listed, not counted as
mismatches.

Run: ``python benchmarks/compare_maps.py [--poses N] [--reference PATH |
--reference-rev REV]``
"""

from __future__ import annotations

import argparse
import io
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
DEFAULT_REFERENCE = Path("/tmp/before")

#: floor of the relative difference's denominator, times the variable's scale
NEAR_ZERO = 1e-6
#: half-width of the neighbourhood of a named pose, as a fraction of each
#: coordinate's range
NEAR_FRACTION = 0.1
#: ranges of free-flyer / planar coordinates around the named poses [m, rad]
TRANSLATION_REACH = 0.5
ROTATION_REACH = 0.5
#: which coordinates of a multi-DOF joint are angles (others: all of them)
ROTATIONS = {"JointModelFreeFlyer": range(3, 6), "JointModelPlanar": range(2, 3)}


# --------------------------------------------------------------------------
# child: one code tree


def coordinate_ranges(robot, named: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of every natural coordinate, shape (nv,) each: a 1-DOF
    joint's position limits when finite (within [-pi, pi]), else [-pi, pi];
    the coordinates of multi-DOF joints (free-flyer, planar, spherical) span
    the named poses widened by TRANSLATION_REACH [m] or ROTATION_REACH [rad]."""
    model = robot.model
    low = np.full(robot.nv, -np.pi)
    high = np.full(robot.nv, np.pi)
    for joint in list(model.joints)[1:]:
        iq, iv, nq, nv = joint.idx_q, joint.idx_v, joint.nq, joint.nv
        if nv == 1 and nq == 1:
            lo, hi = model.lowerPositionLimit[iq], model.upperPositionLimit[iq]
            if np.isfinite(lo) and np.isfinite(hi) and lo < hi:
                low[iv], high[iv] = max(lo, -np.pi), min(hi, np.pi)
        elif nv > 1:
            rotation = ROTATIONS.get(joint.shortname(), range(nv))
            for k in range(nv):
                reach = ROTATION_REACH if k in rotation else TRANSLATION_REACH
                values = named[:, iv + k]
                low[iv + k], high[iv + k] = values.min() - reach, values.max() + reach
    return low, high


def draw_poses(robot, n: int, seed: int) -> tuple[np.ndarray, dict[str, int]]:
    """A fixed set of about ``n`` poses (natural coordinates, (N, nv)) and
    how many of each kind: the named poses (else neutral), a grid over the
    two coordinates of widest range (the others at the first named pose),
    poses near the named poses and poses uniform within the ranges."""
    rng = np.random.default_rng(seed)
    named = [robot.to_natural(q) for q in robot.poses.values()]
    named = np.array(named or [robot.to_natural(robot.neutral())], dtype=float)
    low, high = coordinate_ranges(robot, named)
    width = high - low
    side = max(2, int(np.sqrt(n / 4)))
    axes = np.argsort(-width, kind="stable")[:2]
    grid = np.repeat(named[:1], side ** len(axes), axis=0)
    mesh = np.meshgrid(*[np.linspace(low[a], high[a], side) for a in axes], indexing="ij")
    for a, values in zip(axes, mesh, strict=True):
        grid[:, a] = values.ravel()
    n_rest = max(0, n - len(named) - len(grid))
    n_near = n_rest // 2
    centres = named[rng.integers(len(named), size=n_near)]
    near = centres + rng.uniform(-1.0, 1.0, (n_near, robot.nv)) * NEAR_FRACTION * width
    uniform = rng.uniform(low, high, (n_rest - n_near, robot.nv))
    counts = {"named": len(named), "grid": len(grid), "near named": n_near}
    counts["uniform"] = n_rest - n_near
    return np.vstack([named, grid, near, uniform]), counts


def child(tree: Path, out_dir: Path, poses_from: Path | None, n: int, seed: int) -> int:
    """Evaluate every model with the cdpm of ``tree``; one .npz per model in
    ``out_dir`` plus ``summary.json`` (errors, counts, seconds)."""
    import cdpm

    summary: dict = {"cdpm": cdpm.__file__, "models": {}}
    summary["codes"] = {"poc": dict(cdpm.VERDICT_CODES), "status": dict(cdpm.STATUS_CODES)}
    where = Path(cdpm.__file__).resolve()
    if tree.resolve() not in where.parents:
        summary["error"] = f"imported cdpm from {where}, not from {tree}"
        (out_dir / "summary.json").write_text(json.dumps(summary))
        return 1
    for path in sorted(MODELS.glob("*/*.yaml")):
        name = path.stem
        entry: dict = {}
        summary["models"][name] = entry
        try:
            robot = cdpm.load_robot(path)
            if poses_from is None:
                model_seed = seed + zlib.crc32(name.encode())
                natural, entry["counts"] = draw_poses(robot, n, model_seed)
            else:
                with np.load(poses_from / f"{name}.npz") as data:
                    natural = data["natural"]
            start = time.perf_counter()
            arrays = cdpm.evaluate_poses(robot, natural, tension=None, margin=True)
            entry["seconds"] = time.perf_counter() - start
        except Exception as exc:  # reported by the parent, which fails the run
            entry["error"] = f"{type(exc).__name__}: {exc}"
            continue
        np.savez(out_dir / f"{name}.npz", natural=natural, **arrays)
    (out_dir / "summary.json").write_text(json.dumps(summary))
    return 0


# --------------------------------------------------------------------------
# parent: run both trees and compare


def run_tree(tree: Path, out_dir: Path, poses_from: Path | None, args) -> dict:
    """Run :func:`child` for ``tree`` in a fresh Python process."""
    out_dir.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(tree))
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = "1"  # as maps run; and light on a shared machine
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(tree), str(out_dir)]
    cmd += ["--poses", str(args.poses), "--seed", str(args.seed)]
    if poses_from is not None:
        cmd += ["--poses-from", str(poses_from)]
    start = time.perf_counter()
    # cwd outside any tree: the child's sys.path[0] is this script's folder
    proc = subprocess.run(cmd, env=env, cwd=out_dir, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    summary_path = out_dir / "summary.json"
    if proc.returncode != 0 and not summary_path.is_file():
        return {"error": f"exit code {proc.returncode}: {proc.stderr.strip()[-2000:]}"}
    summary = json.loads(summary_path.read_text())
    summary["wall"] = seconds
    if proc.returncode != 0 and "error" not in summary:
        summary["error"] = f"exit code {proc.returncode}: {proc.stderr.strip()[-2000:]}"
    return summary


def relative_difference(a: np.ndarray, b: np.ndarray, scale: float) -> np.ndarray:
    """Per-element relative difference of float arrays of one shape: 0 where
    both are NaN or equal (infinities included), inf where one is NaN."""
    a = a.astype(float)
    b = b.astype(float)
    both_nan = np.isnan(a) & np.isnan(b)
    one_nan = np.isnan(a) ^ np.isnan(b)
    with np.errstate(invalid="ignore", over="ignore"):
        denominator = np.maximum(np.maximum(np.abs(a), np.abs(b)), NEAR_ZERO * scale)
        rel = np.abs(a - b) / np.where(denominator > 0, denominator, 1.0)
    rel[(a == b) | both_nan] = 0.0
    rel[one_nan | np.isnan(rel)] = np.inf
    return rel


def compare_variable(ref: np.ndarray, new: np.ndarray, rtol: float) -> tuple[int, float, str]:
    """(mismatching poses, largest relative difference, kind) of one
    variable; arrays have the pose axis first."""
    n = ref.shape[0]
    if ref.shape != new.shape:
        return n, np.inf, f"shape {ref.shape} vs {new.shape}"
    if ref.dtype.kind in "iub" and new.dtype.kind in "iub":
        differ = (ref != new).reshape(n, -1).any(axis=1)
        return int(differ.sum()), float(differ.any()), "codes"
    finite = np.concatenate([ref[np.isfinite(ref)], new[np.isfinite(new)]])
    scale = float(np.abs(finite).max()) if finite.size else 0.0
    rel = relative_difference(ref, new, scale).reshape(n, -1)
    worst = rel.max(axis=1, initial=0.0)
    return int((worst > rtol).sum()), float(worst.max(initial=0.0)), "float"


def compare(ref_dir: Path, new_dir: Path, ref: dict, new: dict, rtol: float) -> tuple[list, bool]:
    """Table rows (model, variable, kind, poses, mismatches, largest
    relative difference or a note) and whether everything agreed."""
    rows, ok = [], True
    for name in sorted(set(ref["models"]) | set(new["models"])):
        r_entry, n_entry = ref["models"].get(name, {}), new["models"].get(name, {})
        problems = [
            f"{label}: {entry.get('error', 'model missing')}"
            for label, entry, summary in (("reference", r_entry, ref), ("working", n_entry, new))
            if "error" in entry or name not in summary["models"]
        ]
        if problems:
            rows.append((name, "(run)", "error", "", "", "; ".join(problems)))
            ok = False
            continue
        with np.load(ref_dir / f"{name}.npz") as r_data, np.load(new_dir / f"{name}.npz") as n_data:
            r_vars, n_vars = dict(r_data), dict(n_data)
        for var in sorted(set(r_vars) | set(n_vars)):
            if var not in n_vars or var not in r_vars:
                where = "reference" if var in r_vars else "working tree"
                rows.append((name, var, "", "", "", f"only in the {where}"))
                continue
            mismatches, largest, kind = compare_variable(r_vars[var], n_vars[var], rtol)
            ok &= mismatches == 0
            rows.append((name, var, kind, r_vars[var].shape[0], mismatches, largest))
    return rows, ok


def verdict_summary(new_dir: Path, name: str, codes: dict) -> str:
    """Counts of the working tree's poc verdicts and statuses for a model,
    named with the tree's code tables ``codes`` (variable -> name -> code)."""
    path = new_dir / f"{name}.npz"
    if not path.is_file():
        return ""
    with np.load(path) as data:
        parts = []
        for var in ("poc", "status"):
            if var in data:
                names = {code: label for label, code in codes.get(var, {}).items()}
                values, counts = np.unique(data[var], return_counts=True)
                pairs = ", ".join(
                    f"{names.get(int(v), v)} {c}" for v, c in zip(values, counts, strict=True)
                )
                parts.append(f"{var}: {pairs}")
    return "; ".join(parts)


def export_revision(rev: str, into: Path) -> Path:
    """The files of git revision ``rev`` of this repository, in ``into``."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", rev],
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(into, filter="data")
    return into


def print_table(rows: list, ref: dict, new: dict, new_dir: Path, rtol: float) -> None:
    header = f"{'variable':<24} {'kind':<6} {'poses':>6} {'mismatches':>10}  largest rel. diff"
    current = None
    for name, var, kind, poses, mismatches, largest in rows:
        if name != current:
            current = name
            r_entry, n_entry = ref["models"].get(name, {}), new["models"].get(name, {})
            counts = r_entry.get("counts", {})
            drawn = ", ".join(f"{k} {v}" for k, v in counts.items())
            seconds = [e.get("seconds") for e in (r_entry, n_entry)]
            timing = (
                f"; evaluate_poses {seconds[0]:.1f} s (reference), {seconds[1]:.1f} s (working)"
                if None not in seconds
                else ""
            )
            print(f"\n{name}: poses {drawn}{timing}")
            summary = verdict_summary(new_dir, name, new.get("codes", {}))
            if summary:
                print(f"  working tree {summary}")
            print(header)
        if isinstance(largest, str):
            print(f"{var:<24} {kind:<6} {poses!s:>6} {mismatches!s:>10}  {largest}")
        elif kind == "codes":
            same = "identical" if mismatches == 0 else "DIFFER"
            print(f"{var:<24} {kind:<6} {poses:>6} {mismatches:>10}  {same}")
        else:
            flag = "" if mismatches == 0 else f"  (> rtol {rtol:g})"
            print(f"{var:<24} {kind:<6} {poses:>6} {mismatches:>10}  {largest:.3g}{flag}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--poses", type=int, default=2000, help="poses per model (default 2000)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the poses (default 0)")
    parser.add_argument("--rtol", type=float, default=1e-9, help="float tolerance (1e-9)")
    parser.add_argument(
        "--tree", type=Path, default=ROOT, help=f"the code tree under test (default {ROOT})"
    )
    group = parser.add_mutually_exclusive_group()
    group.add_argument(
        "--reference",
        type=Path,
        default=None,
        help=f"reference code tree (default {DEFAULT_REFERENCE})",
    )
    group.add_argument(
        "--reference-rev", default=None, help="git revision of this repository as reference"
    )
    parser.add_argument("--child", nargs=2, metavar=("TREE", "OUT"), help=argparse.SUPPRESS)
    parser.add_argument("--poses-from", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.poses < 1:
        parser.error("--poses must be at least 1")
    if args.child:
        tree, out = (Path(p) for p in args.child)
        return child(tree, out, args.poses_from, args.poses, args.seed)

    with tempfile.TemporaryDirectory(prefix="compare_maps_") as tmp:
        tmp = Path(tmp)
        if args.reference_rev is not None:
            reference = export_revision(args.reference_rev, tmp / "reference_tree")
            label = f"git revision {args.reference_rev}"
        else:
            reference = (args.reference or DEFAULT_REFERENCE).resolve()
            label = str(reference)
        if not (reference / "cdpm" / "__init__.py").is_file():
            print(f"reference {reference} has no cdpm/__init__.py", file=sys.stderr)
            return 2
        tree = args.tree.resolve()
        print(
            f"comparing maps of {tree} (working) with {label} (reference): "
            f"{args.poses} poses per model, seed {args.seed}, rtol {args.rtol:g}"
        )
        ref_dir, new_dir = tmp / "reference", tmp / "working"
        ref = run_tree(reference, ref_dir, None, args)
        new = (
            {"error": "not run: the reference failed"}
            if "error" in ref
            else run_tree(tree, new_dir, ref_dir, args)
        )
        for what, summary in (("reference", ref), ("working tree", new)):
            if "error" in summary:
                print(f"{what} run failed: {summary['error']}")
                return 1
            print(f"{what}: cdpm from {summary['cdpm']}, {summary['wall']:.1f} s")
        rows, ok = compare(ref_dir, new_dir, ref, new, args.rtol)
        print_table(rows, ref, new, new_dir, args.rtol)
    failed = sum(1 for row in rows if row[2] == "error")
    differ = sum(1 for row in rows if row[2] != "error" and row[4] not in ("", 0))
    if ok:
        print("\nall maps agree")
    else:
        print(f"\nMISMATCH: {differ} variable(s) differ, {failed} model run(s) failed")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
