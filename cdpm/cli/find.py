"""``cdpm find``: poses worth analysing (statically feasible, or POC)."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cdpm.cli._reach import add_reach_arguments, reach_from_args
from cdpm.cli._tension import add_tension_arguments
from cdpm.cli.map import add_robot_arguments, describe_robot, parse_axis, robot_from_args
from cdpm.printing import json_text

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

NAME = "find"
HELP = "find poses worth analysing: statically feasible or positive output controllable"
DESCRIPTION = """\
Draw random poses (uniformly within the joint limits, or within --radius of a
pose given with --near), evaluate each with the map pipeline (equilibrium,
linearisation, positive output controllability) and print the best that
satisfy --where, each as --q values to paste into `cdpm analyze`, `verify`,
`steer` or `view`:

  poc       positive output controllable (verdict YES), ranked by the reach
            margin r_T [m] (largest first; how far tension changes move the
            outputs in every direction within T seconds); poses needing more
            than 10 times the tension budget F (near-singular, where the
            linearisation holds only very close) come last, marked *;
  feasible  a tension within the cables' bounds holds the pose (by the
            equilibrium method in use), ranked by the peak cable tension [N]
            (least first).

Pose values are rounded to 4 decimals before they are evaluated, so what is
printed is exactly what was analysed. With --near the pose itself is tried
first."""
EPILOG = """\
examples:
  cdpm find models/two_link_vertical
  cdpm find models/two_link_vertical --near nominal --radius 0.5 --count 3
  cdpm find models/two_link_vertical --where feasible --tension-bounds 0:25
  cdpm find CAREX/CAREX.yaml --near initial --json   (after cdpm import-caspr ... --out CAREX)
  cdpm find models/spatial_8cable --near centre --radius 0.05 --range platform_joint.z=0:0.5

Ranges: a coordinate with finite URDF limits is drawn within them; an angle
without limits within [-pi, pi] (a pitch [-pi/2, pi/2]); a length without
limits within the box of the cables' fixed anchor points (else +-1 m around
the spec's first pose). --range NAME=LOW:HIGH narrows one (LOW = HIGH fixes it).
--radius R is in the coordinates' units, rad or m, for every coordinate.

