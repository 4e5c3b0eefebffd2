"""``cdpm map``: a workspace map of verdicts over a grid or random poses."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from typing import TYPE_CHECKING

import numpy as np

from cdpm.cli._interrupt import interrupted
from cdpm.cli._reach import add_reach_arguments, reach_from_args
from cdpm.cli._tension import (
    add_tension_arguments,
    check_objective,
    check_pretension,
    tension_argument,
)
from cdpm.errors import InputError, MissingExtraError

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

NAME = "map"
HELP = "map positive output controllability over a grid or random poses (zarr store)"
DESCRIPTION = """\
Sweep the robot over a grid of natural coordinates (or random samples), decide
at every pose positive output controllability (seed paper Theorem 1), output
and positive controllability, wrench closure and static feasibility, and write
the map chunk by chunk into a zarr store (--out) and/or draw it (--plot); one
of them is required. Re-running the same command on the same store resumes an
interrupted map; coordinates not on an axis stay at the base pose. Gravity,
the cables' tension bounds and the pretension can be changed for the map
without editing the spec; they are recorded in the store. Prints how many
poses each verdict has, the POC regions (connected YES poses, stored as
poc_region) with their sizes, and how many steps between neighbouring YES
poses may cross a NO set thinner than the map's resolution (where the
regions may be split)."""
EPILOG = """\
examples:
  cdpm map models/two_link_planar/two_link_planar.yaml \\
      --axis q1=-pi:pi:181 --axis q2=-pi:pi:181 --out map.zarr --plot map.png
  cdpm map SPEC --axis q1=-pi:pi --axis q2=-pi:pi --samples 100000 --seed 1 --out s.zarr
  cdpm map SPEC --axis q1=0:1.5:61 --base q2=pi/3 --workers 2 --out slice.zarr
  cdpm map SPEC --axis q1=-pi:pi:721 --axis q2=-pi:pi:721 --scheduler tcp://host:8786 \\
      --out big.zarr
  cdpm map models/two_link_vertical --axis q1=-pi:pi:121 --axis q2=-pi:pi:121 \\
      --tension pretension --pretension 5 --tension-bounds 0:60 --out pre.zarr
  cdpm map SPEC --axis q1=-pi:pi:61 --gravity 0 0 0 --tension-bounds c1=0:inf --plot g0.png
  cdpm map models/spatial_8cable --axis platform_joint.x=-0.5:0.5:11 --tension best \\
      --out best.zarr    # also: POC for some feasible tension, its tension and margin

