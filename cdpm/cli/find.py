"""``cdpm find``: poses worth analysing (statically feasible, or POC).

The search is :func:`cdpm.regions.search.find_poses`; this module turns the
options into its inputs, with messages naming them, and prints the result."""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING

import numpy as np

from cdpm.cli._reach import add_reach_arguments, reach_from_args
from cdpm.cli._tension import add_tension_arguments
from cdpm.cli.map import add_robot_arguments, describe_robot, parse_axis, robot_from_args
from cdpm.errors import InputError
from cdpm.printing import json_text

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot
    from cdpm.regions.search import FoundPose, PoseSearch, SearchBox

NAME = "find"
HELP = "find poses worth analysing: statically feasible or positive output controllable"
DESCRIPTION = """\
Draw random poses (uniformly within the joint limits, or within --radius of a
pose given with --near), evaluate each with the map pipeline (equilibrium,
linearisation, positive output controllability) and print the best that
satisfy --where, each as --q values to paste into `cdpm analyze`, `verify`,
`steer` or `view`:

  poc       positive output controllable (verdict YES), ranked by the reach
            margin r_T [m] (largest first; how far tension changes move the
            outputs in every direction within T seconds); poses needing more
            than 10 times the tension budget F (near-singular, where the
            linearisation holds only very close) come last, marked *;
  feasible  a tension within the cables' bounds holds the pose (by the
            equilibrium method in use), ranked by the peak cable tension [N]
            (least first).

Pose values are rounded to 4 decimals before they are evaluated, so what is
printed is exactly what was analysed. With --near the pose itself is tried
first."""
EPILOG = """\
examples:
  cdpm find models/two_link_vertical
  cdpm find models/two_link_vertical --near nominal --radius 0.5 --count 3
  cdpm find models/two_link_vertical --where feasible --tension-bounds 0:25
  cdpm find CAREX/CAREX.yaml --near initial --json   (after cdpm import-caspr ... --out CAREX)
  cdpm find models/spatial_8cable --near centre --radius 0.05 --range platform_joint.z=0:0.5

Ranges: a coordinate with finite URDF limits is drawn within them; an angle
without limits within [-pi, pi] (a pitch [-pi/2, pi/2]); a length without
limits within the box of the cables' fixed anchor points (else +-1 m around
the spec's first pose). --range NAME=LOW:HIGH narrows one (LOW = HIGH fixes it).
--radius R is in the coordinates' units, rad or m, for every coordinate.

exit codes: 0 poses were found; 3 none of the poses tried satisfies --where
(the message says how many were tried and how to widen the search); 1 other
errors."""

#: exit code when no pose tried satisfies the condition
NONE_FOUND_EXIT = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", metavar="SPEC", help="cable spec YAML file (or its model folder)")
    parser.add_argument(
        "--where",
        choices=("poc", "feasible"),
        default="poc",
        help="what the poses must be: poc (verdict YES; default) or feasible (held by "
        "tensions within the bounds)",
    )
    parser.add_argument(
        "--near",
        nargs="+",
        metavar="POSE",
        help="search around this pose: a pose name of the spec or its values (Q1 Q2 ...)",
    )
    parser.add_argument(
        "--radius",
        default="0.3",
        metavar="R",
        help="with --near: half-width of the search box [rad or m] (default 0.3)",
    )
    parser.add_argument(
        "--range",
        action="append",
        metavar="NAME=LOW:HIGH",
        help="draw this coordinate within [LOW, HIGH] (rad or m); repeatable",
    )
    parser.add_argument(
        "--count", type=int, default=5, metavar="N", help="poses to print (default 5)"
    )
    parser.add_argument(
        "--tries", type=int, default=1000, metavar="N", help="poses to draw (default 1000)"
    )
    parser.add_argument(
        "--rank",
        type=int,
        default=200,
        metavar="N",
        help="with --where poc: rank at most N of the POC poses found by their reach margin "
        "(a fraction of a millisecond a pose with three outputs, about 0.2 s with six; "
        "default 200)",
    )
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    add_tension_arguments(parser)
    add_robot_arguments(parser)
    add_reach_arguments(parser)


# --------------------------------------------------------------------------
# the options as the search's inputs (cdpm.regions.search does the search)