exit codes: 0 poses were found; 3 none of the poses tried satisfies --where
(the message says how many were tried and how to widen the search); 1 other
errors."""

#: exit code when no pose tried satisfies the condition
NONE_FOUND_EXIT = 3
#: decimals of the printed (and evaluated) pose values
DECIMALS = 4
#: poses evaluated per batch
BATCH = 256
#: a pose needing more than this many times the tension budget is ranked
#: after the others (see :func:`_strained`)
STRAIN_FACTOR = 10


#: most poses one search draws (--tries)
FIND_MAX_TRIES = 10**6


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", metavar="SPEC", help="cable spec YAML file (or its model folder)")
    parser.add_argument(
        "--where",
        choices=("poc", "feasible"),
        default="poc",
        help="what the poses must be: poc (verdict YES; default) or feasible (held by "
        "tensions within the bounds)",
    )
    parser.add_argument(
        "--near",
        nargs="+",
        metavar="POSE",
        help="search around this pose: a pose name of the spec or its values (Q1 Q2 ...)",
    )
    parser.add_argument(
        "--radius",
        default="0.3",
        metavar="R",
        help="with --near: half-width of the search box [rad or m] (default 0.3)",
    )
    parser.add_argument(
        "--range",
        action="append",
        metavar="NAME=LOW:HIGH",
        help="draw this coordinate within [LOW, HIGH] (rad or m); repeatable",
    )
    parser.add_argument(
        "--count", type=int, default=5, metavar="N", help="poses to print (default 5)"
    )
    parser.add_argument(
        "--tries", type=int, default=1000, metavar="N", help="poses to draw (default 1000)"
    )
    parser.add_argument(
        "--rank",
        type=int,
        default=200,
        metavar="N",
        help="with --where poc: rank at most N of the POC poses found by their reach margin "
        "(a fraction of a millisecond a pose with three outputs, about 0.2 s with six; "
        "default 200)",
    )
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    add_tension_arguments(parser)
    add_robot_arguments(parser)
    add_reach_arguments(parser)


# --------------------------------------------------------------------------
# where to draw poses


@dataclass(frozen=True)
class SearchBox:
    """Where poses are drawn: a box of natural coordinates.

    Attributes:
        names: the coordinate names, in the robot's order.
        low, high: the box [rad or m], each (nv,).
        center: natural coordinates of the --near pose (nv,), or None.
        near: the --near pose as given (a name or values), or None.
        radius: the --near half-width [rad or m], or None.
    """

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    center: np.ndarray | None = None
    near: str | None = None
    radius: float | None = None

    def describe(self) -> str:
        parts = [
            f"{n} {lo:.4g}" if lo == hi else f"{n} [{lo:.4g}, {hi:.4g}]"
            for n, lo, hi in zip(self.names, self.low, self.high, strict=True)
        ]
        where = ", ".join(parts)
        if self.center is None:
            return f"uniform in {where}"
        return f"uniform within {self.radius:g} of {self.near} ({where})"


def coordinate_ranges(robot: CableRobot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each natural coordinate may be drawn: (low, high, limited),
    each (nv,).

    Finite URDF limits are used as they are (``limited``); an angle without
    them gets [-pi, pi] (a pitch [-pi/2, pi/2]); a length without them the
    box of the cables' anchor points fixed to the world along its axis, else
    the spec's first pose +- 1 m.
    """
    from cdpm.model.coordinates import _kind

    model = robot.model
    lower_q = np.asarray(model.lowerPositionLimit, dtype=float)
    upper_q = np.asarray(model.upperPositionLimit, dtype=float)
    q0 = robot.configuration(next(iter(robot.poses))) if robot.poses else robot.neutral()
    natural0 = robot.to_natural(q0)
    anchors = _fixed_anchors(robot, q0)
    low, high = np.empty(robot.nv), np.empty(robot.nv)
    limited = np.zeros(robot.nv, dtype=bool)
    for j in range(1, model.njoints):
        joint = model.joints[j]
        kind = _kind(joint)
        n_lengths = {"freeflyer": 3, "planar": 2}.get(kind, 0)
        prismatic = joint.shortname().startswith(("JointModelP", "JointModelTranslation"))
        for k in range(joint.nv):
            iv = joint.idx_v + k
            name = robot.coordinate_names[iv]
            is_length = k < n_lengths or (kind == "euclidean" and prismatic)
            lo = hi = math.nan
            if kind == "euclidean" or k < n_lengths:
                lo, hi = lower_q[joint.idx_q + k], upper_q[joint.idx_q + k]
            if math.isfinite(lo) and math.isfinite(hi) and lo < hi and abs(hi - lo) < 1e6:
                low[iv], high[iv], limited[iv] = lo, hi, True
            elif is_length and anchors.size and k < 3 and kind in ("freeflyer", "planar"):
                axis = {"x": 0, "y": 1, "z": 2}.get(name.rsplit(".", 1)[-1], k)
                low[iv], high[iv] = anchors[:, axis].min(), anchors[:, axis].max()
                if high[iv] - low[iv] < 1e-9:
                    low[iv], high[iv] = natural0[iv] - 1.0, natural0[iv] + 1.0
            elif is_length:
                low[iv], high[iv] = natural0[iv] - 1.0, natural0[iv] + 1.0
            elif name.endswith("pitch") and kind != "euclidean":
                low[iv], high[iv] = -math.pi / 2, math.pi / 2
            else:
                low[iv], high[iv] = -math.pi, math.pi
    return low, high, limited


def _fixed_anchors(robot: CableRobot, q0) -> np.ndarray:
    """World positions (k, 3) [m] of the route points fixed to the world."""
    from cdpm.model.spec import WORLD_FRAME_NAMES

    model = robot.model
    points = robot.attachment_points(q0)
    fixed = []
    for cable, positions in zip(robot.spec.cables, points, strict=True):
        for point, position in zip(cable.route, positions, strict=True):
            frame = point.frame
            if frame in WORLD_FRAME_NAMES or model.frames[model.getFrameId(frame)].parentJoint == 0:
                fixed.append(position)
    return np.array(fixed, dtype=float).reshape(-1, 3)


