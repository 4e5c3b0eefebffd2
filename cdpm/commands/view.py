"""``cdpm view``: serve a meshcat 3-D view of a pose until interrupted."""

from __future__ import annotations

import argparse
import signal
import sys
import time

from cdpm.commands._pose import Q_HELP, add_pose_arguments, pose_from_args

NAME = "view"
HELP = "serve a 3-D view of a pose in the browser (robot, cables, POC verdict)"
DESCRIPTION = """\
Start a meshcat viewer on 127.0.0.1 (never on other interfaces), draw the
robot at one pose with its cables coloured by state (taut: blue, darker with
more tension; slack: pink; unavailable: grey) and the output frame marker
coloured by the positive output controllability verdict (green YES, red NO,
amber MARGINAL), print the URL and serve until Ctrl-C. With --map, overlay a
workspace map (output positions coloured by verdict or margin). Needs the
viz extra: pip install "cdpm[viz]". From another machine, forward the port:
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
        "--port", type=int, default=None, help="web port (default: first free from 7000)"
    )
    parser.add_argument("--map", metavar="MAP", help="workspace map to overlay (.zarr or .nc)")
    parser.add_argument(
        "--color-by",
        choices=("verdict", "margin"),
        default="verdict",
        help="colour of the map points (default: verdict)",
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


def open_map(path: str):
    """An xarray map from a .zarr store or a netCDF file."""
    from pathlib import Path

    from cdpm.errors import InputError, MissingExtraError

    p = Path(path)
    if not p.exists():
        raise InputError(f"map {path!r} not found")
    try:
        import xarray as xr
    except ImportError as exc:
        raise MissingExtraError(
            f"reading a map needs xarray and zarr ({exc}); install them with: "
            "pip install xarray zarr"
        ) from exc
    try:
        if p.is_dir() or p.suffix == ".zarr":
            return xr.open_zarr(p)
        return xr.open_dataset(p)
    except (ValueError, OSError, KeyError) as exc:
        raise InputError(f"cannot read the map {path!r}: {exc}") from exc


def _exit_on_sigterm(signum, frame) -> None:
    sys.exit(128 + signum)


def run(args: argparse.Namespace) -> int:
    from cdpm.robot import load_robot
    from cdpm.viewer import Viewer

    # a plain `kill` also closes the viewer (and stops its server process)
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    robot = load_robot(args.spec)
    q = pose_from_args(robot, args)
    dataset = open_map(args.map) if args.map else None
    with Viewer(robot, q, port=args.port, geometry=args.geometry) as viewer:
        if dataset is not None:
            n = viewer.show_map(dataset, color_by=args.color_by)
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
