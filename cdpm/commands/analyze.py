"""``cdpm analyze``: every verdict at one pose, with certificates."""

from __future__ import annotations

import argparse
import json

NAME = "analyze"
HELP = "linearise at one pose and print POC, positive controllability and more"
DESCRIPTION = """\
Load a cable spec (YAML beside its URDF), linearise the robot at one pose and
print the linearisation (A, B, C), the cables' tensions and input cone, and
each verdict with its certificate: positive output controllability (seed
paper Theorem 1), positive controllability (Brammer; with its witness
eigenvector when it fails), output and Kalman controllability, and wrench
closure."""
EPILOG = """\
examples:
  cdpm analyze models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q pi/6 pi/3
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q 0.5 1.0 --json > report.json

Q values are a configuration vector (nq numbers) or natural coordinates (one
per degree of freedom, nv numbers; angles in rad); arithmetic such as pi/6 is
accepted."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", metavar="SPEC", help="cable spec YAML file (or its model folder)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--q", nargs="+", metavar="Q", help="configuration values, e.g. --q pi/6 pi/3"
    )
    where.add_argument("--pose", metavar="NAME", help="a named pose from the spec")
    parser.add_argument(
        "--json", action="store_true", help="print the report as JSON instead of text"
    )


def run(args: argparse.Namespace) -> int:
    from cdpm.errors import InputError
    from cdpm.report import analyze_pose
    from cdpm.robot import load_robot

    robot = load_robot(args.spec)
    if args.q is not None:
        q = robot.configuration(list(args.q))
    elif args.pose is not None:
        q = args.pose
    elif len(robot.poses) == 1:
        q = next(iter(robot.poses))
    else:
        names = ", ".join(robot.poses) or "none defined"
        raise InputError(f"give --q Q1 Q2 ... or --pose NAME (poses in the spec: {names})")
    report = analyze_pose(robot, q)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    else:
        print(report)
    return 0
