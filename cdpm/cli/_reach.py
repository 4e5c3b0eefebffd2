"""The reach margin's options, shared by ``cdpm analyze`` and ``cdpm map``."""

from __future__ import annotations

import argparse


def add_reach_arguments(parser: argparse.ArgumentParser, margin_switch: bool = False) -> None:
    """``--horizon T`` and ``--tension-budget F`` (and ``--no-margin``)."""
    group = parser.add_argument_group(
        "reach margin r_T (how far tension changes move the outputs in T seconds)"
    )
    group.add_argument(
        "--horizon",
        metavar="T",
        help="horizon T [s] of the reach margin, at most 1e6 (default: the model's, printed)",
    )
    group.add_argument(
        "--tension-budget",
        metavar="F",
        help="largest tension change [N], up or down, of a cable without an upper bound, at "
        "most 1e12 (cables with one use their bounds; default: the model's, printed)",
    )
    if margin_switch:
        group.add_argument(
            "--no-margin",
            action="store_true",
            help="skip the reach margin (the verdicts are the same; much faster with many outputs)",
        )


def reach_from_args(robot, args: argparse.Namespace):
    """The :class:`cdpm.dynamics.reach.ReachSettings` of the parsed options."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.reach import reach_settings

    return reach_settings(robot, args.horizon, args.tension_budget)
