"""``cdpm view``: serve the inspection page of a pose (3-D view and verdict panel)
until interrupted."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import signal
import sys
import threading
import time
import warnings

from cdpm.cli._play import _seconds
from cdpm.cli._pose import Q_HELP, add_pose_arguments, pose_from_args
from cdpm.cli.plot import argument_type

NAME = "view"
HELP = "inspect poses in the browser: 3-D view, sliders and every verdict (127.0.0.1)"
DESCRIPTION = """\
Serve an inspection page on 127.0.0.1 (never on other interfaces): the
meshcat 3-D view of the robot beside a panel with a slider per natural
coordinate, the verdicts at the pose (positive output controllability with
its method and reach margin, Brammer positive controllability, output
controllability, wrench closure, static feasibility), each cable's state
and tension, the outputs with their units, the spec's named poses and a
"copy as --q" button. Moving a slider updates the scene and the panel.
Cables are coloured by state (taut: blue, darker with more tension; slack:
pink; unavailable: grey), the outputs' marks by the POC verdict (green YES,
red NO, amber MARGINAL): a marker on each output point, with the frame's
axes for an orientation output, and a sleeve on a cable whose length is an
output. With --map, overlay a workspace map made by `cdpm map` from the
same spec (output positions coloured by the POC verdict, its margin or
another map variable, --color-by; --allow-other-spec for a map made from
another spec file), with a toggle on the page. Prints the
verdicts and the URL, then serves until Ctrl-C (or for --seconds). Needs
the viz extra: pip install "cdpm[viz]". The page reaches the 3-D scene
through its own port, so one port is all a browser needs: open it as
127.0.0.1 or localhost, or from another machine forward it (ssh -L
7000:127.0.0.1:7000 HOST). The servers answer only requests naming a
loopback host, from the page itself; a mesh outside the model's folder (and
its package:// packages) is not loaded."""
EPILOG = (
    """\
examples:
  cdpm view models/two_link_planar/two_link_planar.yaml --pose nominal
  cdpm view models/two_link_planar/two_link_planar.yaml --q pi/4 pi/2 --port 7010
  cdpm view models/two_link_planar/two_link_planar.yaml --port 0 --scene-port 0 --seconds 60
  cdpm view models/two_link_planar/two_link_planar.yaml --map map.zarr --color-by margin

"""
    + Q_HELP
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pose_arguments(parser)
    parser.add_argument(
        "--port",
        type=argument_type(_any_port),
        default=None,
        help="port of the page, 1-65535, or 0 for any free port (default: first free from 7000)",
    )
    parser.add_argument(
        "--scene-port",
        type=argument_type(_any_port),
        default=None,
        help="port of the 3-D scene's own server, 1-65535, or 0 for any free port "
        "(default: first free from 7000, after the page's); the page reaches the "
        "scene through its own port, so a browser needs only the page's",
    )
    parser.add_argument(
        "--map", metavar="STORE", help="workspace map to overlay (zarr store from cdpm map)"
    )
    parser.add_argument(
        "--allow-other-spec",
        action="store_true",
        help="overlay a map made from another spec file (default: refuse it)",
    )
    # loaded when the command runs (cdpm --help stays fast)
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
        type=argument_type(_serve_seconds),
        default=None,
        help="serve this long then exit, at most "
        f"{threading.TIMEOUT_MAX:.3g} s (default: until Ctrl-C)",
    )


def _any_port(text: str) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.viewer import check_port

    return check_port(text, any_free=True)


def _serve_seconds(text: str) -> float:
    """--seconds: a time [s] the clock can wait (``1e300`` overflows it)."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.errors import InputError

    value = _seconds(text)
    if value > threading.TIMEOUT_MAX:
        raise InputError(
            f"--seconds {text} is longer than this system can wait "
            f"({threading.TIMEOUT_MAX:.3g} s); omit it to serve until Ctrl-C"
        )
    return value


def _exit_on_sigterm(signum, frame) -> None:
    sys.exit(128 + signum)


def map_settings_note(dataset, robot) -> str | None:
    """A sentence when the map was computed with other equilibrium settings
    (tension method, given tensions, pretension, gravity or tension-bound
    overrides) than the ones the page analyses with (the spec's), else None."""

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.pipeline.evaluate import resolve_tension

    made = []
    stored = json.loads(dataset.attrs.get("tension", "null"))
    own = resolve_tension(robot, None)
    if stored is not None and stored != own:
        made.append(f"tension {stored!r} (the spec's method is {own!r})")
    overrides = json.loads(dataset.attrs.get("overrides", "{}") or "{}")
    if overrides:
        made.append("overrides " + ", ".join(f"{k} {v}" for k, v in overrides.items()))
    if not made:
        return None
    return (
        f"the map was made with {'; '.join(made)}; the panel analyses each pose with the "
        "spec's own settings, so map colours and panel verdicts can differ"
    )


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.errors import InputError
    from cdpm.model.robot import load_robot
    from cdpm.viewer import check_map_spec
    from cdpm.viewer.page import InspectionPage
    from cdpm.viewer.scene import _import_meshcat

    if args.port and args.port == args.scene_port:
        raise InputError(
            f"--port and --scene-port are both {args.port}: the page and the scene need two "
            "ports (give another --scene-port, or 0 for any free one)"
        )
    # a plain `kill` also closes the page (and stops the meshcat server process)
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    robot = load_robot(args.spec)
    q = pose_from_args(robot, args)
    _import_meshcat()  # a missing viz extra fails before anything is loaded
    dataset = None
    if args.map:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.maps import open_map

        # before the server starts
        dataset = open_map(args.map)
        if not args.allow_other_spec:
            check_map_spec(dataset, robot, override="--allow-other-spec")
        made_with = map_settings_note(dataset, robot)
        if made_with:
            print(f"cdpm view: note: {made_with}", file=sys.stderr)
    with contextlib.ExitStack() as stack:
        # the scene's warnings (e.g. a mesh not found) as one line each
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UserWarning)
            page = stack.enter_context(
                InspectionPage(
                    robot,
                    q,
                    port=args.port,
                    scene_port=args.scene_port,
                    dataset=dataset,
                    map_name=args.map,
                    color_by=args.color_by,
                    geometry=args.geometry,
                )
            )
        for warning in caught:
            if issubclass(warning.category, UserWarning):
                print(f"cdpm view: warning: {warning.message}", file=sys.stderr)
            else:  # not ours to reword (e.g. ResourceWarning under -W)
                warnings.warn_explicit(
                    warning.message, warning.category, warning.filename, warning.lineno
                )
        if dataset is not None:
            print(f"map: {page.map_points} poses from {args.map}, coloured by {args.color_by}")
        print(page.panel)
        print(f"scene alone: {page.viewer.url()}")
        until = "Ctrl-C to stop" if args.seconds is None else f"for {args.seconds:g} s"
        print(f"viewer: {page.url}  ({until})", flush=True)
        try:
            deadline = math.inf if args.seconds is None else time.monotonic() + args.seconds
            # an hour at a time: one long sleep past the clock's range fails
            while (left := deadline - time.monotonic()) > 0:
                time.sleep(min(left, 3600.0))
            if args.seconds is not None:
                print(f"stopped after {args.seconds:g} s", file=sys.stderr)
        except KeyboardInterrupt:
            print("stopped", file=sys.stderr)
            return 130
    return 0
