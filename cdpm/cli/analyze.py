"""``cdpm analyze``: every verdict at one pose, with certificates."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from cdpm.cli._pose import Q_HELP, add_pose_arguments, pose_from_args
from cdpm.cli._reach import add_reach_arguments
from cdpm.cli._tension import (
    add_tension_arguments,
    cli_equilibrium,
    cli_infeasible_message,
    tension_from_args,
)
from cdpm.errors import InputError
from cdpm.printing import json_text

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

NAME = "analyze"
HELP = "linearise at one pose and print POC, positive controllability and more"
DESCRIPTION = """\
Load a cable spec (YAML beside its URDF), find the equilibrium tensions that
hold the robot at one pose (against gravity and the spec's external wrench;
which cables are taut, which slack), linearise there and print the
linearisation (A, B, C), the cables' input cone, and
each verdict with its certificate: positive output controllability (seed
paper Theorem 1), positive controllability (Brammer; with its witness
eigenvector when it fails), output and Kalman controllability, and wrench
closure; then the reach margin r_T (how far, in T seconds, tension changes
within the cables' bounds can move the outputs in every direction) and, with
--neighbourhood R, the POC neighbourhood: how far around the pose every pose of
a local map is POC, and the largest box around the pose on which POC is proven
for every pose (certified boxes, robots without load; a loaded robot is told
why not).

Each output prints with its unit (m, or rad for rotations and revolute joints)
and, when it is a joint, a cable length or a weighted sum, its formula; r_T is
in the outputs' unit, with metres and radians counted one to one when they mix
(docs/outputs.md).

At a pose that no tension within the cable bounds holds (by the chosen
method) there is no linearisation: the report then shows the pose, the
outputs, the cables with the closest tensions within the bounds and their
statics residual, and the map criteria, marked INFEASIBLE (exit status 3).
A singular pose (the outputs or the cables lose a direction there) is noted
under the outputs."""

#: exit status when the pose has no equilibrium (the report is printed)
EXIT_NO_EQUILIBRIUM = 3

#: --format -> the extension its --output file must have (None: any)
FORMATS = {"text": None, "json": ".json", "npz": ".npz", "mat": ".mat"}

EPILOG = (
    """\
examples:
  cdpm analyze models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q pi/6 pi/3
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q 0.5 1.0 --json > report.json
  cdpm analyze models/two_link_planar --pose nominal --format npz --output lin.npz
  cdpm analyze models/two_link_planar --pose nominal --output lin.mat   (MATLAB file)
  cdpm analyze models/two_link_vertical --q 0.2 0.4 --tension pretension --pretension 10
  cdpm analyze models/two_link_planar --pose nominal --tension 0 0 0 0   (given tensions)
  cdpm analyze models/two_link_planar --pose nominal --neighbourhood 0.3 --points 31
  cdpm analyze models/two_link_vertical --pose nominal --horizon 0.5 --tension-budget 10
  cdpm analyze models/spatial_8cable --pose offset --tension best --objective margin

SPEC is a cable spec YAML file or a folder: models/two_link_planar means
models/two_link_planar/two_link_planar.yaml (or the folder's only spec); a
folder with several specs (e.g. models/) lists them.

output formats (--format, or from the --output file's extension):
  text  the report (default)
  json  the report as JSON ("feasible": false at a pose without equilibrium)
  npz   the linearisation's arrays (A, B, B_cone, C, q, output, tension,
        sign_constrained, input_sign; cable_names, output_names, state_names
        as string arrays), numpy.savez; needs --output FILE.npz
  mat   the same arrays for MATLAB (scipy.io.savemat; names as cell arrays);
        needs --output FILE.mat

exit status:
  0  the report was printed (or written)
  1  an error (bad spec, pose or option; the message says which)
  2  bad usage
  3  no tension within the cable bounds holds the pose by the chosen method:
     the report is printed, marked INFEASIBLE, without linearisation or
     verdicts; stderr says what to change (nothing is written for npz/mat;
     when the mass matrix is singular there too, a body without inertia
     about an axis, stderr and the report name that first).
     With --tension best: no tension within the cable bounds holds the pose
     at all (when only the spec's method finds none, the search still runs
     and the status is 0)

--tension best prints the report at the spec's tension, then the feasible
equilibrium tensions (LPs: each cable's least and greatest tension, which
cables can or must be slack) and the tension search: whether some feasible
tension makes the pose POC (a YES is certified at the tension printed; a NO
means none of the candidates tried is POC), the tension chosen, its verdict,
its reach margin and how it was found (json: "best_tension").

"""
    + Q_HELP
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    add_tension_arguments(parser, best=True)
    output = parser.add_argument_group("output")
    how = output.add_mutually_exclusive_group()
    how.add_argument(
        "--format",
        choices=tuple(FORMATS),
        help="text (default), json, npz or mat (see below); default: from --output's "
        "extension, else text",
    )
    how.add_argument(
        "--json",
        dest="format",
        action="store_const",
        const="json",
        help="the same as --format json",
    )
    output.add_argument(
        "--output",
        "-o",
        metavar="FILE",
        help="write to FILE instead of stdout (required for npz and mat; the extension must "
        "match the format: .json, .npz, .mat)",
    )
    parser.add_argument(
        "--neighbourhood",
        metavar="R",
        help="also map the poses within R [rad or m] of the pose (every natural coordinate) "
        "and report the largest box and ball around it in which every sampled pose is POC, "
        "and the largest box q +- h (h <= R) proven POC at every pose (certified boxes; "
        "zero-load robots)",
    )
    parser.add_argument(
        "--points",
        metavar="N",
        help="grid points per coordinate of the --neighbourhood map, odd (default: as many "
        "as a budget of a few thousand poses allows)",
    )
    add_reach_arguments(parser, margin_switch=True)


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.robot import load_robot
    from cdpm.pipeline.compiled import load_kernels_for, notice_on_stderr
    from cdpm.text.report import analyze_pose

    fmt, output = output_from_args(args)
    robot = load_robot(args.spec)
    q = pose_from_args(robot, args)
    tension, _ = tension_from_args(robot, args)
    search = tension == "best"
    if search and fmt in ("npz", "mat"):
        raise InputError(
            f"--format {fmt} writes one linearisation and --tension best reports two (the "
            "spec's tension and the best one): run --tension best first, then --tension F1 F2 "
            f"... with the best tension printed, and --format {fmt}"
        )
    radius, points = neighbourhood_from_args(robot, args)
    load_kernels_for(robot, None if search else tension, notice_on_stderr)
    report = cli_equilibrium(
        analyze_pose,
        robot,
        q,
        tension=None if search else tension,
        pretension=args.pretension,
        horizon=args.horizon,
        tension_budget=args.tension_budget,
        neighbourhood=radius,
        neighbourhood_points=points,
        infeasible="report",
        margin=not args.no_margin,
        command="cdpm analyze",
    )
    best = _best_tension(robot, q, args) if search else None
    if search:
        certified = _certified_box(robot, q, radius, args)
        return _print_with_best(report, best, fmt, output, certified)
    if not report.feasible:
        print(f"cdpm analyze: error: {_infeasible_words(report)}", file=sys.stderr)
    if fmt in ("npz", "mat"):
        if not report.feasible:
            print(report)
            print(f"cdpm analyze: no linearisation, {output} not written", file=sys.stderr)
            return EXIT_NO_EQUILIBRIUM
        report.linearisation.save(output)
        lin = report.linearisation
        shapes = ", ".join(f"{k} {'x'.join(map(str, lin.to_arrays()[k].shape))}" for k in "ABC")
        print(f"wrote {output}: the linearisation of {_where(report)} ({shapes}; {fmt})")
        return 0
    certified = _certified_box(robot, q, radius, args)
    if fmt == "json":
        data = report.as_dict()
        if certified is not None:
            data["certified_neighbourhood"] = certified[1]
        text = json_text(data)
    else:
        text = str(report) if certified is None else f"{report}\n\n{certified[0]}"
    if output is None:
        print(text)
    else:
        output.write_text(text + "\n", encoding="utf-8")
        print(f"wrote {output}: the {fmt} report of {_where(report)}")
    return 0 if report.feasible else EXIT_NO_EQUILIBRIUM


def _infeasible_words(report) -> str:
    """Why a report without equilibrium has no verdicts: a singular mass
    matrix first (the map status says so), else the missing equilibrium."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.text.report import SINGULAR_MASS_MATRIX, SINGULAR_MASS_MATRIX_FIX

    if report.singular_mass_matrix:
        return (
            f"{SINGULAR_MASS_MATRIX}. To fix: {SINGULAR_MASS_MATRIX_FIX} (no tension within "
            f"the cable bounds holds this pose either, by method {report.equilibrium.method!r})"
        )
    return cli_infeasible_message(report.equilibrium)


def _best_tension(robot: CableRobot, q, args: argparse.Namespace):
    """The tension search at q (:func:`cdpm.best_tension`), or None when
    no tension within the cable bounds holds the pose."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.equilibrium import InfeasibleEquilibriumError
    from cdpm.dynamics.tension_choice import best_tension

    try:
        return best_tension(
            robot,
            q,
            args.objective or "poc",
            horizon=args.horizon,
            tension_budget=args.tension_budget,
        )
    except InfeasibleEquilibriumError:
        return None


def _certified_box(robot: CableRobot, q, radius, args: argparse.Namespace):
    """With --neighbourhood R: the largest box around the pose proven POC
    (:func:`cdpm.regions.neighbourhood.certified_neighbourhood`), as (text,
    JSON data); None without --neighbourhood."""
    if radius is None:
        return None
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.regions.neighbourhood import certified_neighbourhood
    from cdpm.text.regions import certified_neighbourhood_json, certified_neighbourhood_lines

    box = certified_neighbourhood(
        robot, q, radius, horizon=args.horizon, tension_budget=args.tension_budget
    )
    return "\n".join(certified_neighbourhood_lines(box)), certified_neighbourhood_json(box)


def _print_with_best(report, best, fmt: str, output: Path | None, certified=None) -> int:
    """Print (or write) the report followed by the tension search (and,
    with --neighbourhood, the certified box: ``certified`` as (text, JSON))."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.text.tension import best_tension_json, best_tension_text

    if not report.feasible and report.singular_mass_matrix:
        print(f"cdpm analyze: error: {_infeasible_words(report)}", file=sys.stderr)
    if best is None:
        print(
            "cdpm analyze: error: no tension within the cable bounds holds this pose, so there "
            "is no tension to choose: try another pose or wider tension bounds in the spec",
            file=sys.stderr,
        )
    elif not report.feasible:
        print(
            f"cdpm analyze: note: {cli_infeasible_message(report.equilibrium)}; the tension "
            "search below uses the other feasible tensions",
            file=sys.stderr,
        )
    if fmt == "json":
        data = report.as_dict()
        data["best_tension"] = None if best is None else best_tension_json(best)
        if certified is not None:
            data["certified_neighbourhood"] = certified[1]
        text = json_text(data)
    else:
        search = (
            "Tension search: none (no tension within the cable bounds holds the pose)"
            if best is None
            else best_tension_text(best)
        )
        text = f"{report}\n\n{search}"
        if certified is not None:
            text += f"\n\n{certified[0]}"
    if output is None:
        print(text)
    else:
        output.write_text(text + "\n", encoding="utf-8")
        print(f"wrote {output}: the {fmt} report of {_where(report)} with the tension search")
    return EXIT_NO_EQUILIBRIUM if best is None else 0


def output_from_args(args: argparse.Namespace) -> tuple[str, Path | None]:
    """(format, output file) from --format/--json and --output, checked
    before any work: npz and mat need a file, and a file's extension must
    match its format."""
    output = None if args.output is None else Path(args.output)
    fmt = args.format
    if fmt is None:
        by_extension = {ext: name for name, ext in FORMATS.items() if ext}
        fmt = by_extension.get(output.suffix.lower(), "text") if output else "text"
    want = FORMATS[fmt]
    if output is None and fmt in ("npz", "mat"):
        raise InputError(
            f"--format {fmt} writes a file: add --output FILE{want} (e.g. --output lin{want})"
        )
    if output is not None and want is not None and output.suffix.lower() != want:
        raise InputError(
            f"--output {args.output}: --format {fmt} writes a {want} file; give a FILE "
            f"ending in {want}"
        )
    if output is not None and not output.parent.is_dir():
        raise InputError(f"--output {args.output}: folder {output.parent} does not exist")
    return fmt, output


def neighbourhood_from_args(robot: CableRobot, args: argparse.Namespace):
    """(R, points) from --neighbourhood and --points, checked: points are an
    odd integer >= 1 and only mean something with --neighbourhood."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.expressions import parse_number
    from cdpm.regions.neighbourhood import MAX_POSES

    radius = None if args.neighbourhood is None else args.neighbourhood.strip()
    if radius is not None:
        try:
            value = parse_number(radius)
        except ValueError:
            value = -1.0
        if not (value > 0 and value < float("inf")):
            raise InputError(
                f"--neighbourhood must be a positive number [rad or m] (the half-width R of "
                f"the box around the pose), e.g. 0.3 or pi/20, got {radius!r}"
            )
    if args.points is None:
        return radius, None
    if radius is None:
        raise InputError(
            f"--points {args.points.strip()} sets the grid of the POC neighbourhood: add "
            "--neighbourhood R, or leave out --points"
        )
    try:
        points = int(args.points)
    except ValueError:
        points = -1
    if points < 1 or points % 2 == 0:
        raise InputError(
            f"--points must be an odd integer >= 1 (grid points per coordinate, so that the "
            f"pose itself is one), got {args.points.strip()!r}"
        )
    if points > 1 and points**robot.nv > MAX_POSES:
        raise InputError(
            f"--points {points} over {robot.nv} coordinates is a grid of {points**robot.nv:,} "
            f"poses; at most {MAX_POSES:,}: give fewer --points"
        )
    return radius, points


def _where(report) -> str:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.text.format import pose_words

    return pose_words(report.pose_name)
