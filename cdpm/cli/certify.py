"""``cdpm certify``: positive output controllability proven on whole boxes
of poses (a certified map, zarr store)."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from cdpm.cli._interrupt import interrupted
from cdpm.cli._reach import add_reach_arguments, reach_from_args
from cdpm.errors import InputError

NAME = "certify"
HELP = "prove POC YES or NO on whole boxes of poses over a grid of cells (zarr store)"
DESCRIPTION = """\
Cut the mapped coordinates into a grid of cells and prove, on every pose of a
cell, positive output controllability (seed paper Theorem 1) or its absence,
with round-off accounted for; a cell neither proven is bisected across its
widest side down to --min-fraction of a cell's width, and what is left stays
undecided. Coordinates not on an axis stay at the base pose. Proven YES boxes
that share a face form certified regions: every pose of a region is POC. Two
cases are certified: zero load (no gravity or external load, tension bounds
from 0, no joint damping: YES and NO proofs), and under load an equilibrium
chosen as the least-norm tension in bounds (min_norm, pretension: YES where
the taut set stays the same over a box); a robot in neither case is undecided
everywhere, with the reason. Re-running the same command on the same store (--out)
resumes an interrupted run. Prints the volume fractions proven YES, proven NO
and undecided, the certified regions and the run's time.

Exit status: 0 done (also when boxes stay undecided), 1 error, 2 usage,
130 interrupted (finished chunks stay in --out; the same command resumes)."""
EPILOG = """\
examples:
  cdpm certify models/two_link_planar/two_link_planar.yaml \\
      --axis q1=-pi:pi:61 --axis q2=-pi:pi:61 --out certified.zarr --plot certified.png
  cdpm certify SPEC --axis q1=0.3:0.7:8 --axis q2=0.9:1.3:8 --min-fraction 0.125 --json
  cdpm certify SPEC --axis q1=-pi:pi:61 --axis q2=-pi:pi:61 --plot c.png --compare map.zarr
  cdpm certify SPEC --axis q1=-pi:pi:121 --axis q2=-pi:pi:121 --scheduler tcp://host:8786 \\
      --out big.zarr

