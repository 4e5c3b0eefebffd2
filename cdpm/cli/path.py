"""``cdpm path``: a path of POC poses between two poses of a map."""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.cli._play import add_play_arguments, check_play_arguments
from cdpm.cli.plot import argument_type
from cdpm.cli.verify import _image
from cdpm.errors import InputError
from cdpm.expressions import parse_number
from cdpm.printing import json_text

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

NAME = "path"
HELP = "a path of POC poses between two poses of a map or certified map (inside one region)"
DESCRIPTION = """\
Read a map written by `cdpm map ... --out STORE`, move the start and the goal
to their nearest map poses and find a path of positive output controllable
(POC) map poses joining them inside one POC region (seed paper Lemma 1 /
Remark 10: along it pull-only cables can drive the output from pose to pose).
Grid maps step between face-adjacent poses (wrapping around angles that span a
full turn), sampled maps between samples within the neighbourhood radius (over
one axis, between consecutive samples).
Prints the region, the number of waypoints, the length, the smallest margin
and the waypoints, and warns of steps that may cross a NO set thinner than
the map's resolution (where the reach margin r_T at both ends is within one
step's change of 0); --maximin maximises the smallest margin along the path
(of the waypoints between the two ends, whose margins are given) instead of
taking the shortest, avoiding such steps where it can. --plot
draws the map with the path (blue; the warned steps magenta; with --steer the
title says which legs missed), --view plays the path in the 3-D viewer,
--steer steers the simulated nonlinear robot from waypoint to waypoint and
prints the miss at each (and, for a leg that missed, why).

On a certified map (`cdpm certify ... --out STORE`) the path is made of
straight steps, each inside one certified YES box of one certified region
(YES boxes sharing a face), so every pose along it is proven POC; the start
and goal are not moved and must lie in YES boxes of the same region (else the
message names the box holding each, its verdict and the nearest certified
region). --maximin keeps to boxes of large margin lower bound; --steer steers
one leg per step (both ends in one certified box); --plot draws the boxes
(YES green, the path's region darker, NO red, undecided hatched) and the
path."""
EPILOG = """\
examples:
  cdpm path map.zarr --from nominal --to 2.5 -1.5
  cdpm path map.zarr --from pi/6 pi/3 --to 3 -2 --maximin --plot path.png
  cdpm path vertical.zarr --from 0.2 0.8 --to 0.2 1.25 --steer --legs 2
  cdpm path certified.zarr --from nominal --to 0 2 --steer --plot path.png

V values are the map's axis values in the order of its axes (printed with
every path), arithmetic such as pi/6 accepted; or the robot's natural
coordinates (one per coordinate; those off the map's axes must be at the
map's base pose); or one pose name of the map's spec.

exit codes: 0 a path was found (and, with --steer, every leg reached its
waypoint's output); 3 the start and goal are not joined by POC poses
(different regions, or one of them in none; the message names both); 4 with
--steer, a leg missed its waypoint's output (the table says which); 1 other
errors (unknown store, a pose off the map or of the wrong length); 2 usage
errors (unknown or missing options)."""

