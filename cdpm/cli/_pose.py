"""SPEC plus ``--q``/``--pose``: the pose arguments every per-pose command takes."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from cdpm.errors import InputError

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

Q_HELP = """\
Q values are a configuration vector (nq numbers) or natural coordinates (one
per degree of freedom, nv numbers; angles in rad); arithmetic such as pi/6 is
accepted. Without --q or --pose the spec's first named pose is used."""


def add_pose_arguments(parser: argparse.ArgumentParser) -> None:
    """Add SPEC and the mutually exclusive --q / --pose."""
    parser.add_argument("spec", metavar="SPEC", help="cable spec YAML file (or its model folder)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--q", nargs="+", metavar="Q", help="configuration values, e.g. --q pi/6 pi/3"
    )
    where.add_argument("--pose", metavar="NAME", help="a named pose from the spec")


def pose_from_args(robot: CableRobot, args: argparse.Namespace):
    """The pose asked for: the configuration from --q, the pose name from
    --pose (validated), else the spec's first named pose, else neutral.

    Pose names are returned as names so reports and titles can show them;
    every robot method accepts them.
    """
    if args.q is not None:
        return _configuration_from_q(robot, args.q)
    if args.pose is not None:
        robot.configuration(args.pose)  # unknown names fail here, listing the poses
        return args.pose
    if robot.poses:
        return next(iter(robot.poses))
    return robot.neutral()


def _configuration_from_q(robot: CableRobot, tokens: list[str]):
    """The configuration from the --q values, with errors that name --q."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.spec import parse_number

    values = []
    for k, token in enumerate(tokens):
        try:
            values.append(parse_number(token))
        except ValueError as exc:
            where = f"value {k + 1} of {len(tokens)}" if len(tokens) > 1 else "value"
            raise InputError(
                f"--q {where}: {exc}; give one number per coordinate "
                f"({', '.join(robot.coordinate_names)})"
            ) from exc
    try:
        return robot.configuration(values)
    except InputError as exc:
        raise InputError(f"--q {' '.join(tokens)}: {exc}") from exc