def _box_from_args(robot: CableRobot, args: argparse.Namespace) -> SearchBox:
    """The box poses are drawn from (:func:`cdpm.regions.search.search_box`)
    of --range, --near and --radius, each checked with a message naming it."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.expressions import parse_number
    from cdpm.regions.search import search_box

    names = tuple(robot.coordinate_names)
    ranges: dict[str, tuple[float, float]] = {}
    for text in args.range or []:
        name, bounds = parse_axis(text, sampled=True, option="--range")
        message = f"--range {text!r}"
        if name not in names:
            raise InputError(f"{message}: no coordinate {name!r}; coordinates: {', '.join(names)}")
        if name in ranges:
            raise InputError(f"{message}: coordinate {name!r} is given twice; give it once")
        if bounds[0] > bounds[1]:
            raise InputError(
                f"{message}: LOW {bounds[0]:g} is above HIGH {bounds[1]:g}; give LOW <= HIGH "
                "(LOW = HIGH fixes the coordinate)"
            )
        ranges[name] = bounds
    if not args.near:
        return search_box(robot, ranges=ranges)
    text = str(args.radius).strip()
    try:
        radius = parse_number(text)
    except ValueError as exc:
        raise InputError(f"--radius {text}: {exc}; give a half-width in rad or m") from exc
    if not (math.isfinite(radius) and radius >= 0):
        raise InputError(f"--radius {text}: give a finite half-width >= 0 (rad or m)")
    center, label = _near_pose(robot, args.near)
    return search_box(robot, ranges=ranges, near=center, radius=radius, near_label=label)


def _near_pose(robot: CableRobot, tokens: list[str]) -> tuple[np.ndarray, str]:
    """(natural coordinates, label) of the --near pose."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.expressions import parse_number

    if len(tokens) == 1:
        try:
            parse_number(tokens[0])
        except ValueError:
            try:
                return robot.to_natural(robot.configuration(tokens[0])), tokens[0]
            except InputError as exc:
                raise InputError(f"--near {tokens[0]}: {exc}") from None
    values = []
    for token in tokens:
        try:
            values.append(parse_number(token.strip()))
        except ValueError as exc:
            raise InputError(
                f"--near {' '.join(tokens)}: {exc}; give a pose name or one value per "
                f"coordinate ({', '.join(robot.coordinate_names)})"
            ) from exc
    try:
        natural = robot.to_natural(robot.configuration(values))
    except InputError as exc:
        raise InputError(f"--near {' '.join(tokens)}: {exc}") from None
    return natural, " ".join(t.strip() for t in tokens)


