"""``--tension`` and ``--pretension``: the equilibrium options of the per-pose
commands (analyze, verify, steer)."""

from __future__ import annotations

import argparse
import sys
import warnings
from typing import TYPE_CHECKING

from cdpm.errors import InputError

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot


def add_tension_arguments(parser: argparse.ArgumentParser, best: bool = False) -> None:
    """Add --tension METHOD|F... and --pretension N; with ``best`` also
    ``--tension best`` (the search over the feasible tensions) and
    ``--objective poc|margin``."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.cli.plot import argument_type

    search = (
        "; best: the spec's method and also the search over every feasible equilibrium "
        "tension for a POC one of largest reach margin (--objective)"
        if best
        else ""
    )
    parser.add_argument(
        "--tension",
        nargs="+",
        metavar="METHOD|F",
        help="equilibrium method (zero, min_norm, pretension) or one tension per cable [N]; "
        f"default: the spec's equilibrium.method (min_norm if none){search}",
    )
    if best:
        parser.add_argument(
            "--objective",
            choices=("poc", "margin"),
            help="with --tension best: poc (default) finds whether some feasible tension is POC "
            "and picks the POC candidate of largest reach margin; margin also refines it "
            "towards a larger margin",
        )
    parser.add_argument(
        "--pretension",
        type=argument_type(_pretension),
        metavar="N",
        help="least tension of every cable for the pretension method [N] "
        "(default: the spec's equilibrium.pretension); an error with any other method",
    )


def _pretension(text: str) -> float:
    """--pretension: a number or arithmetic (parse_number: ``10*pi``), in
    [0, MAX_TENSION] N."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.equilibrium import checked_pretension
    from cdpm.model.spec import parse_number

    try:
        value = parse_number(text)
    except ValueError as exc:
        raise InputError(f"--pretension takes a tension in N: {exc}") from None
    return checked_pretension(value)


#: how the per-pose commands spell the options that fix an equilibrium
#: problem (the keys of :data:`cdpm.dynamics.equilibrium.PYTHON_OPTIONS`)
CLI_OPTIONS: dict[str, str] = {
    "method_option": "--tension {}",
    "pretension_option": "--pretension {}",
    "omit_option": "leave out --tension",
}


def cli_equilibrium(function, *args, command: str = "cdpm", **kwargs):
    """Call ``function`` with the equilibrium's errors and warnings in this
    command's words: they name its options (--tension, --pretension)
    instead of Python arguments. Equilibrium warnings print once each to
    stderr as ``<command>: warning: ...``; other warnings pass through."""

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.equilibrium import (
        EquilibriumWarning,
        InfeasibleEquilibriumError,
        NotAnEquilibriumError,
    )

    caught: list = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", EquilibriumWarning)
            try:
                return function(*args, **kwargs)
            except (InfeasibleEquilibriumError, NotAnEquilibriumError) as exc:
                raise exc.spelled(**CLI_OPTIONS) from None
    finally:
        _show_warnings(caught, command)


def _show_warnings(caught: list, command: str) -> None:
    """Print the equilibrium warnings (once each, in this command's
    words) and re-issue the others."""

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.equilibrium import EquilibriumWarning

    shown = set()
    for warning in caught:
        if isinstance(warning.message, EquilibriumWarning):
            text = str(warning.message.spelled(**CLI_OPTIONS))
            if text not in shown:
                shown.add(text)
                print(f"{command}: warning: {text}", file=sys.stderr)
        else:
            warnings.warn_explicit(
                warning.message, warning.category, warning.filename, warning.lineno
            )


def cli_infeasible_message(result) -> str:
    """The error message of an infeasible equilibrium ``result``, naming
    this command's options."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.equilibrium import InfeasibleEquilibriumError

    return str(InfeasibleEquilibriumError(result).spelled(**CLI_OPTIONS))


def tension_from_args(robot: CableRobot, args: argparse.Namespace):
    """(tension setting, pretension) from --tension and --pretension, checked;
    the setting is ``"best"`` for ``--tension best`` where the command
    offers it (it has --objective)."""
    tension = tension_argument(args.tension, best=hasattr(args, "objective"))
    check_objective(tension, getattr(args, "objective", None))
    check_pretension(robot, tension, args.pretension)
    return tension, args.pretension


def check_objective(tension, objective: str | None) -> None:
    """--objective only means something with --tension best."""
    if objective is not None and tension != "best":
        raise InputError(
            f"--objective {objective} sets what the tension search looks for: add --tension "
            "best, or leave out --objective"
        )


def check_pretension(robot: CableRobot, tension, pretension: float | None) -> None:
    """--pretension only means something for the pretension method, and that
    method needs one (from the flag or the spec)."""

    if tension == "best":  # the spec's method, and the search
        tension = None
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


def tension_argument(values: list[str] | None, best: bool = False):
    """None, a method name, a list of tensions, or (with ``best``, for the
    commands that search the feasible tensions) ``"best"`` from ``--tension``."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.equilibrium import EQUILIBRIUM_METHODS
    from cdpm.model.spec import parse_number

    if not values:
        return None
    if "best" in values:
        if not best:
            raise InputError(
                "--tension best (the search over the feasible tensions) is an option of cdpm "
                f"analyze and cdpm map; here give a method ({', '.join(EQUILIBRIUM_METHODS)}) "
                "or one tension per cable in N"
            )
        if len(values) != 1:
            raise InputError(
                f"--tension best searches the tensions itself: give --tension best alone, or "
                f"the tensions without best (got {' '.join(values)})"
            )
        return "best"
    if len(values) == 1 and values[0] in EQUILIBRIUM_METHODS:
        return values[0]
    try:
        return [parse_number(v) for v in values]
    except ValueError as exc:
        raise InputError(
            f"--tension takes a method ({', '.join(EQUILIBRIUM_METHODS)}) or one tension "
            f"per cable in N: {exc}"
        ) from exc