def search_box(robot: CableRobot, args: argparse.Namespace) -> SearchBox:
    """The box poses are drawn from: the coordinate ranges, narrowed by
    --range and, with --near, to within --radius of that pose."""
    from cdpm.errors import InputError
    from cdpm.model.spec import parse_number

    low, high, limited = coordinate_ranges(robot)
    names = tuple(robot.coordinate_names)
    given = set()
    for text in args.range or []:
        name, (lo, hi) = parse_axis(text, sampled=True)
        message = f"--range {text!r}"
        if name not in names:
            raise InputError(f"{message}: no coordinate {name!r}; coordinates: {', '.join(names)}")
        if name in given:
            raise InputError(f"{message}: coordinate {name!r} is given twice; give it once")
        given.add(name)
        i = names.index(name)
        low[i], high[i], limited[i] = lo, hi, True
    if not args.near:
        return SearchBox(names, low, high)
    text = str(args.radius).strip()
    try:
        radius = parse_number(text)
    except ValueError as exc:
        raise InputError(f"--radius {text}: {exc}; give a half-width in rad or m") from exc
    if not (math.isfinite(radius) and radius >= 0):
        raise InputError(f"--radius {text}: give a finite half-width >= 0 (rad or m)")
    center, label = _near_pose(robot, args.near)
    lo = np.where(limited, np.maximum(low, center - radius), center - radius)
    hi = np.where(limited, np.minimum(high, center + radius), center + radius)
    outside = np.flatnonzero(lo > hi)
    if outside.size:
        i = int(outside[0])
        raise InputError(
            f"--near {label}: {names[i]} = {center[i]:.4g} is more than --radius {radius:g} "
            f"outside its range [{low[i]:.4g}, {high[i]:.4g}]; give a pose within the range or a "
            "larger --radius"
        )
    return SearchBox(names, lo, hi, center, label, radius)


def _near_pose(robot: CableRobot, tokens: list[str]) -> tuple[np.ndarray, str]:
    """(natural coordinates, label) of the --near pose."""
    from cdpm.errors import InputError
    from cdpm.model.spec import parse_number

    if len(tokens) == 1:
        try:
            parse_number(tokens[0])
        except ValueError:
            try:
                return robot.to_natural(robot.configuration(tokens[0])), tokens[0]
            except InputError as exc:
                raise InputError(f"--near {tokens[0]}: {exc}") from None
    values = []
    for token in tokens:
        try:
            values.append(parse_number(token.strip()))
        except ValueError as exc:
            raise InputError(
                f"--near {' '.join(tokens)}: {exc}; give a pose name or one value per "
                f"coordinate ({', '.join(robot.coordinate_names)})"
            ) from exc
    try:
        natural = robot.to_natural(robot.configuration(values))
    except InputError as exc:
        raise InputError(f"--near {' '.join(tokens)}: {exc}") from None
    return natural, " ".join(t.strip() for t in tokens)


def draw_poses(box: SearchBox, tries: int, seed: int) -> np.ndarray:
    """``tries`` poses (tries, nv) uniform in ``box``, rounded to DECIMALS
    (inwards at the box's ends); with a centre, the centre first (exact)."""
    rng = np.random.default_rng(seed)
    scale = 10.0**DECIMALS
    lo = np.ceil(np.round(box.low * scale, 6)) / scale
    hi = np.floor(np.round(box.high * scale, 6)) / scale
    hi = np.maximum(hi, lo)
    poses = np.round(rng.uniform(lo, hi, size=(tries, lo.size)), DECIMALS)
    poses = np.clip(poses, lo, hi)
    if box.center is not None:
        poses[0] = box.center
    return poses


# --------------------------------------------------------------------------
# evaluating and ranking


def _evaluate(robot: CableRobot, natural: np.ndarray, tension, margin: bool, reach) -> dict:
    """The map variables at ``natural`` (N, nv), in batches."""
    from cdpm.maps import evaluate_poses
    from cdpm.pipeline.evaluate import single_threaded_blas

    if natural.shape[0] == 0:
        return {}
    parts = []
    with single_threaded_blas():
        for start in range(0, natural.shape[0], BATCH):
            chunk = natural[start : start + BATCH]
            parts.append(evaluate_poses(robot, chunk, tension, margin=margin, reach=reach))
    return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}


def _feasible(data: dict) -> np.ndarray:
    """Held by a tension within the bounds, by the equilibrium method in use."""
    from cdpm.verdicts import STATUS_CODES, YES

    return (data["static_feasible"] == YES) & (data["status"] != STATUS_CODES["no_equilibrium"])


def _value_text(value: float) -> str:
    """A pose value as --q takes it: at most DECIMALS decimals, no -0."""
    text = f"{value:.{DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _pose_argv(box: SearchBox, index: int, natural: np.ndarray) -> list[str]:
    """What to paste: --pose NAME for the --near pose given by name."""
    if index == 0 and box.center is not None:
        if " " not in box.near and not _is_number(box.near):
            return ["--pose", box.near]
        return ["--q", *box.near.split()]
    return ["--q", *(_value_text(v) for v in natural)]


def _is_number(text: str) -> bool:
    from cdpm.model.spec import parse_number

    try:
        parse_number(text)
    except ValueError:
        return False
    return True


