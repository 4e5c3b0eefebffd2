"""``cdpm steer``: steer the nonlinear robot's output to a target."""

from __future__ import annotations

import argparse
import math
import signal
import sys

import numpy as np

from cdpm.cli._play import add_play_arguments, check_play_arguments
from cdpm.cli._pose import Q_HELP, add_pose_arguments, pose_from_args
from cdpm.cli._tension import add_tension_arguments, cli_equilibrium, tension_from_args
from cdpm.cli.plot import argument_type
from cdpm.cli.verify import _image, add_duration_argument
from cdpm.errors import InputError
from cdpm.expressions import parse_number
from cdpm.printing import json_text

NAME = "steer"
HELP = "find pull-only tensions that move the output to a target, and simulate them"
DESCRIPTION = """\
Start at rest at the equilibrium of a pose, plan piecewise-constant tension
changes on the linearisation (an LP: slack cables only pull harder, taut ones
stay inside their bounds) and correct them on the nonlinear simulation until
the output reaches the target. Prints the outcome and the tension profile;
--plot draws y(t) and f(t), --view plays the motion in the 3-D viewer."""
EPILOG = (
    """\
examples:
  cdpm steer models/two_link_planar/two_link_planar.yaml --pose nominal --to 0.876
  cdpm steer models/two_link_vertical/two_link_vertical.yaml --by 0.005 0 --plot s.png
  cdpm steer models/two_link_planar/two_link_planar.yaml --by -0.01 --view

"""
    + Q_HELP
)


def _number(text: str) -> float:
    """An argparse type: a finite number (arithmetic allowed)."""
    try:
        value = parse_number(text)
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc)) from exc
    if not math.isfinite(value):
        raise InputError(f"{text!r}: give a finite value")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    add_tension_arguments(parser)
    goal = parser.add_mutually_exclusive_group(required=True)
    goal.add_argument(
        "--to",
        nargs="+",
        type=argument_type(_number),
        metavar="Y",
        help="the output target, one value per output, in its unit [m or rad]",
    )
    goal.add_argument(
        "--by",
        nargs="+",
        type=argument_type(_number),
        metavar="DY",
        help="the target as a change of the outputs from the pose's, in their units [m or rad]",
    )
    add_duration_argument(parser)
    parser.add_argument(
        "--intervals", type=int, default=20, metavar="K", help="piecewise-constant intervals"
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument(
        "--plot", type=argument_type(_image), metavar="IMAGE", help="draw y(t) and f(t) to IMAGE"
    )
    add_play_arguments(parser, "the motion")


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.robot import load_robot
    from cdpm.steering.shooting import STEER_MAX_INTERVALS, steer
    from cdpm.text.steering import steer_json, steer_text, tension_profile_text

    robot = load_robot(args.spec)
    pose = pose_from_args(robot, args)
    values = np.array(args.to if args.to is not None else args.by, dtype=float)
    if values.shape != (robot.n_outputs,):
        option = "--to" if args.to is not None else "--by"
        raise InputError(
            f"{option} takes {robot.n_outputs} value(s), one per output "
            f"({', '.join(robot.output_names)}); got {values.size}"
        )
    check_play_arguments(args, "the motion")
    if not 1 <= args.intervals <= STEER_MAX_INTERVALS:
        raise InputError(
            f"--intervals must be from 1 to {STEER_MAX_INTERVALS}, got {args.intervals}"
        )
    target = values if args.to is not None else robot.output(pose) + values
    tension, pretension = tension_from_args(robot, args)
    result = cli_equilibrium(
        steer,
        robot,
        pose,
        target,
        duration=args.duration,
        intervals=args.intervals,
        tension=tension,
        pretension=pretension,
    )
    if args.plot:
        where = f"pose {pose!r}" if isinstance(pose, str) else "the given q"
        word = "reached" if result.reached else "NOT reached"
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.dynamics.reach import reach_unit
        from cdpm.plotting.trajectories import display_unit, plot_trajectory

        factor, unit = display_unit(reach_unit(robot.output_units))
        plot_trajectory(
            result.trajectory,
            args.plot,
            title=f"{robot.spec.path.name}, {where}: steering to the dashed target, {word} "
            f"(miss {result.miss * factor:.2g} {unit})",
            target=result.target,
            equilibrium=result.equilibrium_tension,
        )
    if args.json:
        print(json_text(steer_json(result)))
    else:
        print(steer_text(result))
        print(tension_profile_text(result))
        if args.plot:
            print(f"plot written to {args.plot}")
    if args.view:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.cli.view import _exit_on_sigterm
        from cdpm.viewer import Viewer

        # a plain `kill` also closes the viewer (and stops its server process)
        signal.signal(signal.SIGTERM, _exit_on_sigterm)
        out = sys.stderr if args.json else sys.stdout  # keep --json output parseable
        with Viewer(robot, result.trajectory.q[0], port=args.port) as viewer:
            until = "Ctrl-C to stop" if args.seconds is None else f"for {args.seconds:g} s"
            print(f"viewer: {viewer.url()}  (playing the motion in a loop, {until})", file=out)
            out.flush()
            frames = viewer.play(result, loop=True, seconds=args.seconds)  # Ctrl-C ends it
        print(f"viewer stopped after {frames} frames", file=sys.stderr)
    return 0 if result.reached else 1