AXIS is NAME=LOW:HIGH:CELLS: CELLS equal cells from LOW to HIGH (CELLS + 1
edges; q1=-pi:pi:61 is 61 cells, unlike `cdpm map`, whose COUNT counts
poses), or NAME=E1,E2,... (the cells' edges, increasing); values accept
arithmetic such as -pi/2. NAME is a coordinate of the robot (a joint name, or
<joint>.x ... <joint>.yaw for a free-flyer; `cdpm analyze SPEC` lists them).
--compare draws the YES outline of a sampled map (`cdpm map ... --out
MAP.zarr` over the same coordinates) over the certified boxes."""

#: most cells along one axis
MAX_AXIS_CELLS = 10**6


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", metavar="SPEC", help="cable spec YAML file (or its model folder)")
    parser.add_argument(
        "--axis",
        action="append",
        required=True,
        metavar="AXIS",
        help="NAME=LOW:HIGH:CELLS (CELLS cells, CELLS + 1 edges) or NAME=E1,E2,... (edges)",
    )
    parser.add_argument(
        "--base",
        nargs="+",
        metavar="VALUE",
        help="pose of the other coordinates: a pose name, NAME=VALUE pairs or "
        "all values (default: the spec's first pose)",
    )
    parser.add_argument(
        "--min-fraction",
        metavar="F",
        help="a box still undecided is bisected while wider than F of a cell's width, F in "
        "[1/4096, 1] (default 1/16: four bisections per axis; the least box is the largest "
        "1/2^k at most F); smaller proves more of the volume near NO sets, slower",
    )
    parser.add_argument(
        "--out", metavar="STORE", help="zarr store to write and resume (e.g. certified.zarr)"
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace an existing store instead of resuming it"
    )
    parser.add_argument(
        "--plot", metavar="IMAGE", help="draw the proven boxes into this image (e.g. c.png)"
    )
    parser.add_argument(
        "--compare",
        metavar="MAP",
        help="with --plot: outline the YES poses of this sampled map store (cdpm map --out)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="local processes certifying chunks, this one included (default: one per CPU "
        "this process may use, at most 16; 1 = in this process only); not with --scheduler",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDR",
        help="run on a Dask distributed scheduler, e.g. tcp://127.0.0.1:8786",
    )
    parser.add_argument(
        "--chunk-size",
        type=int,
        metavar="N",
        help="cells per chunk (default: a thirty-second of the map, within 32 and 256)",
    )
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_reach_arguments(parser)


def parse_cell_axis(text: str) -> tuple[str, np.ndarray]:
    """(name, cell edges) from NAME=LOW:HIGH:CELLS or NAME=E1,E2,..."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.spec import parse_number

    name, sep, rest = text.partition("=")
    name = name.strip()
    form = "expected NAME=LOW:HIGH:CELLS (e.g. q1=-pi:pi:61) or NAME=E1,E2,... (edges)"
    if not sep or not name or not rest.strip():
        raise InputError(f"--axis {text!r}: {form}")

    def number(token: str, what: str) -> float:
        if not token.strip():
            raise InputError(f"--axis {text!r}: {what} of axis {name!r} is empty; {form}")
        try:
            value = parse_number(token.strip())
        except ValueError as exc:
            raise InputError(f"--axis {text!r}: {what} of axis {name!r}: {exc}") from None
        if not math.isfinite(value):
            raise InputError(f"--axis {text!r}: {what} of axis {name!r} must be finite")
        return value

    if ":" in rest and "," in rest:
        raise InputError(
            f"--axis {text!r}: axis {name!r} mixes a range (':') and a list (','); {form}"
        )
    if ":" in rest:
        parts = rest.split(":")
        if len(parts) != 3:
            raise InputError(f"--axis {text!r}: {form}")
        low, high = number(parts[0], "LOW"), number(parts[1], "HIGH")
        try:
            cells = int(parts[2])
        except ValueError:
            raise InputError(
                f"--axis {text!r}: CELLS of axis {name!r} must be a whole number, got "
                f"{parts[2]!r} (e.g. {name}=-pi:pi:61)"
            ) from None
        if not 1 <= cells <= MAX_AXIS_CELLS:
            raise InputError(f"--axis {text!r}: CELLS must be from 1 to {MAX_AXIS_CELLS:,}")
        if not low < high:
            raise InputError(f"--axis {text!r}: LOW must be below HIGH")
        return name, np.linspace(low, high, cells + 1)
    edges = np.array([number(t, f"edge {k + 1}") for k, t in enumerate(rest.split(","))])
    if edges.size < 2 or not np.all(np.diff(edges) > 0):
        raise InputError(
            f"--axis {text!r}: give at least two increasing edges (one cell between each "
            f"neighbouring pair), or {name}=LOW:HIGH:CELLS"
        )
    return name, edges


def parse_cell_axes(texts: list[str]) -> dict[str, np.ndarray]:
    """{name: edges} from every --axis; each coordinate once."""
    axes: dict[str, np.ndarray] = {}
    for text in texts:
        name, edges = parse_cell_axis(text)
        if name in axes:
            raise InputError(f"--axis {name} is given twice; give each coordinate one --axis")
        axes[name] = edges
    return axes


def _min_fraction(text: str | None) -> float | None:
    if text is None:
        return None
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.spec import parse_number

    try:
        value = parse_number(text)
    except ValueError as exc:
        raise InputError(f"--min-fraction {text!r}: {exc}") from None
    from cdpm.certify.map import MIN_FRACTION_FLOOR

    if not (math.isfinite(value) and MIN_FRACTION_FLOOR <= value <= 1):
        raise InputError(
            f"--min-fraction {text}: give a fraction in [1/4096, 1], e.g. 1/16 (boxes double "
            "along a NO curve with every bisection: a smaller least box may never finish)"
        )
    return float(value)


def _check_options(args: argparse.Namespace) -> None:
    """Before any work: the store's name, --workers with --scheduler,
    whole numbers >= 1, --compare only with --plot, the image's format."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps.runtime import check_scheduler_address, store_path_problem

    if args.out and store_path_problem(args.out):
        stem = Path(args.out).with_suffix("")
        raise InputError(
            f"--out {args.out}: a certified map store is a zarr directory, not "
            f"{store_path_problem(args.out)}: give --out {stem}.zarr (and --plot for an image)"
        )
    if args.scheduler and args.workers is not None:
        raise InputError(
            f"--workers {args.workers} counts local processes, and with --scheduler the Dask "
            "cluster's workers certify the chunks: leave out one of them"
        )
    for option, value in (("--workers", args.workers), ("--chunk-size", args.chunk_size)):
        if value is not None and value < 1:
            raise InputError(f"{option} {value}: give a whole number >= 1")
    if args.compare and not args.plot:
        raise InputError("--compare draws over the plot: add --plot IMAGE")
    if args.plot:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.cli.map import _check_plot_path

        _check_plot_path(args.plot)
    if args.scheduler:
        check_scheduler_address(args.scheduler)


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.certify.map import MIN_FRACTION, certify_map
    from cdpm.cli.map import parse_base
    from cdpm.maps.runtime import StoreSettingsError, interrupts_held
    from cdpm.model.robot import load_robot
    from cdpm.printing import json_text
    from cdpm.text.certify import certified_json, certified_lines

    with interrupts_held():
        axes = parse_cell_axes(args.axis)
        base = parse_base(args.base)
        min_fraction = _min_fraction(args.min_fraction)
        _check_options(args)
        robot = load_robot(args.spec)
        if isinstance(base, list):
            base = robot.configuration(base)
        reach = reach_from_args(robot, args)  # checked before any work
        sampled = None
        if args.compare:
            # loaded when the command runs (cdpm --help stays fast)
            from cdpm.maps import open_map
            from cdpm.plotting.certified import check_sampled

            sampled = open_map(args.compare)
            try:
                check_sampled(sampled, list(axes)[:2])
            except InputError as exc:
                raise InputError(f"--compare {args.compare}: {exc}") from None
            # the map must be of this spec, as an overlay in the viewer
            from cdpm.viewer.overlay import check_map_spec

            try:
                check_map_spec(sampled, robot, override=None, use="certify")
            except InputError as exc:
                raise InputError(f"--compare: {exc}") from None
    say = sys.stderr if args.json else sys.stdout
    runs = []

    def announce(info) -> None:
        runs.append(info)
        if args.quiet:
            return
        for line in info.lines():
            print(line, file=say, flush=True)

    if not args.json:
        print(f"reach margin bound of YES boxes: {reach.describe()}")
    start = time.perf_counter()
    try:
        cmap = certify_map(
            robot,
            axes,
            base,
            min_fraction=MIN_FRACTION if min_fraction is None else min_fraction,
            horizon=reach.horizon,
            tension_budget=reach.tension_budget,
            store=args.out,
            overwrite=args.overwrite,
            workers=args.workers,
            scheduler=args.scheduler,
            progress=not args.quiet,
            chunk_size=args.chunk_size,
            announce=announce,
        )
    except KeyboardInterrupt as exc:
        return interrupted("certify", args.out, getattr(exc, "certified_store", None))
    except StoreSettingsError as exc:
        raise InputError(
            exc.explain("re-run with the stored settings", "add --overwrite", "--out path")
        ) from None
    seconds = time.perf_counter() - start
    summary = certified_json(cmap, seconds)
    if args.out:
        summary["store"] = str(args.out)
    if args.plot:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.plotting.certified import save_certified_plot

        written = save_certified_plot(cmap, args.plot, sampled=sampled)
        summary["plot"] = str(written)
    if args.json:
        print(json_text(summary))
        return 0
    for line in certified_lines(summary):
        print(line)
    if args.out:
        computed = not runs or runs[-1].todo_chunks > 0
        print(f"certified map {'written to' if computed else 'read from'} {args.out}")
    if args.plot:
        print(f"plot written to {summary['plot']}")
    return 0