def _strained(peak_tension: np.ndarray, reach) -> np.ndarray:
    """Poses whose equilibrium needs more than STRAIN_FACTOR times the
    tension budget F (the robot's weight by default): near-singular poses,
    where the linearisation, and so the reach margin, holds only very close
    to the pose."""
    return np.asarray(peak_tension) > STRAIN_FACTOR * reach.tension_budget


def find_poses(robot: CableRobot, box: SearchBox, args: argparse.Namespace, tension, reach):
    """Evaluate the drawn poses and rank those satisfying --where.

    Returns:
        dict: ``natural`` (tries, nv), ``counts`` ({feasible, poc}),
        ``ranked`` (how many were ranked), ``chosen`` (indices into the
        poses, best first) and the variables of the chosen poses with the
        reach margin (``rows``: one dict per pose).
    """
    from cdpm.verdicts import VERDICT_LABELS, YES

    natural = draw_poses(box, args.tries, args.seed)
    data = _evaluate(robot, natural, tension, margin=False, reach=None)
    feasible = _feasible(data)
    poc = data["poc"] == YES
    candidates = np.flatnonzero(poc if args.where == "poc" else feasible)
    rng = np.random.default_rng(args.seed + 1)
    if args.where == "poc":
        ranked = candidates
        if ranked.size > args.rank:
            ranked = np.sort(rng.choice(ranked, size=args.rank, replace=False))
        if box.center is not None and candidates.size and candidates[0] == 0 and 0 not in ranked:
            ranked = np.concatenate([[0], ranked[1:]])  # the --near pose is always ranked
        scored = _evaluate(robot, natural[ranked], tension, margin=True, reach=reach)
        margin = np.nan_to_num(scored.get("reach_margin", np.zeros(0)), nan=-np.inf)
        strained = _strained(scored.get("tension_max", np.zeros(0)), reach)
        order = np.lexsort((-margin, strained))[: args.count]
        chosen, chosen_data = ranked[order], {k: v[order] for k, v in scored.items()}
    else:
        ranked = candidates
        peak = data["tension_max"][candidates]
        order = np.argsort(np.nan_to_num(peak, nan=np.inf), kind="stable")[: args.count]
        chosen = candidates[order]
        chosen_data = _evaluate(robot, natural[chosen], tension, margin=True, reach=reach)
    rows = []
    strained = _strained(chosen_data.get("tension_max", np.zeros(0)), reach)
    for k, index in enumerate(chosen):
        distance = None
        if box.center is not None:
            distance = float(np.max(np.abs(natural[index] - box.center), initial=0.0))
        margin = float(chosen_data["reach_margin"][k])
        error = float(chosen_data["reach_margin_error"][k])
        rows.append(
            {
                "argv": _pose_argv(box, int(index), natural[index]),
                "natural": [float(v) for v in natural[index]],
                "poc": VERDICT_LABELS[int(chosen_data["poc"][k])],
                "static_feasible": VERDICT_LABELS[int(chosen_data["static_feasible"][k])],
                "reach_margin": margin if math.isfinite(margin) else None,
                "reach_margin_error": error if math.isfinite(error) else None,
                "peak_tension": float(chosen_data["tension_max"][k]),
                "strained": bool(strained[k]),
                "distance": distance,
            }
        )
    counts = {"feasible": int(feasible.sum()), "poc": int(poc.sum())}
    return {"natural": natural, "counts": counts, "ranked": int(ranked.size), "rows": rows}


# --------------------------------------------------------------------------
# the command


