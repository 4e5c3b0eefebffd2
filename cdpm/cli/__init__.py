"""Command line: ``cdpm <command> ...``.

The CLI is thin: each command lives in its own module under
:mod:`cdpm.cli` with ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``, and calls library functions. Heavy imports happen
inside ``run`` so ``cdpm --help`` is instant.
"""

from __future__ import annotations

import argparse
import difflib
import errno
import importlib
import os
import signal
import sys
import threading
from typing import Any

from cdpm import __version__
from cdpm.errors import CdpmError

__all__ = ["main", "build_parser"]

#: command modules, in the order ``cdpm --help`` lists them
COMMAND_MODULES = (
    "cdpm.cli.analyze",
    "cdpm.cli.verify",
    "cdpm.cli.steer",
    "cdpm.cli.view",
    "cdpm.cli.picture",
    "cdpm.cli.map",
    "cdpm.cli.certify",
    "cdpm.cli.plot",
    "cdpm.cli.path",
    "cdpm.cli.find",
    "cdpm.cli.import_caspr",
)

_EPILOG = """\
examples:
  cdpm analyze models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm analyze models/two_link_planar/two_link_planar.yaml --q pi/6 pi/3 --json
  cdpm map models/two_link_vertical/two_link_vertical.yaml \\
      --axis q1=-pi:pi:121 --axis q2=-pi:pi:121 --out vertical.zarr --plot vertical.png
  cdpm certify models/two_link_planar/two_link_planar.yaml \\
      --axis q1=-pi:pi:61 --axis q2=-pi:pi:61 --out certified.zarr --plot certified.png
  cdpm path vertical.zarr --from nominal --to -2.6 2.4 --maximin --plot path.png
  cdpm find models/two_link_vertical --where poc --count 3
  cdpm verify models/two_link_planar/two_link_planar.yaml --pose nominal --plot verify.png
  cdpm view models/two_link_planar/two_link_planar.yaml --pose nominal

each command's --help lists its options.
"""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every command."""
    parser = argparse.ArgumentParser(
        prog="cdpm",
        description=(
            "Positive output controllability of cable-driven parallel manipulators: "
            "load a URDF + cable spec, linearise at a pose, decide whether pulling "
            "cables can drive the output anywhere near it."
        ),
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"cdpm {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        module = importlib.import_module(name)
        cmd = sub.add_parser(
            module.NAME,
            help=module.HELP,
            description=module.DESCRIPTION,
            epilog=getattr(module, "EPILOG", None),
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def _unknown_command(argv: list[str]) -> str | None:
    """The error for a first argument that is neither an option nor a
    command, with the nearest command names (``cdpm anlyze`` -> "did you
    mean 'analyze'?"); None when the first argument is fine."""
    if not argv or argv[0].startswith("-"):
        return None
    names = [name.rsplit(".", 1)[1].replace("_", "-") for name in COMMAND_MODULES]
    if argv[0] in names:
        return None
    near = difflib.get_close_matches(argv[0], names, n=2, cutoff=0.6)
    hint = f"did you mean {' or '.join(repr(n) for n in near)}? " if near else ""
    return f"unknown command {argv[0]!r}; {hint}commands: {', '.join(names)} (cdpm --help)"


def _protect_negative_numbers(argv: list[str]) -> list[str]:
    """Let values such as ``-pi/6`` follow an option without being taken for
    an option themselves (argparse only recognises plain negative numbers)."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.spec import parse_number

    out = []
    for token in argv:
        if token.startswith("-") and not token.startswith("--") and len(token) > 1:
            try:
                parse_number(token)
            except ValueError:
                pass
            else:
                token = _PROTECTED + token
        out.append(token)
    return out


#: the prefix that hides a negative number from argparse's option matching
_PROTECTED = " "


def _unprotect(value: Any) -> Any:
    """A parsed value without the prefix :func:`_protect_negative_numbers`
    added (numbers parse either way; a name such as a pose ``-1`` must not
    keep it), in lists too."""
    if isinstance(value, str) and value.startswith(_PROTECTED + "-"):
        return value[len(_PROTECTED) :]
    if isinstance(value, list):
        return [_unprotect(v) for v in value]
    return value


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (0 ok, 1 error, 2 usage; some
    commands add their own, listed in their --help: 3 analyze found no
    equilibrium, 3 path found no connection)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    unknown = _unknown_command(argv)
    if unknown is not None:
        print(f"cdpm: error: {unknown}", file=sys.stderr)
        return 2
    parser = build_parser()
    args = parser.parse_args(_protect_negative_numbers(argv))
    for name, value in vars(args).items():
        setattr(args, name, _unprotect(value))
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    previous = _terminate_as_interrupt()
    try:
        return int(args._run(args) or 0)
    except CdpmError as exc:
        print(f"cdpm {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:
        # output piped into e.g. `head`, which closed early: not an error

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        # a file or folder the system refused (unwritable, missing parent,
        # name too long...): one line naming it, never a traceback

        name = exc.filename if exc.filename is not None else ""
        what = f" {name!r}" if name else ""
        out = getattr(args, "out", None)
        if out and name and os.sep not in str(name) and str(name) != str(out):
            # a store's file named by its key (c.0.0)
            what += f" (writing {out})"
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            if not name and out:  # the error names no file: the command's outputs
                plot = getattr(args, "plot", None)
                what = f" {str(out)!r}" + (f" or {str(plot)!r}" if plot else "")
            problem = f"cannot write{what}"
            fix = "free some space, or write elsewhere"
        else:
            problem = f"cannot use{what}"
            fix = "choose a path you can write to (its folder must exist)"
        print(
            f"cdpm {args.command}: error: {problem}: {exc.strerror or exc}; {fix}",
            file=sys.stderr,
        )
        return 1
    except MemoryError:
        print(
            f"cdpm {args.command}: error: not enough memory for this request; ask for "
            "fewer poses, a smaller picture or smaller chunks",
            file=sys.stderr,
        )
        return 1
    except KeyboardInterrupt:
        print(f"cdpm {args.command}: interrupted", file=sys.stderr)
        return 130
    finally:
        _restore_terminate(previous)


def _terminate_as_interrupt():
    """Handle SIGTERM like Ctrl-C (KeyboardInterrupt), so a terminated
    command cleans up (stops its workers, keeps finished map chunks) as an
    interrupted one does; returns the previous handler (None when signals
    cannot be set here, e.g. outside the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    return signal.signal(signal.SIGTERM, interrupt)


def _restore_terminate(previous) -> None:
    if previous is not None:
        signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
