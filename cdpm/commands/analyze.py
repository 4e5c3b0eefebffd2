"""``cdpm analyze``: every verdict at one pose, with certificates."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING

from cdpm.commands._pose import Q_HELP, add_pose_arguments, pose_from_args

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.robot import CableRobot

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
closure."""
EPILOG = (
    """\
examples:
  cdpm analyze models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q pi/6 pi/3
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q 0.5 1.0 --json > report.json
  cdpm analyze models/two_link_vertical --pose horizontal --tension pretension --pretension 10
  cdpm analyze models/two_link_planar --pose nominal --tension 0 0 0 0   (given tensions)

"""
    + Q_HELP
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    parser.add_argument(
        "--tension",
        nargs="+",
        metavar="METHOD|F",
        help="equilibrium method (zero, min_norm, pretension) or one tension per cable [N]; "
        "default: the spec's equilibrium.method (min_norm if none)",
    )
    parser.add_argument(
        "--pretension",
        type=float,
        metavar="N",
        help="least tension of every cable for the pretension method [N] "
        "(default: the spec's equilibrium.pretension); an error with any other method",
    )
    parser.add_argument(
        "--json", action="store_true", help="print the report as JSON instead of text"
    )


def run(args: argparse.Namespace) -> int:
    import sys
    import warnings

    from cdpm.equilibrium import EquilibriumWarning, InfeasibleEquilibriumError
    from cdpm.report import analyze_pose
    from cdpm.robot import load_robot

    robot = load_robot(args.spec)
    q = pose_from_args(robot, args)
    tension = _tension_argument(args.tension)
    _check_pretension(robot, tension, args.pretension)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", EquilibriumWarning)
            report = analyze_pose(robot, q, tension=tension, pretension=args.pretension)
    except InfeasibleEquilibriumError as exc:
        raise InfeasibleEquilibriumError(
            exc.result, method_option="--tension {}", pretension_option="--pretension {}"
        ) from None
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


def _check_pretension(robot: CableRobot, tension, pretension: float | None) -> None:
    """--pretension only means something for the pretension method, and that
    method needs one (from the flag or the spec)."""
    from cdpm.errors import InputError

    method = tension if isinstance(tension, str) or tension is None else "given"
    method = method or robot.spec.equilibrium_method
    if pretension is not None and method != "pretension":
        source = "" if tension is not None else f" ({robot.spec.path.name}'s equilibrium.method)"
        what = "given tensions" if method == "given" else f"method {method!r}{source}"
        raise InputError(
            f"--pretension {pretension:g} only applies to --tension pretension, and this "
            f"analysis uses {what}: add --tension pretension, or leave out --pretension"
        )
    if method == "pretension" and pretension is None and not robot.spec.pretension > 0:
        raise InputError(
            f"--tension pretension needs a pretension > 0 N and {robot.spec.path.name} gives "
            "none (with 0 it is the min_norm method): add --pretension N, or set "
            "equilibrium: {pretension: N} in the spec"
        )


def _tension_argument(values: list[str] | None):
    """None, a method name, or a list of tensions from ``--tension``."""
    from cdpm.equilibrium import EQUILIBRIUM_METHODS
    from cdpm.errors import InputError
    from cdpm.spec import parse_number

    if not values:
        return None
    if len(values) == 1 and values[0] in EQUILIBRIUM_METHODS:
        return values[0]
    try:
        return [parse_number(v) for v in values]
    except ValueError as exc:
        raise InputError(
            f"--tension takes a method ({', '.join(EQUILIBRIUM_METHODS)}) or one tension "
            f"per cable in N: {exc}"
        ) from exc