AXIS is NAME=LOW:HIGH:COUNT (a grid of COUNT values), NAME=V1,V2,... (given
values) or, with --samples, NAME=LOW:HIGH (a sampling range); values accept
arithmetic such as -pi/2. NAME is a coordinate of the robot (a joint name, or
<joint>.x ... <joint>.yaw for a free-flyer; `cdpm analyze SPEC` lists them).
BOUNDS is MIN:MAX for every cable or CABLE=MIN:MAX for one (MAX may be inf);
several --tension-bounds combine, one cable's over every cable's."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", metavar="SPEC", help="cable spec YAML file (or its model folder)")
    parser.add_argument(
        "--axis",
        action="append",
        required=True,
        metavar="AXIS",
        help="NAME=LOW:HIGH:COUNT, NAME=V1,V2,... or (with --samples) NAME=LOW:HIGH",
    )
    parser.add_argument(
        "--out",
        metavar="STORE",
        help="zarr store to write and resume (a directory, e.g. map.zarr)",
    )
    parser.add_argument(
        "--plot", metavar="IMAGE", help="also draw the map into this image (e.g. map.png)"
    )
    parser.add_argument("--samples", type=int, metavar="N", help="N random poses instead of a grid")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default 0)")
    parser.add_argument(
        "--base",
        nargs="+",
        metavar="VALUE",
        help="pose of the other coordinates: a pose name, NAME=VALUE pairs or "
        "all values (default: the spec's first pose)",
    )
    add_tension_arguments(parser, best=True)
    add_robot_arguments(parser)
    parser.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="local processes computing chunks, this one included (default: one per CPU this "
        "process may use, at most 16; 1 = in this process only); not with --scheduler",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDR",
        help="run on a Dask distributed scheduler, e.g. tcp://127.0.0.1:8786 (its workers "
        "compute the chunks)",
    )
    parser.add_argument(
        "--chunk-size",
        type=int,
        metavar="N",
        help="poses per chunk (default 16384 without load, 2048 to 4096 under load)",
    )
    parser.add_argument(
        "--no-margin",
        action="store_true",
        help="skip the reach margin (same verdicts, faster)",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace an existing store instead of resuming it"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_reach_arguments(parser)


def parse_axis(text: str, sampled: bool, option: str = "--axis"):
    """(name, values or (low, high)) from NAME=LOW:HIGH:COUNT, NAME=V1,V2 or NAME=LOW:HIGH.

    Every value must be a finite number and every item present: an empty
    item (``q1=0:1:5,`` or ``q1=0,,1``) is an error, not skipped. Errors
    name ``option``, the option the text was given with.
    """

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.spec import parse_number

    name, sep, rest = text.partition("=")
    name = name.strip()
    if not sep or not name or not rest.strip():
        raise InputError(f"{option} {text!r}: expected NAME=LOW:HIGH:COUNT or NAME=V1,V2,...")

    def number(token: str, what: str) -> float:
        if not token.strip():
            raise InputError(
                f"{option} {text!r}: {what} of axis {name!r} is empty; "
                "remove the stray ',' or ':' or fill in the value"
            )
        try:
            value = parse_number(token.strip())
        except ValueError as exc:
            raise InputError(f"{option} {text!r}: {what} of axis {name!r}: {exc}") from exc
        if not math.isfinite(value):
            raise InputError(
                f"{option} {text!r}: {what} of axis {name!r} is {value}; axis values must be "
                "finite numbers (e.g. -pi:pi:181)"
            )
        return value

    if ":" in rest and "," in rest:
        raise InputError(
            f"{option} {text!r}: axis {name!r} mixes a range (':') and a list (','); give "
            f"either {name}=LOW:HIGH:COUNT or {name}=V1,V2,..."
        )
    if ":" in rest:
        parts = rest.split(":")
        if sampled:
            if len(parts) != 2:
                with_samples = "with --samples " if option == "--axis" else ""
                raise InputError(f"{option} {text!r}: {with_samples}give a range NAME=LOW:HIGH")
            return name, (number(parts[0], "LOW"), number(parts[1], "HIGH"))
        if len(parts) != 3:
            raise InputError(f"{option} {text!r}: expected NAME=LOW:HIGH:COUNT")
        low, high = number(parts[0], "LOW"), number(parts[1], "HIGH")
        try:
            count = int(parts[2])
        except ValueError as exc:
            raise InputError(
                f"{option} {text!r}: COUNT of axis {name!r} must be an integer, "
                f"got {parts[2]!r} (e.g. {name}=0:1:11)"
            ) from exc
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.maps import MAX_AXIS_POINTS

        if count < 1 or count > MAX_AXIS_POINTS:
            raise InputError(
                f"{option} {text!r}: COUNT must be from 1 to {MAX_AXIS_POINTS:,}, got {count:,}"
            )
        return name, np.linspace(low, high, count)
    if sampled:
        with_samples = "with --samples " if option == "--axis" else ""
        raise InputError(f"{option} {text!r}: {with_samples}give a range NAME=LOW:HIGH")
    items = rest.split(",")
    return name, np.array([number(t, f"value {k + 1}") for k, t in enumerate(items)])


def parse_axes(texts: list[str], sampled: bool) -> dict:
    """{name: values or (low, high)} from every --axis; each coordinate once."""

    axes: dict = {}
    given: dict[str, str] = {}
    for text in texts:
        name, values = parse_axis(text, sampled)
        if name in axes:
            raise InputError(
                f"--axis {name} is given twice ({given[name]!r} and {text!r}); give each "
                "coordinate one --axis (list several values as NAME=V1,V2,...)"
            )
        axes[name], given[name] = values, text
    return axes


def parse_base(tokens):
    """A pose name, {name: value} or a list of values from --base tokens."""

    if not tokens:
        return None
    if len(tokens) == 1 and "=" not in tokens[0]:
        token = tokens[0]
        try:
            # loaded when the command runs (cdpm --help stays fast)
            from cdpm.model.spec import parse_number

            return [parse_number(token)]
        except ValueError:
            return token  # a pose name
    if all("=" in t for t in tokens):
        pairs = {}
        for t in tokens:
            k, _, v = t.partition("=")
            pairs[k.strip()] = v.strip()
        return pairs
    if any("=" in t for t in tokens):
        raise InputError("--base takes a pose name, NAME=VALUE pairs or all values, not a mix")
    return list(tokens)


def _check_plot_path(path: str) -> None:
    """Fail before any work when --plot cannot be written: matplotlib
    missing, or an image format it does not write."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.plotting import check_image_path

    try:
        check_image_path(path)
    except MissingExtraError as exc:
        raise MissingExtraError(
            "--plot needs matplotlib: pip install 'cdpm[maps]' (or leave out --plot and "
            "draw the stored map later with `cdpm plot STORE -o map.png`)"
        ) from exc
    except InputError as exc:
        raise InputError(f"--plot {path}: {exc}") from None


def add_robot_arguments(parser: argparse.ArgumentParser) -> None:
    """--gravity and --tension-bounds: the robot as mapped, without editing
    its spec (``cdpm map`` records them in the store)."""
    group = parser.add_argument_group(
        "the robot's load and cables (instead of the spec's; recorded with the result)"
    )
    group.add_argument(
        "--gravity",
        nargs=3,
        metavar=("GX", "GY", "GZ"),
        help="gravity in the world frame [m/s^2], e.g. 0 0 -9.81, or 0 0 0 for none",
    )
    group.add_argument(
        "--tension-bounds",
        action="append",
        metavar="BOUNDS",
        help="tension bounds [N]: MIN:MAX for every cable, or CABLE=MIN:MAX for one "
        "(MAX may be inf); repeat for several cables",
    )


def parse_gravity(tokens: list[str] | None):
    """The gravity vector [m/s^2] from --gravity, or None."""

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.spec import parse_number

    if tokens is None:
        return None
    values = []
    for token in tokens:
        try:
            value = parse_number(token.strip())
        except ValueError as exc:
            raise InputError(
                f"--gravity {' '.join(t.strip() for t in tokens)}: {exc}; give three numbers "
                "in m/s^2, e.g. --gravity 0 0 -9.81 (or 0 0 0 for none)"
            ) from exc
        if not math.isfinite(value):
            raise InputError(f"--gravity: {value} is not a finite acceleration in m/s^2")
        values.append(value)
    return values


def parse_tension_bounds(texts: list[str] | None, robot: CableRobot):
    """{cable: (min, max)} [N] from every --tension-bounds (MIN:MAX for
    every cable, CABLE=MIN:MAX for one; one cable's over every cable's), or
    None."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.model.spec import parse_number

    if not texts:
        return None
    form = "expected MIN:MAX (every cable) or CABLE=MIN:MAX (one cable), e.g. 0:50 or c1=0:inf"
    every, per_cable = None, {}
    for text in texts:
        name, sep, pair = text.rpartition("=")
        name = name.strip()
        parts = pair.split(":")
        if (sep and not name) or len(parts) != 2:
            raise InputError(f"--tension-bounds {text!r}: {form}")
        try:
            bounds = tuple(parse_number(v.strip()) for v in parts)
        except ValueError as exc:
            raise InputError(f"--tension-bounds {text!r}: {exc}; {form}") from exc
        if not sep:
            if every is not None:
                raise InputError(
                    f"--tension-bounds MIN:MAX for every cable is given twice ({every[1]!r} and "
                    f"{text!r}); give it once (and CABLE=MIN:MAX for single cables)"
                )
            every = (bounds, text)
            continue
        if name not in robot.cable_names:
            raise InputError(
                f"--tension-bounds {text!r}: no cable named {name!r} in "
                f"{robot.spec.path.name}; cables: {', '.join(robot.cable_names)}"
            )
        if name in per_cable:
            raise InputError(f"--tension-bounds: cable {name!r} is given twice; give it once")
        per_cable[name] = bounds
    out = {name: every[0] for name in robot.cable_names} if every else {}
    out.update(per_cable)
    return out


def robot_from_args(args: argparse.Namespace):
    """(robot, the spec's robot, tension setting) from SPEC, --gravity,
    --tension-bounds, --tension and --pretension, all checked before any
    work; the robot carries the overrides (:func:`cdpm.maps.override_robot`)."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps import override_robot
    from cdpm.model.robot import load_robot

    spec_robot = load_robot(args.spec)
    tension = tension_argument(args.tension, best=hasattr(args, "objective"))
    check_objective(tension, getattr(args, "objective", None))
    _check_tension(spec_robot, tension, args.pretension)
    check_pretension(spec_robot, tension, args.pretension)
    robot = override_robot(spec_robot, gravity=parse_gravity(args.gravity))
    bounds = parse_tension_bounds(args.tension_bounds, spec_robot)
    try:
        robot = override_robot(robot, tension_bounds=bounds)
    except InputError as exc:
        raise InputError(f"--tension-bounds: {exc}") from None
    try:
        robot = override_robot(robot, pretension=args.pretension)
    except InputError as exc:
        raise InputError(f"--pretension: {exc}") from None
    return robot, spec_robot, tension


def describe_robot(robot: CableRobot, spec_robot: CableRobot) -> str | None:
    """``overrides of SPEC: ...`` when the robot differs from its spec."""
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps.plan import describe_overrides, robot_overrides

    overrides = robot_overrides(robot, spec_robot)
    if not overrides:
        return None
    return f"overrides of {spec_robot.spec.path.name}: {describe_overrides(overrides, spec_robot)}"


def _check_tension(robot: CableRobot, tension, pretension: float | None) -> None:
    """The pretension method needs a pretension > 0 N, from --pretension or
    the spec (with 0 N it is the min_norm method)."""

    if tension == "best":  # the spec's method, and the search
        tension = None
    method = tension if isinstance(tension, str) or tension is None else "given"
    method = method or robot.spec.equilibrium_method
    if pretension is not None and not (math.isfinite(pretension) and pretension >= 0):
        raise InputError(f"--pretension {pretension:g}: give a finite tension >= 0 N")
    if method != "pretension":
        return
    if pretension is None and not robot.spec.pretension > 0:
        raise InputError(
            f"--tension pretension needs a pretension > 0 N, and {robot.spec.path.name} gives "
            "none (with 0 it is the min_norm method): add --pretension N, set "
            "equilibrium: {pretension: N} in the spec, or use --tension min_norm"
        )
    if pretension == 0:
        raise InputError(
            "--pretension 0 makes the pretension method the min_norm method: give "
            "--pretension N > 0, or use --tension min_norm"
        )


def _check_outputs(args: argparse.Namespace) -> None:
    """Before any work: something keeps the map, --out names a store (not
    an image), and --workers is not given with --scheduler."""

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps import store_path_problem

    if not args.out and not args.plot:
        raise InputError(
            "nothing would keep this map: add --out STORE (a zarr store, e.g. --out map.zarr: "
            "kept, resumable, read by cdpm plot, path and view) and/or --plot IMAGE "
            "(e.g. --plot map.png)"
        )
    if args.out and store_path_problem(args.out):
        stem = os.path.splitext(args.out)[0]
        problem = store_path_problem(args.out)
        if problem.startswith("an image"):
            fix = f"give --out {stem}.zarr to keep the map, and --plot {args.out} to draw it"
        else:
            fix = f"give --out {stem}.zarr (xarray.open_zarr reads it)"
        raise InputError(f"--out {args.out}: a map store is a zarr directory, not {problem}: {fix}")
    if args.scheduler and args.workers is not None:
        raise InputError(
            f"--workers {args.workers} counts local processes, and with --scheduler the Dask "
            "cluster's workers compute the chunks: leave out --workers (start more Dask workers "
            f"with `dask worker {args.scheduler}`), or leave out --scheduler to run locally"
        )
    for option, value in (
        ("--samples", args.samples),
        ("--workers", args.workers),
        ("--chunk-size", args.chunk_size),
    ):
        if value is not None and value < 1:
            raise InputError(f"{option} {value}: give a whole number >= 1")
    if args.scheduler:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.maps import check_scheduler_address

        check_scheduler_address(args.scheduler)  # before the model is loaded


def _some_tension_line(ds) -> str:
    """``POC for some feasible tension: yes 12 (60.0%), ...`` of a map
    made with --tension best."""

    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps import VERDICT_CODES

    some = np.asarray(ds["poc_some_tension"].values)
    words = ", ".join(
        f"{name} {int((some == code).sum())} ({100 * (some == code).mean():.1f}%)"
        for name, code in VERDICT_CODES.items()
        if (some == code).any()
    )
    return f"positive output controllable for some feasible tension (tension search): {words}"


def _regions_line(labels, seams: bool) -> str:
    """``POC regions: 4 (sizes 1191, 1034, ...)`` from a map's poc_region;
    ``seams``: the map has full-turn seams, whose poses the sizes count once."""

    listed = json.loads(labels.attrs.get("regions", "[]"))
    n = int(labels.attrs.get("n_regions", len(listed)))
    sizes = ", ".join(str(r["size"]) for r in listed[:5]) + (", ..." if n > 5 else "")
    if not n:
        return "POC regions: none (no YES poses)"
    return f"POC regions (connected YES poses): {n}; sizes {sizes}" + (
        " (a pose on a full-turn seam counts once)" if seams else ""
    )


def run(args: argparse.Namespace) -> int:
    # loaded when the command runs (cdpm --help stays fast)
    from cdpm.maps import (
        STATUS_CODES,
        VERDICT_CODES,
        StoreSettingsError,
        interrupts_held,
        workspace_map,
    )

    # the checks and the model's loading import Pinocchio and SciPy: an
    # interrupt waits for them (one inside an import broke it)
    with interrupts_held():
        axes = parse_axes(args.axis, args.samples is not None)
        base = parse_base(args.base)
        _check_outputs(args)
        if args.plot:
            _check_plot_path(args.plot)
        robot, spec_robot, tension = robot_from_args(args)
        if isinstance(base, list):
            base = robot.configuration(base)
        overrides = describe_robot(robot, spec_robot)
        reach = None if args.no_margin else reach_from_args(robot, args)
    if overrides:
        print(overrides)
    if reach is not None:
        print(f"reach margin: {reach.describe()}")
    runs = []

    def announce(info) -> None:
        runs.append(info)
        for line in info.lines():
            print(line, flush=True)

    try:
        ds = workspace_map(
            robot,
            axes,
            base=base,
            tension=tension,
            samples=args.samples,
            seed=args.seed,
            workers=args.workers,
            scheduler=args.scheduler,
            store=args.out,
            overwrite=args.overwrite,
            chunk_size=args.chunk_size,
            progress=not args.quiet,
            margin=not args.no_margin,
            horizon=None if reach is None else reach.horizon,
            tension_budget=None if reach is None else reach.tension_budget,
            announce=announce,
            tension_objective=args.objective or "poc",
        )
    except KeyboardInterrupt as exc:
        return interrupted("map", args.out, getattr(exc, "map_store", None))
    except StoreSettingsError as exc:
        raise InputError(
            exc.explain("re-run with the stored settings", "add --overwrite", "--out path")
        ) from None
    poc = np.asarray(ds["poc"].values)
    status = np.asarray(ds["status"].values)
    total = poc.size
    words = ", ".join(
        f"{name} {int((poc == code).sum())} ({100 * (poc == code).mean():.1f}%)"
        for name, code in VERDICT_CODES.items()
        if (poc == code).any()
    )
    print(f"{robot.spec.path.name}: {total} poses; positive output controllable: {words}")
    if tension == "best":
        print(_some_tension_line(ds))
    if "poc_region" in ds:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.maps.regions import map_layout
        from cdpm.regions.paths import suspect_region_splits

        print(_regions_line(ds["poc_region"], "closed" in map_layout(ds).wrap))
        thin = suspect_region_splits(ds)
        # said only where it matters: steps whose loss would split a region
        if thin and thin[1]:
            print(
                f"  {thin[0]} step(s) between neighbouring YES poses may cross a NO set thinner "
                "than the map's resolution (r_T comes within a step's change of 0: an estimate "
                "from its sampled slopes, not a proof); without them the YES poses would form "
                f"{thin[1]} more region(s), so the regions may be split there; `cdpm path` names "
                "such steps on a path"
            )
    flagged = {n: int((status == c).sum()) for n, c in STATUS_CODES.items() if c > 0}
    flagged = {n: k for n, k in flagged.items() if k}
    if flagged:
        print("flagged poses: " + ", ".join(f"{n} {k}" for n, k in flagged.items()))
    if args.out:
        computed = not runs or runs[-1].todo_chunks > 0
        print(f"map written to {args.out}" if computed else f"map read from {args.out}")
    if args.plot:
        # loaded when the command runs (cdpm --help stays fast)
        from cdpm.plotting import save_map_plot

        written = save_map_plot(ds, args.plot)
        print(f"plot written to {written}", file=sys.stderr if args.quiet else sys.stdout)
    return 0
