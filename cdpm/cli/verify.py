"""``cdpm verify``: show a pose's POC verdict on the nonlinear robot."""

from __future__ import annotations

import argparse

from cdpm.cli._pose import Q_HELP, add_pose_arguments, pose_from_args
from cdpm.cli._tension import add_tension_arguments, cli_equilibrium, tension_from_args
from cdpm.cli.plot import argument_type
from cdpm.errors import InputError
from cdpm.expressions import parse_number
from cdpm.printing import json_text

NAME = "verify"
HELP = "steer the nonlinear robot to targets around a pose with pull-only tensions"
DESCRIPTION = """\
Decide positive output controllability at a pose, then show what it means on
the full nonlinear dynamics. At a YES pose: steer the output to the 2p
targets y0 +- R e_i with tensions inside every cable's bounds at every
instant, and print each target's miss, peak tension and duration. At a NO
pose: steer toward the blocked direction v of the certificate and print the
best attempt, whose progress v.(y - y0) stays at most of second order in R.
The default R is 0.2 % of the robot's size (the largest distance between two
cable attachment points). Exit status 0 when the verdict shows on the robot
(YES: every target reached; NO: the blocked direction stays out of reach),
else 1."""
EPILOG = (
    """\
examples:
  cdpm verify models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm verify models/two_link_vertical/two_link_vertical.yaml --radius 0.005 --plot v.png
  cdpm verify models/spatial_8cable/spatial_8cable.yaml --pose centre --random 4 --json

"""
    + Q_HELP
)


def _positive(option: str, what: str):
    """An argparse type for OPTION: a positive finite number (arithmetic allowed)."""

    def check(text: str) -> float:
        value = parse_number(text)
        if not (value > 0 and value < float("inf")):
            raise InputError(f"{option} must be a positive {what}, got {text!r}")
        return value

    check.__name__ = option.lstrip("-")
    return check


_radius = _positive("--radius", "distance [m]")
_duration = _positive("--duration", "time [s]")


def add_duration_argument(parser: argparse.ArgumentParser) -> None:
    """``--duration T``: the steering time of ``cdpm verify`` and ``cdpm steer``."""
    parser.add_argument(
        "--duration",
        type=argument_type(_duration),
        metavar="T",
        help="steering time [s], from 1e-6 to 1e6 and at most what the pose's linearisation "
        "resolves (the error names it; default: per pose, from its dynamics)",
    )


def _count(text: str) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.steering.verify import MAX_RANDOM_DIRECTIONS

    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_RANDOM_DIRECTIONS:
        raise InputError(f"--random takes a count from 0 to {MAX_RANDOM_DIRECTIONS}, got {text!r}")
    return value


def _image(text: str):
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.plotting import check_image_path

    return check_image_path(text)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    add_tension_arguments(parser)
    parser.add_argument(
        "--radius",
        type=argument_type(_radius),
        metavar="R",
        help="distance of the targets from y0 [output units, m] (default 0.2 %% of the "
        "robot's size)",
    )
    parser.add_argument(
        "--random",
        type=argument_type(_count),
        default=0,
        metavar="N",
        help="also steer to N random directions at distance R (YES poses), at most 1000",
    )
    add_duration_argument(parser)
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument(
        "--plot", type=argument_type(_image), metavar="IMAGE", help="draw every run to IMAGE"
    )


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.robot import load_robot
    from cdpm.steering.verify import verify_pose
    from cdpm.text.steering import verify_json, verify_text

    robot = load_robot(args.spec)
    pose = pose_from_args(robot, args)
    tension, pretension = tension_from_args(robot, args)
    report = cli_equilibrium(
        verify_pose,
        robot,
        pose,
        args.radius,
        random_directions=args.random,
        duration=args.duration,
        tension=tension,
        pretension=pretension,
    )
    if args.plot:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.plotting.trajectories import plot_verify_report

        plot_verify_report(report, args.plot)
    if args.json:
        print(json_text(verify_json(report)))
    else:
        print(verify_text(report))
        if args.plot:
            print(f"plot written to {args.plot}")
    return 0 if report.demonstrated else 1