def run(args: argparse.Namespace) -> int:
    from cdpm.errors import InputError
    from cdpm.pipeline.compiled import load_kernels_for, notice_on_stderr

    for option, value, least in (("--count", args.count, 1), ("--tries", args.tries, 1)):
        if value < least:
            raise InputError(f"{option} {value}: give a whole number >= {least}")
    if args.tries > FIND_MAX_TRIES:
        raise InputError(
            f"--tries {args.tries:,}: at most {FIND_MAX_TRIES:,} poses per search (about "
            "0.1 ms each); for more, map them: cdpm map SPEC --samples N ... --out map.zarr"
        )
    if args.rank < args.count:
        raise InputError(
            f"--rank {args.rank} is less than --count {args.count}: rank at least as many "
            "poses as are printed"
        )
    robot, spec_robot, tension = robot_from_args(args)
    box = search_box(robot, args)
    reach = reach_from_args(robot, args)
    load_kernels_for(robot, tension, notice_on_stderr)
    result = find_poses(robot, box, args, tension, reach)
    rows, counts, tries = result["rows"], result["counts"], args.tries
    what = "positive output controllable (YES)" if args.where == "poc" else "statically feasible"
    if args.json:
        print(json_text(_as_json(robot, spec_robot, box, args, reach, result)))
    else:
        overrides = describe_robot(robot, spec_robot)
        if overrides:
            print(overrides)
        print(f"{robot.spec.path.name}: {tries} poses tried, {box.describe()} (seed {args.seed})")
        print(
            f"  statically feasible: {counts['feasible']} ({100 * counts['feasible'] / tries:.1f}%)"
            f"; positive output controllable: {counts['poc']} "
            f"({100 * counts['poc'] / tries:.1f}%)"
        )
        if rows:
            print(f"reach margin: {reach.describe()}")
            _print_rows(robot, box, args, result, reach, what)
    if not rows:
        print(f"cdpm find: {_none_found(box, args, counts, what)}", file=sys.stderr)
        return NONE_FOUND_EXIT
    return 0


def _print_rows(robot, box: SearchBox, args, result, reach, what: str) -> None:
    rows = result["rows"]
    if args.where == "poc":
        among = (
            f"all {result['ranked']}"
            if result["ranked"] == result["counts"]["poc"]
            else f"{result['ranked']} of the {result['counts']['poc']} (drawn at random; --rank N "
            "ranks more)"
        )
        print(f"{len(rows)} {what} pose(s) of the most reach margin r_T, among {among}:")
    else:
        print(f"{len(rows)} {what} pose(s) of the least peak tension:")
    from cdpm.dynamics.reach import reach_unit

    unit = reach_unit(robot.output_units).replace(" and ", ", ").replace(", one to one", "")
    header = f"  {'#':>2}  {f'r_T [{unit}]':>10}  {'POC':<12}  {'peak tension [N]':>16}"
    if box.center is not None:
        header += f"  {'distance':>8}"
    print(header + "  pose")
    for k, row in enumerate(rows, 1):
        margin = "-" if row["reach_margin"] is None else f"{row['reach_margin']:.4g}"
        verdict = row["poc"] + ("*" if row["strained"] else "")
        line = f"  {k:>2}  {margin:>10}  {verdict:<12}  {row['peak_tension']:>16.4g}"
        if box.center is not None:
            line += f"  {row['distance']:>8.4g}"
        print(line + "  " + " ".join(row["argv"]))
    if any(row["strained"] for row in rows):
        print(
            f"  * needs more than {STRAIN_FACTOR} x F = {STRAIN_FACTOR * reach.tension_budget:g} N "
            "of tension: a near-singular pose, whose reach margin holds only very close to it"
            + (" (ranked after the others)" if args.where == "poc" else "")
        )
    print(f"analyse one: cdpm analyze {args.spec} {' '.join(rows[0]['argv'])}")


def _none_found(box: SearchBox, args, counts: dict, what: str) -> str:
    """Why nothing was found, and how to widen the search."""
    widen = [f"more poses (--tries {10 * args.tries})"]
    if box.center is not None:
        widen += [f"a larger --radius (now {box.radius:g})", "no --near (the whole range)"]
    if args.range:
        widen.append("wider or fewer --range")
    if args.where == "poc":
        found = f"{counts['feasible'] or 'none'} of them statically feasible"
    else:
        found = "none statically feasible"
    return (
        f"none of the {args.tries} poses tried is {what} ({found}); widen the search: "
        f"{', '.join(widen)}, another --seed, or change the load or cables (--gravity, "
        "--tension-bounds, --tension)"
    )


def _as_json(robot: CableRobot, spec_robot, box: SearchBox, args, reach, result) -> dict:
    from cdpm.maps.plan import robot_overrides

    return {
        "spec": str(robot.spec.path),
        "where": args.where,
        "tried": args.tries,
        "seed": args.seed,
        "near": box.near,
        "radius": box.radius,
        "ranges": {
            n: [float(lo), float(hi)]
            for n, lo, hi in zip(box.names, box.low, box.high, strict=True)
        },
        "counts": {
            "statically_feasible": result["counts"]["feasible"],
            "poc_yes": result["counts"]["poc"],
        },
        "ranked": result["ranked"],
        "reach": {"horizon": reach.horizon, "tension_budget": reach.tension_budget},
        "overrides": robot_overrides(robot, spec_robot),
        "coordinates": list(robot.coordinate_names),
        "poses": result["rows"],
    }
