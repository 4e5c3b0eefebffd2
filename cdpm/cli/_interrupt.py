"""What ``cdpm map`` and ``cdpm certify`` say after Ctrl-C or SIGTERM: how
to go on from the chunks their store kept."""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["interrupted"]

#: the exit status of an interrupted command (128 + SIGINT)
INTERRUPTED_EXIT = 130


def interrupted(command: str, out: str | None, store: str | None) -> int:
    """Print how to go on after an interrupt and return the exit status.

    Args:
        command: the command's name (``map``, ``certify``).
        out: the store the user asked for (``--out``), or None.
        store: the store the run had opened, or None when it had not yet.
    """
    if out and store is None:
        hint = f"{out} was not opened yet: run the same command again to make or resume it"
    elif out:
        done = Path(store) / ".cdpm" / "done"
        try:
            finished = sum(p.name.isdigit() for p in done.iterdir()) if done.is_dir() else 0
        except OSError:
            finished = 0
        if finished:
            chunks = "chunk is" if finished == 1 else "chunks are"
            hint = (
                f"the {finished} finished {chunks} kept in {out}: run the same command "
                "again to resume from them"
            )
        else:
            hint = f"no chunk was finished yet: run the same command again to make {out}"
    else:
        hint = "nothing was kept: add --out STORE to keep finished chunks and resume later"
    print(f"cdpm {command}: interrupted; {hint}", file=sys.stderr)
    # Python remembers an interrupt that went through an exec() of a string
    # (dataclasses and some lazy imports run one) even once it is handled,
    # and `python -m cdpm` then ended by SIGINT instead of this exit code
    # (now and then, when Ctrl-C or SIGTERM came in such a call); an exec
    # that completes forgets it
    exec("pass")
    return INTERRUPTED_EXIT
