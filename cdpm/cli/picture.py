"""``cdpm picture``: render a pose to an image file without a browser."""

from __future__ import annotations

import argparse

from cdpm.cli._pose import add_pose_arguments, pose_from_args
from cdpm.cli.plot import argument_type

NAME = "picture"
HELP = "draw a pose (robot, cables by state, outputs, POC verdict) to an image file"
DESCRIPTION = """\
Render the robot at one pose as a 2-D projection with matplotlib, headless:
links, base anchors, attachment points, cables coloured by state (taut:
blue, darker with more tension; slack: dashed pink; unavailable: dotted
grey), the outputs in the colour of the positive output controllability
verdict (green YES, red NO, amber MARGINAL): a star on each output point,
the axes of the frame of an orientation output (x red, y green, z blue), a
halo along a cable whose length is an output, a joint output named at its
joint; the legend gives the values of joint and cable outputs, the title the
verdict. The file's extension picks the format, as for cdpm plot (.png,
.pdf, .svg, .jpg, ...). Needs the viz extra: pip install "cdpm[viz]"."""
EPILOG = """\
examples:
  cdpm picture models/two_link_planar/two_link_planar.yaml --pose nominal -o pose.png
  cdpm picture models/two_link_planar/two_link_planar.yaml --q 0.3 1.2 --plane xy -o pose.svg
  cdpm picture models/two_link_vertical --pose nominal -o pose.jpg"""


def _picture_file(text: str):
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.plotting.picture import check_picture_path

    return check_picture_path(text)


def _picture_dpi(text: str) -> float:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.plotting.picture import check_picture_dpi

    return check_picture_dpi(text)


def _picture_title(text: str) -> str:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.plotting.picture import check_picture_title

    return check_picture_title(text)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="FILE",
        type=argument_type(_picture_file),
        help="image to write; the extension picks the format (.png, .pdf, .svg, .jpg, ...)",
    )
    parser.add_argument(
        "--plane",
        choices=("auto", "xy", "xz", "yz"),
        default="auto",
        help="projection plane (default: across the thinnest world axis of the scene)",
    )
    parser.add_argument(
        "--title",
        default=None,
        type=argument_type(_picture_title),
        help="figure title, drawn as written ($ is no maths) (default: pose and verdict)",
    )
    parser.add_argument(
        "--dpi", type=argument_type(_picture_dpi), default=110, help="resolution (default 110)"
    )


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.robot import load_robot
    from cdpm.plotting.picture import render_pose
    from cdpm.viewer import pose_state

    robot = load_robot(args.spec)
    q = pose_from_args(robot, args)
    state = pose_state(robot, q)
    render_pose(
        robot, q, args.output, plane=args.plane, title=args.title, dpi=args.dpi, state=state
    )
    print(
        f"wrote {args.output}: POC {state.verdict_key.upper()} at "
        f"{(state.natural.round(6) + 0.0).tolist()}"  # + 0.0: no -0.0
    )
    return 0