#: exit code when no path of POC poses joins start and goal
NOT_CONNECTED_EXIT = 3
#: exit code when --steer steered a leg that missed its waypoint's output
LEG_MISSED_EXIT = 4
#: --steer without --legs: one leg per this many steps (short legs are
#: steered well from a linear plan) ...
STEPS_PER_LEG = 5
#: ... and at most this many legs (a leg takes about a second)
MAX_DEFAULT_LEGS = 20
#: --steer: durations tried per leg, in units of steering's default duration
LEG_DURATION_FACTORS = (1.0, 4.0, 16.0)
#: --steer: a leg that misses by at most LEG_NEAR_MISS_FACTOR times its
#: tolerance (the shooting converging, slowly) is tried again first with
#: LEG_ITERATION_FACTOR times steering's shooting iterations, same duration
LEG_NEAR_MISS_FACTOR = 10.0
LEG_ITERATION_FACTOR = 3
#: playback time per path step with --view [s]
VIEW_STEP_SECONDS = 0.15


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("map", metavar="MAP", help="zarr store written by cdpm map or cdpm certify")
    parser.add_argument(
        "--from",
        dest="start",
        nargs="+",
        required=True,
        metavar="V",
        help="the start: axis values in the map's order, or a pose name of the map's spec",
    )
    parser.add_argument(
        "--to",
        dest="goal",
        nargs="+",
        required=True,
        metavar="V",
        help="the goal: axis values in the map's order, or a pose name of the map's spec",
    )
    parser.add_argument(
        "--maximin",
        action="store_true",
        help="maximise the smallest margin along the path, the ends' given (then the "
        "shortest such path)",
    )
    parser.add_argument(
        "--plot",
        type=argument_type(_image),
        metavar="IMAGE",
        help="draw the map with the path into IMAGE",
    )
    add_play_arguments(parser, "the path")
    parser.add_argument(
        "--steer",
        action="store_true",
        help="steer the simulated nonlinear robot from waypoint to waypoint (cdpm.steer), "
        f"print the miss at each and how many legs reached; exit code {LEG_MISSED_EXIT} when "
        "a leg missed",
    )
    parser.add_argument(
        "--legs",
        type=int,
        default=None,
        metavar="N",
        help="with --steer: N legs between N + 1 waypoints spread evenly along the path, "
        f"start and goal included (default: one per {STEPS_PER_LEG} steps, at most "
        f"{MAX_DEFAULT_LEGS}; a leg takes about a second, up to tens of seconds when it "
        "cannot reach)",
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps import open_map
    from cdpm.maps.regions import REGION_VARIABLE, attach_regions
    from cdpm.regions.paths import NotConnectedError, poc_path
    from cdpm.text.regions import path_json, path_text, path_warnings

    check_play_arguments(args, "the path")
    if args.legs is not None and not args.steer:
        raise InputError("--legs goes with --steer (how many legs to steer)")
    if args.legs is not None and args.legs < 1:
        raise InputError(f"--legs must be a positive number of legs, got {args.legs}")
    if _is_certified_store(args.map):
        return _run_certified(args)
    ds = open_map(args.map)
    if REGION_VARIABLE not in ds.data_vars:
        ds = attach_regions(ds)  # a map made before regions were stored
    robot = _robot_of_map(ds)
    start = _pose_argument(ds, robot, args.start, "--from")
    goal = _pose_argument(ds, robot, args.goal, "--to")
    try:
        path = poc_path(ds, start, goal, maximise_margin=args.maximin)
    except NotConnectedError as exc:
        if args.json:
            print(json_text(_not_connected_dict(exc)))
        print(f"cdpm path: not connected: {exc}", file=sys.stderr)
        return NOT_CONNECTED_EXIT
    out = sys.stderr if args.json else sys.stdout  # keep --json output parseable
    if not args.json:
        print(f"map {args.map}: axes {', '.join(path.axes)}")
        print(path_text(path))
    else:
        for line in path_warnings(path):
            print(f"cdpm path: {line}", file=sys.stderr)
    legs = None
    if args.steer:
        legs = _steer_path(robot.get("--steer"), ds, path, args.legs or _default_legs(path), out)

    def draw(subtitle):
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.plotting import save_map_plot

        return save_map_plot(ds, args.plot, path=path, subtitle=subtitle)

    _plot_and_json(args, robot, legs, draw, path_json(path), out)
    if args.view:
        _view(robot.get("--view"), ds, path, args, out)
    return LEG_MISSED_EXIT if legs and not all(leg["reached"] for leg in legs) else 0


def _is_certified_store(store: str) -> bool:
    """Whether ``store`` is a certified map store (``cdpm certify ... --out``):
    its zarr group says so (attribute ``cdpm_kind``)."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.certify.store import KIND

    meta = Path(store).expanduser() / "zarr.json"
    try:
        attrs = json.loads(meta.read_text(encoding="utf-8")).get("attributes", {})
    except (OSError, ValueError, AttributeError):
        return False  # not a zarr v3 group: open_map says what it is
    return isinstance(attrs, dict) and attrs.get("cdpm_kind") == KIND


def _open_certified(store: str):
    """The certified map of a store (:func:`cdpm.open_certified`)."""
    import cdpm

    opener = getattr(cdpm, "open_certified", None)
    if opener is None:  # not exported at the top level (yet)
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.certify.map import open_certified as opener
    return opener(store)


def _run_certified(args: argparse.Namespace) -> int:
    """``cdpm path`` on a certified map: a path of straight steps, each
    inside one certified YES box of one certified region
    (:func:`cdpm.regions.certified.certified_path`)."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.regions.certified import certified_path
    from cdpm.regions.paths import NotConnectedError
    from cdpm.text.regions import certified_path_json, certified_path_text

    if args.legs is not None:
        raise InputError(
            "--legs does not apply to a certified map: each leg is one step of the certified "
            "path, inside one certified box (leave out --legs)"
        )
    cmap = _open_certified(args.map)
    robot = _robot_of_certified(cmap)
    start = _certified_pose(cmap, robot, args.start, "--from")
    goal = _certified_pose(cmap, robot, args.goal, "--to")
    try:
        path = certified_path(cmap, start, goal, maximise_margin=args.maximin, robot=robot.robot)
    except NotConnectedError as exc:
        if args.json:
            print(json_text(_not_connected_dict(exc)))
        print(f"cdpm path: not connected: {exc}", file=sys.stderr)
        if args.plot and exc.start_pose and exc.goal_pose:
            # loaded when the command runs (cdpm --help stays fast)
            from cdpm.plotting.certified_path import save_certified_path_plot

            ends = [list(exc.start_pose.values()), list(exc.goal_pose.values())]
            written = save_certified_path_plot(
                cmap, args.plot, ends=ends, subtitle="not connected: no certified path joins them"
            )
            print(f"plot written to {written} (the map, the start and the goal)", file=sys.stderr)
        return NOT_CONNECTED_EXIT
    out = sys.stderr if args.json else sys.stdout  # keep --json output parseable
    if not args.json:
        print(f"certified map {args.map}: coordinates {', '.join(cmap.coordinates)}")
        for line in _turned_ends(cmap, (start, path.start), (goal, path.goal)):
            print(line)
        print(certified_path_text(path))
    legs = None
    if args.steer:
        r = robot.get("--steer")
        pairs = [(i, i + 1) for i in range(path.n_steps)]
        if not pairs:
            print("steering: start and goal are the same pose; nothing to steer", file=out)
        else:
            why = "one leg per step: both ends of each leg in one certified YES box"
            legs = _steer_legs(r, path.natural, pairs, None, out, why)

    def draw(subtitle):
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.plotting.certified_path import save_certified_path_plot

        return save_certified_path_plot(cmap, args.plot, path=path, subtitle=subtitle)

    _plot_and_json(args, robot, legs, draw, certified_path_json(path), out)
    if args.view:
        r = robot.get("--view")
        _play(r, _waypoint_trajectory(r, path.natural, None), args, out)
    return LEG_MISSED_EXIT if legs and not all(leg["reached"] for leg in legs) else 0


def _turned_ends(cmap, *ends) -> list[str]:
    """Lines naming an end given beyond a full-turn axis' range: the same
    pose, a whole number of turns away on the map; ``ends``: (as given, as
    on the map) pairs over the mapped coordinates."""
    lines = []
    for word, (given, held) in zip(("start", "goal"), ends, strict=True):
        g = np.asarray(given, dtype=float).reshape(-1)
        h = np.asarray(held, dtype=float).reshape(-1)
        if g.size != h.size:  # a pose name: natural coordinates, on the map
            continue
        turns = (g - h) / (2 * np.pi)
        moved = [
            f"{name} = {a:.6g} is {name} = {b:.6g} on the map"
            for name, a, b, t in zip(cmap.coordinates, g, h, turns, strict=True)
            if abs(t) > 1e-12 and abs(t - round(t)) < 1e-9
        ]
        if moved:
            lines.append(f"  the {word}'s {'; '.join(moved)} (whole turns of a full-turn axis)")
    return lines


def _numbers(tokens: list[str]) -> list[float] | None:
    """The tokens as numbers (pi/6 etc. allowed), or None when one is not."""
    try:
        return [parse_number(token) for token in tokens]
    except (TypeError, ValueError):
        return None


def _certified_pose(cmap, robot: _MapRobot, tokens: list[str], option: str) -> Any:
    """A pose from --from/--to on a certified map: numbers (the mapped
    coordinates in the map's order, or natural coordinates), or one pose
    name of the map's spec (its natural coordinates)."""
    tokens = [t.strip() for t in tokens]
    numbers = _numbers(tokens)
    if numbers is not None:
        return numbers
    if len(tokens) == 1:
        r = robot.get(f"{option} {tokens[0]} (a pose name)")
        try:
            return np.asarray(r.to_natural(r.configuration(tokens[0])), dtype=float)
        except (KeyError, ValueError) as exc:
            raise InputError(f"{option} {tokens[0]}: {exc}") from exc
    raise InputError(
        f"{option} {' '.join(tokens)}: give numbers (values of {', '.join(cmap.coordinates)}, "
        "e.g. pi/6) or one pose name of the map's spec"
    )


class _MapRobot:
    """A map's robot, loaded on first use from the spec the map records and
    checked against the spec's hash: ``load(why)`` is
    :func:`cdpm.maps.regions.map_robot` for a sampled map,
    :func:`cdpm.regions.certified.certified_map_robot` for a certified one."""

    def __init__(self, load):
        self.load, self.robot = load, None

    def get(self, why: str) -> CableRobot:
        if self.robot is None:
            self.robot = self.load(why)
        return self.robot


def _robot_of_map(ds) -> _MapRobot:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps.regions import map_robot

    return _MapRobot(lambda why: map_robot(ds, why))


def _robot_of_certified(cmap) -> _MapRobot:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.regions.certified import certified_map_robot

    return _MapRobot(lambda why: certified_map_robot(cmap, why))


def _pose_argument(ds, robot: _MapRobot, tokens: list[str], option: str) -> Any:
    """A pose from --from/--to: numbers (map axis order, or natural
    coordinates), or one pose name of the map's spec; checked against the
    map (a pose off the map or of the wrong length is an InputError naming
    the option)."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps.regions import map_layout, named_pose, nearest_index, region_labels

    tokens = [t.strip() for t in tokens]
    numbers = _numbers(tokens)
    if numbers is None and len(tokens) == 1:
        r = robot.get(f"{option} {tokens[0]} (a pose name)")
        try:
            pose: Any = named_pose(ds, tokens[0], r)
        except InputError as exc:
            raise InputError(f"{option} {tokens[0]}: {exc}") from exc
    elif numbers is None:
        raise InputError(
            f"{option} {' '.join(tokens)}: give numbers (the map's axis values, e.g. pi/6) or "
            "one pose name of the map's spec"
        )
    else:
        pose = numbers
    layout = map_layout(ds)
    try:
        radius = region_labels(ds).attrs.get("radius") if layout.mode == "sample" else None
        nearest_index(ds, layout, pose, radius)
    except InputError as exc:
        raise InputError(f"{option} {' '.join(tokens)}: {exc}") from exc
    return pose


def _not_connected_dict(exc) -> dict:
    return {
        "connected": False,
        "message": str(exc),
        "start_region": exc.start_region,
        "goal_region": exc.goal_region,
        "start_pose": exc.start_pose,
        "goal_pose": exc.goal_pose,
        "start_size": exc.start_size,
        "goal_size": exc.goal_size,
    }


def _map_tension(ds):
    """The map's equilibrium tension setting (a method name or tensions [N])."""
    text = ds.attrs.get("tension")
    return None if text is None else json.loads(text)


def _default_legs(path) -> int:
    """One leg per STEPS_PER_LEG steps, at most MAX_DEFAULT_LEGS."""
    steps = max(path.n_waypoints - 1, 1)
    return min(-(-steps // STEPS_PER_LEG), MAX_DEFAULT_LEGS)


def _plot_and_json(args, robot, legs, draw, path_data: dict, out) -> None:
    """The path's picture (``draw(subtitle)`` writes it; the legs' outcome
    as its subtitle) and its JSON (the path's ``path_data``, with the
    steering's legs), as the options ask."""
    if args.plot:
        subtitle = None if legs is None else _legs_caption(legs, _miss_unit(robot.get("--steer")))
        print(f"plot written to {draw(subtitle)}", file=out)
    if args.json:
        result = {"connected": True, **path_data}
        if legs is not None:
            result["steering"] = legs
            result["legs_reached"] = sum(leg["reached"] for leg in legs)
        print(json_text(result))


def _steer_path(robot: CableRobot, ds, path, legs: int, out) -> list[dict]:
    """Steer the nonlinear robot along ``legs`` legs of a map's path: from
    rest at the equilibrium of one chosen waypoint to the output of the
    next (:func:`_steer_legs`)."""
    k = path.n_waypoints
    if k == 1:
        print("steering: start and goal are the same map pose; nothing to steer", file=out)
        return []
    n = min(int(legs), k - 1)
    stops = np.unique(np.round(np.linspace(0, k - 1, n + 1)).astype(int))
    pairs = [(int(i), int(j)) for i, j in zip(stops[:-1], stops[1:], strict=True)]
    return _steer_legs(robot, path.natural, pairs, _map_tension(ds), out)


def _steer_legs(robot: CableRobot, natural, pairs, tension, out, why=None) -> list[dict]:
    """Steer the nonlinear robot along legs: leg (i, j) from rest at the
    equilibrium of waypoint i (natural coordinates ``natural[i]``) to the
    output of waypoint j.

    Each leg is tried with steering's default duration (made for small
    moves) and its STEER_ITERATIONS shooting iterations; a leg that misses
    by at most LEG_NEAR_MISS_FACTOR times its tolerance is tried again with
    LEG_ITERATION_FACTOR times the iterations (the shooting corrects the
    nonlinear miss slowly where the plan's gain is off: on the gravity arm
    a 0.15 m leg came within 3.3e-4 m of its 1.5e-4 m tolerance in 12
    iterations and reached it in 14), then with
    LEG_DURATION_FACTORS times the duration, at most the longest steering
    accepts at the waypoint (:func:`cdpm.steering.shooting.longest_duration`).
    The attempt shown is the one that reached, else the one of least miss.

    Returns:
        One dict per leg: from, to (waypoint numbers), distance |y_to - y_from|
        [output units], miss |y(T) - y_to|, tolerance, reached, duration [s]
        and iterations of the attempt shown, its status (why it missed, in
        words), and every attempt tried (duration, iterations, miss).
    """

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.linearisation import linearise
    from cdpm.steering import shooting

    print(
        f"steering the nonlinear robot along {len(pairs)} leg(s), each from rest at the "
        "equilibrium of a waypoint to the output of the next one listed"
        + (f" ({why})" if why else "")
        + ":",
        file=out,
    )
    unit = _miss_unit(robot)
    print(
        f"  {'leg':>4} {'from':>5} {'to':>5} {f'distance [{unit}]':>13} {f'miss [{unit}]':>10} "
        f"{'T [s]':>7}  reached",
        file=out,
    )
    rows = []
    for number, (i, j) in enumerate(pairs, start=1):
        q_from = robot.from_natural(natural[i])
        y_to = robot.output(robot.from_natural(natural[j]))
        tries = [shooting.steer(robot, q_from, y_to, tension=tension)]
        first = tries[0].duration
        near = tries[0].miss <= LEG_NEAR_MISS_FACTOR * tries[0].tolerance
        if not tries[0].reached and tries[0].blocked_direction is None and near:
            more = shooting.STEER_ITERATIONS * LEG_ITERATION_FACTOR
            tries.append(
                shooting.steer(
                    robot, q_from, y_to, tension=tension, duration=first, max_iterations=more
                )
            )
        longest = None  # what the plan resolves at this waypoint (steer refuses more)
        for factor in LEG_DURATION_FACTORS[1:]:
            if any(t.reached for t in tries) or tries[0].blocked_direction is not None:
                break
            if longest is None:
                longest = shooting.longest_duration(linearise(robot, q_from, tension=tension))
            T = min(factor * first, longest)
            if T <= tries[-1].duration:
                break
            tries.append(shooting.steer(robot, q_from, y_to, tension=tension, duration=T))
        reached = [t for t in tries if t.reached]
        result = reached[0] if reached else min(tries, key=lambda t: t.miss)
        distance = float(np.linalg.norm(y_to - result.y0))
        rows.append(
            {
                "from": int(i),
                "to": int(j),
                "distance": distance,
                "miss": float(result.miss),
                "tolerance": float(result.tolerance),
                "reached": bool(result.reached),
                "duration": result.duration,
                "iterations": int(result.iterations),
                "status": result.status,
                "tries": [
                    {"duration": t.duration, "iterations": int(t.iterations), "miss": t.miss}
                    for t in tries
                ],
            }
        )
        word = "yes" if result.reached else "no"
        print(
            f"  {number:>4} {int(i):>5} {int(j):>5} {distance:>13.4g} {result.miss:>10.3g} "
            f"{result.duration:>7.3g}  {word}",
            file=out,
        )
        out.flush()
    for line in _missed_lines(rows, unit):
        print(line, file=out)
    reached = sum(row["reached"] for row in rows)
    legs_text = f"{len(rows)} legs reached their" if len(rows) != 1 else "1 leg reached its"
    print(f"{reached} of {legs_text} waypoint's output", file=out)
    return rows


def _missed_lines(rows: list[dict], unit: str) -> list[str]:
    """Why each missed leg missed: the miss against the tolerance, the
    steering's own words and every attempt made."""
    out = []
    for number, row in enumerate(rows, start=1):
        if row["reached"]:
            continue
        tried = ", ".join(
            f"T = {t['duration']:.3g} s ({t['iterations']} simulations, miss {t['miss']:.3g})"
            for t in row["tries"]
        )
        out.append(
            f"  leg {number} (waypoints {row['from']} to {row['to']}) missed by "
            f"{row['miss']:.3g} {unit}, tolerance {row['tolerance']:.3g} {unit}: "
            f"{row['status']}; tried {tried}"
        )
    return out


def _miss_unit(robot: CableRobot) -> str:
    """The unit of the legs' distances and misses: the outputs' (``m``,
    ``rad``, or ``m, rad``)."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.reach import reach_unit

    return reach_unit(robot.output_units).replace(" and ", ", ").replace(", one to one", "")


def _legs_caption(legs: list[dict], unit: str) -> str:
    """How steering along the path went, for the picture's title: ``"steered
    along 18 leg(s): 17 reached their waypoint's output; missed: leg 16
    (waypoints 72 to 76) by 0.000331 m"``."""
    reached = sum(leg["reached"] for leg in legs)
    text = f"steered along {len(legs)} leg(s): {reached} reached their waypoint's output"
    missed = [
        f"leg {k} (waypoints {leg['from']} to {leg['to']}) by {leg['miss']:.3g} {unit}"
        for k, leg in enumerate(legs, start=1)
        if not leg["reached"]
    ]
    return text + ("; missed: " + ", ".join(missed) if missed else "")


def _path_trajectory(robot: CableRobot, ds, path):
    """A map's path as a :class:`cdpm.Trajectory` for the viewer
    (:func:`_waypoint_trajectory` with the map's tension)."""
    return _waypoint_trajectory(robot, path.natural, _map_tension(ds))


def _waypoint_trajectory(robot: CableRobot, natural, tension):
    """Waypoints (natural coordinates (k, nv)) as a :class:`cdpm.Trajectory`
    for the viewer: their configurations at rest with their equilibrium
    tensions, VIEW_STEP_SECONDS per step."""

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.dynamics.equilibrium import equilibrium_tension
    from cdpm.dynamics.simulation import Trajectory, trajectory_labels

    qs = np.array([robot.from_natural(x) for x in natural])
    if tension is None or isinstance(tension, str):
        fs = np.array([equilibrium_tension(robot, q, tension).tension for q in qs])
    else:
        fs = np.tile(np.asarray(tension, dtype=float), (qs.shape[0], 1))
    fs = np.where(np.isfinite(fs), fs, robot.tension_min)
    return Trajectory(
        t=np.arange(qs.shape[0]) * VIEW_STEP_SECONDS,
        q=qs,
        v=np.zeros((qs.shape[0], robot.nv)),
        f=fs,
        y=np.array([robot.output(q) for q in qs]),
        lengths=np.array([robot.cable_lengths(q) for q in qs]),
        **trajectory_labels(robot),
    )


def _view(robot: CableRobot, ds, path, args, out) -> None:
    _play(robot, _path_trajectory(robot, ds, path), args, out)


def _play(robot: CableRobot, traj, args, out) -> None:
    """Play a trajectory of waypoints in the 3-D viewer, in a loop."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.cli.view import _exit_on_sigterm
    from cdpm.viewer import Viewer

    # a plain `kill` also closes the viewer (and stops its server process)
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    with Viewer(robot, traj.q[0], port=args.port) as viewer:
        until = "Ctrl-C to stop" if args.seconds is None else f"for {args.seconds:g} s"
        print(f"viewer: {viewer.url()}  (playing the path in a loop, {until})", file=out)
        out.flush()
        frames = viewer.play(traj, loop=True, seconds=args.seconds)  # Ctrl-C ends it
    print(f"viewer stopped after {frames} frames", file=sys.stderr)
