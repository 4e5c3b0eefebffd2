"""``cdpm view``: serve a meshcat 3-D view of a pose until interrupted."""

from __future__ import annotations

import argparse
import signal
import sys
import time

from cdpm.commands._play import _port
from cdpm.commands._pose import Q_HELP, add_pose_arguments, pose_from_args
from cdpm.commands.plot import argument_type

NAME = "view"
HELP = "serve a 3-D view of a pose in the browser (robot, cables, POC verdict)"
DESCRIPTION = """\
Start a meshcat viewer on 127.0.0.1 (never on other interfaces), draw the
robot at one pose with its cables coloured by state (taut: blue, darker with
more tension; slack: pink; unavailable: grey) and the output frame marker
coloured by the positive output controllability verdict (green YES, red NO,
amber MARGINAL), print the URL and serve until Ctrl-C. With --map, overlay a
workspace map made by `cdpm map` from the same spec (output positions
coloured by the POC verdict, its margin or another map variable, --color-by;
--allow-other-spec for a map made from another spec file). Needs the viz
extra: pip install "cdpm[viz]". From another machine, forward the port:
ssh -L 7000:127.0.0.1:7000 HOST."""
EPILOG = (
    """\
examples:
  cdpm view models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm view models/two_link_planar/two_link_planar.yaml --q pi/4 pi/2 --port 7010
  cdpm view models/two_link_planar/two_link_planar.yaml --map map.zarr --color-by margin

"""
    + Q_HELP
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    parser.add_argument(
        "--port",
        type=argument_type(_port),
        default=None,
        help="web port, 1-65535 (default: first free from 7000)",
    )
    parser.add_argument(
        "--map", metavar="STORE", help="workspace map to overlay (zarr store from cdpm map)"
    )
    parser.add_argument(
        "--allow-other-spec",
        action="store_true",
        help="overlay a map made from another spec file (default: refuse it)",
    )
    from cdpm.viewer.overlay import color_choices

    parser.add_argument(
        "--color-by",
        choices=color_choices(),
        default="verdict",
        help="colour of the map points: the POC verdict, its margin or another map "
        "criterion (default: verdict)",
    )
    parser.add_argument(
        "--geometry",
        choices=("auto", "urdf", "generated"),
        default="auto",
        help="link geometry: URDF visuals or generated (default: URDF when it has some)",
    )
    parser.add_argument(
        "--seconds",
        type=float,
        default=None,
        help="serve this long then exit (default: until Ctrl-C)",
    )


def _exit_on_sigterm(signum, frame) -> None:
    sys.exit(128 + signum)


def run(args: argparse.Namespace) -> int:
    from cdpm.robot import load_robot
    from cdpm.viewer import Viewer, check_map_spec

    # a plain `kill` also closes the viewer (and stops its server process)
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    robot = load_robot(args.spec)
    q = pose_from_args(robot, args)
    dataset = None
    if args.map:
        from cdpm.maps import open_map

        # before the server starts
        dataset = open_map(args.map)
        if not args.allow_other_spec:
            check_map_spec(dataset, robot, override="--allow-other-spec")
    with Viewer(robot, q, port=args.port, geometry=args.geometry) as viewer:
        if dataset is not None:
            n = viewer.show_map(dataset, color_by=args.color_by, check_spec=False)  # checked
            print(f"map: {n} poses from {args.map}, coloured by {args.color_by}")
        print(viewer.state)
        print(f"viewer: {viewer.url()}  (Ctrl-C to stop)", flush=True)
        try:
            if args.seconds is not None:
                time.sleep(max(args.seconds, 0.0))
            else:
                while True:
                    time.sleep(3600)
        except KeyboardInterrupt:
            print("stopped", file=sys.stderr)
            return 130
    return 0
