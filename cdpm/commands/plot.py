"""``cdpm plot``: draw a workspace map stored by ``cdpm map``."""

from __future__ import annotations

import argparse

NAME = "plot"
HELP = "draw a workspace map (zarr store) into an image"
DESCRIPTION = """\
Read a map written by `cdpm map ... --out STORE` and draw it: the verdict over
the first two axes (slices for more axes), the POC margin, and the poses in
output space coloured by verdict."""
EPILOG = """\
examples:
  cdpm plot map.zarr -o map.png
  cdpm plot map.zarr -o closure.png --variable wrench_closure --no-margin"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("store", metavar="STORE", help="zarr store written by cdpm map")
    parser.add_argument("-o", "--output", required=True, metavar="PNG", help="image to write")
    parser.add_argument(
        "--variable",
        default="poc",
        help="verdict to colour by: poc (default), output_controllable, "
        "positive_controllable, wrench_closure, static_feasible",
    )
    parser.add_argument("--no-margin", action="store_true", help="leave out the margin panel")
    parser.add_argument(
        "--no-output-view", action="store_true", help="leave out the output-space panel"
    )
    parser.add_argument("--dpi", type=int, default=100, help="resolution (default 100)")


def run(args: argparse.Namespace) -> int:
    from cdpm.plotting import save_map_plot

    path = save_map_plot(
        args.store,
        args.output,
        dpi=args.dpi,
        variable=args.variable,
        margin=not args.no_margin,
        output_view=not args.no_output_view,
    )
    print(f"plot written to {path}")
    return 0
