"""``cdpm analyze``: every verdict at one pose, with certificates."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING

from cdpm.commands._pose import Q_HELP, add_pose_arguments, pose_from_args
from cdpm.commands._reach import add_reach_arguments
from cdpm.commands._tension import add_tension_arguments, cli_equilibrium, tension_from_args

if TYPE_CHECKING:  # pragma: no cover
    pass

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
a local map is POC."""
EPILOG = (
    """\
examples:
  cdpm analyze models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q pi/6 pi/3
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q 0.5 1.0 --json > report.json
  cdpm analyze models/two_link_vertical --pose horizontal --tension pretension --pretension 10
  cdpm analyze models/two_link_planar --pose nominal --tension 0 0 0 0   (given tensions)
  cdpm analyze models/two_link_planar --pose nominal --neighbourhood 0.3
  cdpm analyze models/two_link_vertical --pose nominal --horizon 0.5 --tension-budget 10

"""
    + Q_HELP
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    add_tension_arguments(parser)
    parser.add_argument(
        "--json", action="store_true", help="print the report as JSON instead of text"
    )
    parser.add_argument(
        "--neighbourhood",
        metavar="R",
        help="also map the poses within R [rad or m] of the pose (every natural coordinate) "
        "and report the largest box and ball around it in which every pose is POC",
    )
    add_reach_arguments(parser)


def run(args: argparse.Namespace) -> int:
    import sys
    import warnings

    from cdpm.equilibrium import EquilibriumWarning
    from cdpm.report import analyze_pose
    from cdpm.robot import load_robot

    robot = load_robot(args.spec)
    q = pose_from_args(robot, args)
    tension, _ = tension_from_args(robot, args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", EquilibriumWarning)
        report = cli_equilibrium(
            analyze_pose,
            robot,
            q,
            tension=tension,
            pretension=args.pretension,
            horizon=args.horizon,
            tension_budget=args.tension_budget,
            neighbourhood=args.neighbourhood,
        )
    for warning in caught:
        if issubclass(warning.category, EquilibriumWarning):
            print(f"cdpm analyze: warning: {_cli_words(str(warning.message))}", file=sys.stderr)
        else:
            warnings.warn_explicit(
                warning.message, warning.category, warning.filename, warning.lineno
            )
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    else:
        print(report)
    return 0


def _cli_words(message: str) -> str:
    """A library message with the Python argument named as this command's option."""
    return message.replace("pretension=N", "--pretension N")
