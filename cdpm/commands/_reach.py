"""The reach margin's options, shared by ``cdpm analyze`` and ``cdpm map``."""

from __future__ import annotations

import argparse


def add_reach_arguments(parser: argparse.ArgumentParser) -> None:
    """``--horizon T`` and ``--tension-budget F``."""
    group = parser.add_argument_group(
        "reach margin",
        "r_T: within T seconds the cables can move the outputs at least r_T in every "
        "direction, with tension changes within the cables' bounds (docs/analysis.md)",
    )
    group.add_argument(
        "--horizon",
        metavar="T",
        help="horizon T [s] of the reach margin (default: the model's, printed)",
    )
    group.add_argument(
        "--tension-budget",
        metavar="F",
        help="how much harder than at equilibrium [N] a cable without an upper bound may "
        "pull (default: the model's, printed)",
    )


def reach_from_args(robot, args: argparse.Namespace):
    """The :class:`cdpm.reach.ReachSettings` of the parsed options."""
    from cdpm.reach import reach_settings

    return reach_settings(robot, args.horizon, args.tension_budget)
