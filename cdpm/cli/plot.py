"""``cdpm plot``: draw a workspace map stored by ``cdpm map``."""

from __future__ import annotations

import argparse

from cdpm.errors import CdpmError

NAME = "plot"
HELP = "draw a workspace map (zarr store) into an image"
DESCRIPTION = """\
Read a map written by `cdpm map ... --out STORE` and draw it, the map's first
axis horizontal:
  - the verdict over the first two axes (for more axes: slices along the
    third, further axes at their middle value; the title says what is left
    out), with the outlines and numbers of the POC regions when the map has
    them (for --variable poc only);
  - the reach margin r_T [the outputs' unit: m, rad, or m and rad counted one
    to one] within the map's horizon T on a log
    colour scale (maps without it: the unit-impulse POC margin), a few
    stragglers far beyond the 1st or 99th percentile clipped (the colour bar
    says so); zero margins in red, poses not analysed in greys by reason;
    no panel for a map made with --no-margin;
  - the poses in output space, coloured by verdict: by default the map's
    outputs (one output: against the first axis; two or more: the first two,
    or when one of them does not vary, the two that vary most), or those
    named with --outputs; where poses fall
    on one point, NO is drawn over YES over not analysed (the title says
    so); each axis says the output's unit ([rad] for rotations and revolute
    joints) and the formula of a joint, cable or sum output
    (docs/outputs.md).
A map over one axis is drawn as a verdict band along that axis above a line
of the margin. Maps of random samples are drawn as scatter plots. `cdpm path
... --plot` draws a path over the verdict and margin panels."""
EPILOG = """\
examples:
  cdpm plot map.zarr -o map.png
  cdpm plot map.zarr -o map.png --outputs tip_x tip_z
  cdpm plot map.zarr -o workspace.png --outputs tip.x tip.y   # the output frame's position
  cdpm plot map.zarr -o closure.pdf --variable wrench_closure --no-margin"""


def argument_type(check):
    """An argparse ``type`` from a cdpm check: the check's error message
    becomes argparse's (a usage error, exit code 2, before any work)."""

    def convert(text: str):
        try:
            return check(text.strip())
        except CdpmError as exc:  # InputError, or MissingExtraError with its pip hint
            raise argparse.ArgumentTypeError(str(exc)) from exc

    convert.__name__ = check.__name__
    return convert


def _dpi(text: str) -> float:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.plotting import check_dpi

    return check_dpi(text)


def _image(text: str):
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.plotting import check_image_path

    return check_image_path(text)


#: ``--dpi`` values: positive numbers (also used by ``cdpm picture``)
DPI_TYPE = argument_type(_dpi)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("store", metavar="STORE", help="zarr store written by cdpm map")
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="IMAGE",
        type=argument_type(_image),
        help="image to write; the extension picks the format (.png, .pdf, .svg, ...)",
    )
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.pipeline.criteria import verdict_criteria

    parser.add_argument(
        "--variable",
        default="poc",
        help=f"verdict to colour by: {', '.join(verdict_criteria())} (default poc)",
    )
    parser.add_argument(
        "--outputs",
        nargs="+",
        metavar="NAME",
        help="one or two quantities for the output-space panel: names of the map's outputs, "
        "or FRAME.x, FRAME.y, FRAME.z for the world position of the first output drawn at a "
        "frame; "
        "one is plotted against the first axis (default: the map's outputs; the first two "
        "of three or more)",
    )
    parser.add_argument("--no-margin", action="store_true", help="leave out the margin panel")
    parser.add_argument(
        "--no-output-view", action="store_true", help="leave out the output-space panel"
    )
    parser.add_argument("--dpi", type=DPI_TYPE, default=100, help="resolution (default 100)")


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps import open_map
    from cdpm.plotting import save_map_plot

    dataset = open_map(args.store)
    path = save_map_plot(
        dataset,
        args.output,
        dpi=args.dpi,
        variable=args.variable,
        margin=not args.no_margin,
        output_view=not args.no_output_view,
        outputs=args.outputs,
    )
    print(f"plot written to {path}")
    return 0