def _value_text(value: float) -> str:
    """A pose value as --q takes it: at most DECIMALS decimals, no -0."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.regions.search import DECIMALS

    text = f"{value:.{DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _pose_argv(box: SearchBox, pose: FoundPose) -> list[str]:
    """What to paste: --pose NAME for the --near pose given by name."""
    if pose.index == 0 and box.center is not None:
        if " " not in box.near and not _is_number(box.near):
            return ["--pose", box.near]
        return ["--q", *box.near.split()]
    return ["--q", *(_value_text(v) for v in pose.natural)]


def _is_number(text: str) -> bool:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.expressions import parse_number

    try:
        parse_number(text)
    except ValueError:
        return False
    return True


def _row(box: SearchBox, pose: FoundPose) -> dict:
    """One found pose as printed and as JSON (None for a margin not computed)."""
    margin, error = pose.reach_margin, pose.reach_margin_error
    return {
        "argv": _pose_argv(box, pose),
        "natural": [float(v) for v in pose.natural],
        "poc": pose.poc,
        "static_feasible": pose.static_feasible,
        "reach_margin": margin if math.isfinite(margin) else None,
        "reach_margin_error": error if math.isfinite(error) else None,
        "peak_tension": pose.peak_tension,
        "strained": pose.strained,
        "distance": pose.distance,
    }


# --------------------------------------------------------------------------
# the command


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.pipeline.compiled import load_kernels_for, notice_on_stderr
    from cdpm.regions.search import MAX_TRIES, find_poses

    for option, value, least in (("--count", args.count, 1), ("--tries", args.tries, 1)):
        if value < least:
            raise InputError(f"{option} {value}: give a whole number >= {least}")
    if args.tries > MAX_TRIES:
        raise InputError(
            f"--tries {args.tries:,}: at most {MAX_TRIES:,} poses per search (about "
            "0.1 ms each); for more, map them: cdpm map SPEC --samples N ... --out map.zarr"
        )
    if args.rank < args.count:
        raise InputError(
            f"--rank {args.rank} is less than --count {args.count}: rank at least as many "
            "poses as are printed"
        )
    if args.seed < 0:
        raise InputError(f"--seed {args.seed}: give a whole number >= 0")
    robot, spec_robot, tension = robot_from_args(args)
    box = _box_from_args(robot, args)
    reach = reach_from_args(robot, args)
    load_kernels_for(robot, tension, notice_on_stderr)
    search = find_poses(
        robot,
        box,
        where=args.where,
        count=args.count,
        tries=args.tries,
        rank=args.rank,
        seed=args.seed,
        tension=tension,
        reach=reach,
    )
    rows = [_row(box, pose) for pose in search.poses]
    counts = {"feasible": search.statically_feasible, "poc": search.poc_yes}
    tries = args.tries
    what = "positive output controllable (YES)" if args.where == "poc" else "statically feasible"
    if args.json:
        print(json_text(_as_json(robot, spec_robot, args, search, rows)))
    else:
        overrides = describe_robot(robot, spec_robot)
        if overrides:
            print(overrides)
        print(f"{robot.spec.path.name}: {tries} poses tried, {box.describe()} (seed {args.seed})")
        print(
            f"  statically feasible: {counts['feasible']} ({100 * counts['feasible'] / tries:.1f}%)"
            f"; positive output controllable: {counts['poc']} "
            f"({100 * counts['poc'] / tries:.1f}%)"
        )
        if rows:
            print(f"reach margin: {reach.describe()}")
            _print_rows(robot, args, search, rows, what)
    if not rows:
        print(f"cdpm find: {_none_found(box, args, counts, what)}", file=sys.stderr)
        return NONE_FOUND_EXIT
    return 0


def _print_rows(robot, args, search: PoseSearch, rows: list[dict], what: str) -> None:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.reach import reach_unit
    from cdpm.regions.search import STRAIN_FACTOR

    box, reach = search.box, search.reach
    if args.where == "poc":
        among = (
            f"all {search.ranked}"
            if search.ranked == search.poc_yes
            else f"{search.ranked} of the {search.poc_yes} (drawn at random; --rank N ranks more)"
        )
        print(f"{len(rows)} {what} pose(s) of the most reach margin r_T, among {among}:")
    else:
        print(f"{len(rows)} {what} pose(s) of the least peak tension:")
    unit = reach_unit(robot.output_units).replace(" and ", ", ").replace(", one to one", "")
    header = f"  {'#':>2}  {f'r_T [{unit}]':>10}  {'POC':<12}  {'peak tension [N]':>16}"
    if box.center is not None:
        header += f"  {'distance':>8}"
    print(header + "  pose")
    for k, row in enumerate(rows, 1):
        margin = "-" if row["reach_margin"] is None else f"{row['reach_margin']:.4g}"
        verdict = row["poc"] + ("*" if row["strained"] else "")
        line = f"  {k:>2}  {margin:>10}  {verdict:<12}  {row['peak_tension']:>16.4g}"
        if box.center is not None:
            line += f"  {row['distance']:>8.4g}"
        print(line + "  " + " ".join(row["argv"]))
    if any(row["strained"] for row in rows):
        print(
            f"  * needs more than {STRAIN_FACTOR} x F = {STRAIN_FACTOR * reach.tension_budget:g} N "
            "of tension: a near-singular pose, whose reach margin holds only very close to it"
            + (" (ranked after the others)" if args.where == "poc" else "")
        )
    print(f"analyse one: cdpm analyze {args.spec} {' '.join(rows[0]['argv'])}")


def _none_found(box: SearchBox, args, counts: dict, what: str) -> str:
    """Why nothing was found, and how to widen the search."""
    widen = [f"more poses (--tries {10 * args.tries})"]
    if box.center is not None:
        widen += [f"a larger --radius (now {box.radius:g})", "no --near (the whole range)"]
    if args.range:
        widen.append("wider or fewer --range")
    if args.where == "poc":
        found = f"{counts['feasible'] or 'none'} of them statically feasible"
    else:
        found = "none statically feasible"
    return (
        f"none of the {args.tries} poses tried is {what} ({found}); widen the search: "
        f"{', '.join(widen)}, another --seed, or change the load or cables (--gravity, "
        "--tension-bounds, --tension)"
    )


def _as_json(robot: CableRobot, spec_robot, args, search: PoseSearch, rows: list[dict]) -> dict:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps.plan import robot_overrides

    box, reach = search.box, search.reach
    return {
        "spec": str(robot.spec.path),
        "where": args.where,
        "tried": args.tries,
        "seed": args.seed,
        "near": box.near,
        "radius": box.radius,
        "ranges": {
            n: [float(lo), float(hi)]
            for n, lo, hi in zip(box.names, box.low, box.high, strict=True)
        },
        "counts": {"statically_feasible": search.statically_feasible, "poc_yes": search.poc_yes},
        "ranked": search.ranked,
        "reach": {"horizon": reach.horizon, "tension_budget": reach.tension_budget},
        "overrides": robot_overrides(robot, spec_robot),
        "coordinates": list(robot.coordinate_names),
        "poses": rows,
    }
