"""``--view``, ``--port`` and ``--seconds``: playing a motion in the viewer,
shared by ``cdpm steer`` and ``cdpm path``."""

from __future__ import annotations

import argparse
import math

from cdpm.errors import InputError


def _port(text: str) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.viewer import check_port

    return check_port(text)


def _seconds(text: str) -> float:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.expressions import parse_number

    try:
        value = parse_number(text)
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc)) from exc
    if not (0 <= value < math.inf):
        raise InputError(f"--seconds must be a non-negative time [s], got {text!r}")
    return value


def add_play_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """The options that play ``what`` (e.g. "the motion") in the 3-D viewer."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.cli.plot import argument_type

    parser.add_argument(
        "--view", action="store_true", help=f"play {what} in the 3-D viewer (127.0.0.1)"
    )
    parser.add_argument(
        "--port",
        type=argument_type(_port),
        default=None,
        help="viewer web port, 1-65535 (default: first free from 7000)",
    )
    parser.add_argument(
        "--seconds",
        type=argument_type(_seconds),
        default=None,
        metavar="S",
        help="with --view: play in a loop for S seconds, then exit (default: until Ctrl-C)",
    )


def check_play_arguments(args: argparse.Namespace, what: str) -> None:
    """--seconds and --port only mean something with --view."""

    if args.seconds is not None and not args.view:
        raise InputError(f"--seconds goes with --view (how long to play {what})")
    if args.port is not None and not args.view:
        raise InputError("--port goes with --view (the viewer's web port)")
