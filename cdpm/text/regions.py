"""Text and JSON of the regions' results: the POC neighbourhood of a pose
(:class:`~cdpm.regions.neighbourhood.Neighbourhood`, in the pose report and
``cdpm analyze --neighbourhood``) and its certified box
(:class:`~cdpm.regions.neighbourhood.CertifiedNeighbourhood`), a path of
POC poses (:class:`~cdpm.regions.paths.POCPath`, ``cdpm path``) and a
certified path (:class:`~cdpm.regions.certified.CertifiedPath`, ``cdpm path``
on a certified map)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from cdpm.numerics import SUSPECT_LIPSCHITZ_SAFETY
from cdpm.printing import strict
from cdpm.verdicts import STATUS_LABELS, YES, verdict_key

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.regions.certified import CertifiedPath
    from cdpm.regions.neighbourhood import CertifiedNeighbourhood, Neighbourhood, SampledPose
    from cdpm.regions.paths import POCPath


#: waypoints printed in full; longer paths print the first and last halves
PRINT_WAYPOINTS = 16
#: suspect steps printed with a warning line each; the others are listed
PRINT_SUSPECT = 4


# ------------------------------------------------------------ neighbourhood


def neighbourhood_lines(nb: Neighbourhood) -> list[str]:
    """The neighbourhood in words, for the pose report (first line: the
    summary)."""
    u, R, (lo, hi) = nb.unit, nb.radius, nb.box_bracket
    if nb.verdict != YES:
        return [f"POC neighbourhood: radius 0: {nb.reason} (no neighbourhood evaluated)"]
    grid = f"{nb.grid_shape} grid{' plus rays' if nb.axis_rays else ''} of half-width"
    grid = f"on a {grid} {R:.4g} {u}"
    clear = "is YES and r_T stays clear of 0 between neighbouring samples"
    if nb.whole_box_yes:
        head = f"every sampled pose within {R:.4g} {u} (box, inf-norm) of the pose {clear}, "
        out = [f"{head}{grid}: the whole box, so the radius is at least {R:.4g} {u}"]
    elif lo > 0:
        head = f"radius {lo:.4g} {u} (box, inf-norm) {grid}: every sampled pose within it "
        out = [f"{head}{clear}"]
    else:
        out = [f"radius 0 {grid}: the pose is YES, but {nb.reason}"]
    out[0] = "POC neighbourhood: " + out[0]
    if not nb.whole_box_yes:
        why = f": it stops there: {nb.reason}" if lo > 0 else ""  # radius 0: said above
        out.append(f"  box radius in [{lo:.4g}, {hi:.4g}] {u}{why}")
    names, varied, near = nb.coordinate_names, nb.coordinates, nb.nearest
    if near is not None:
        where = f"{near.describe()} at ({_where(near, names, varied)})"
        out.append(f"  nearest non-YES pose: {where}, {near.distance_box:.4g} {u} away")
    if nb.nearest_suspect is not None:
        a, b = nb.nearest_suspect
        out.append(
            f"  nearest suspect edge: r_T = {a.margin:.3g} and {b.margin:.3g} "
            f"{nb.margin_unit} at ({_where(a, names, varied)}) and "
            f"({_where(b, names, varied)}), {a.distance_box:.4g} and {b.distance_box:.4g} "
            f"{u} away ({nb.suspect_edges} suspect edges in all)"
        )
        least = nb.suspect_least
        if least is not None:
            what = (
                f"a {least.describe()} pose"
                if least.verdict != YES
                else f"r_T down to {least.margin:.3g} {nb.margin_unit}"
            )
            out.append(
                f"    resampled along it: {what} at ({_where(least, names, varied)}), "
                f"{least.distance_box:.4g} {u} away"
            )
    ball, end = nb.ball_bracket
    out.append(
        f"  ball (2-norm): every sampled pose within {R:.4g} {u} {clear}"
        if end is None
        else f"  ball (2-norm): radius {ball:.4g} {u}, the region may end at {end:.4g}"
    )
    out.append("  " + _sampled_text(nb))
    out.append(f"  r_T: T {nb.reach.horizon:.3g} s, budget {nb.reach.tension_budget:.3g} N")
    if nb.suspect_edges or nb.suspect_cleared:
        out.append("  " + _thin_no_set_text(nb))
    if u == "m or rad":
        out.append("  mixed units: 1 m of translation counts as 1 rad (set scale= to change)")
    elif u == "scaled units":
        parts = zip(nb.coordinates, nb.scale, nb.units, strict=True)
        scales = ", ".join(f"{c} {x:g} {unit}" for c, x, unit in parts)
        out.append(f"  distances in dq / scale; scale: {scales}")
    counts = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in nb.counts.items() if v)
    out.append(f"  verdicts: {counts}")
    if nb.outside_limits:
        also = nb.nearest is not None and nb.nearest.outside_limits
        out.append(
            f"  {nb.outside_limits} sampled poses lie outside the URDF joint limits "
            "(evaluated anyway)" + ("; the nearest non-YES pose is one of them" if also else "")
        )
    return out


def _thin_no_set_text(nb: Neighbourhood) -> str:
    """How the steps where a thin NO set may pass were found: the estimate,
    said to be one, and what resampling them did."""
    text = (
        "thin NO sets: a step from a to b is suspect when r(a) + r(b) <= "
        f"{SUSPECT_LIPSCHITZ_SAFETY:g} L h, L the largest slope of r_T sampled at a or b "
        "(an estimate of how fast r_T can fall, not a proof)"
    )
    flagged = nb.suspect_edges + nb.suspect_cleared
    if nb.refined_poses:
        text += (
            f"; {flagged} step(s) flagged, resampled at {nb.refined_poses} more poses: "
            f"{nb.suspect_cleared} cleared, {nb.suspect_edges} still suspect"
        )
    return text


def neighbourhood_text(nb: Neighbourhood) -> str:
    """:func:`neighbourhood_lines` as one text."""
    return "\n".join(neighbourhood_lines(nb))


def _where(pose: SampledPose, names: Sequence[str], varied: Sequence[str]) -> str:
    """The pose as ``"q1 = 1.4636, q2 = 1.6072"`` (the varied coordinates)."""
    return ", ".join(f"{c} = {pose.natural[list(names).index(c)]:.5g}" for c in varied)


def _sampled_text(nb: Neighbourhood) -> str:
    names = ", ".join(nb.coordinates)
    if nb.points > 1:
        steps = {f"{s:.3g} {unit}" for s, unit in zip(nb.step, nb.units, strict=True)}
        text = f"sampled: {nb.grid_shape} grid over {names}, step {' / '.join(sorted(steps))}"
    else:
        text = f"sampled: over {names}, no grid beyond q"
    if nb.axis_rays + nb.corner_rays:
        text += (
            f", plus {nb.axis_rays} axis and {nb.corner_rays} corner rays of "
            f"{nb.ray_points} points (step {nb.radius / nb.ray_points:.3g} {nb.unit})"
        )
    return text + f"; {nb.n_poses} poses in {nb.seconds:.2g} s"


def sampled_pose_json(pose: SampledPose, coordinate_names: Sequence[str]) -> dict:
    """Strict-JSON data of a sampled pose (coordinates by name; a margin
    not analysed is null)."""
    return strict(
        {
            "coordinates": dict(zip(coordinate_names, map(float, pose.natural), strict=True)),
            "distance_box": pose.distance_box,
            "distance_ball": pose.distance_ball,
            "verdict": verdict_key(pose.verdict),
            "status": STATUS_LABELS.get(pose.status, str(pose.status)),
            "description": pose.describe(),
            "outside_limits": pose.outside_limits,
            "reach_margin": pose.margin,
        }
    )


def neighbourhood_json(nb: Neighbourhood) -> dict:
    """Strict-JSON data of the neighbourhood (None for an unbounded bracket,
    a NaN step or margin)."""
    names, varied, suspect = nb.coordinate_names, nb.coordinates, nb.nearest_suspect

    def plain(pose):
        return None if pose is None else sampled_pose_json(pose, names)

    same = (
        "radius points ray_points n_poses box_radius box_bracket ball_radius ball_bracket "
        "whole_box_yes suspect_edges counts status_counts outside_limits tension pretension "
        "tol seconds reason"
    )
    return strict(
        {
            "model": nb.model_name,
            "pose": nb.pose_name,
            "coordinates": dict(zip(names, nb.natural.tolist(), strict=True)),
            "varied": list(varied),
            "units": list(nb.units),
            "unit": nb.unit,
            "scale": dict(zip(varied, nb.scale.tolist(), strict=True)),
            "grid": nb.grid_shape,
            "step": dict(zip(varied, nb.step.tolist(), strict=True)),
            "rays": {"axis": nb.axis_rays, "corner": nb.corner_rays},
            "verdict": verdict_key(nb.verdict),
            "status": STATUS_LABELS.get(nb.status, str(nb.status)),
            "nearest": plain(nb.nearest),
            "nearest_ball": plain(nb.nearest_ball),
            "nearest_suspect": None if suspect is None else [plain(p) for p in suspect],
            "suspect_lipschitz_safety": SUSPECT_LIPSCHITZ_SAFETY,
            "reach": nb.reach.as_dict(),
            **{key: getattr(nb, key) for key in same.split()},
        }
    )


# --------------------------------------------------------------------- path


def path_warnings(path: POCPath) -> list[str]:
    """One line per suspect step: where the path may cross a NO set
    thinner than the map's resolution (empty when none or not checked)."""
    out = []
    for i in path.suspect_steps or ():
        moves = ", ".join(
            f"{a} {path.coordinates[a][i]:.4g} -> {path.coordinates[a][i + 1]:.4g}"
            for a in path.axes
            if path.coordinates[a][i] != path.coordinates[a][i + 1]
        )
        out.append(
            f"warning: the path may cross a NO set thinner than the map's resolution "
            f"between waypoints {i} and {i + 1} ({moves}): their reach margins "
            f"{path.margins[i]:.4g} and {path.margins[i + 1]:.4g} are within one step's "
            f"change of 0 ({SUSPECT_LIPSCHITZ_SAFETY:g} times the largest slope of r_T "
            "sampled nearby: an estimate, not a proof; `cdpm analyze --q` at poses between "
            "them tells)"
        )
    return out


def _unit_text(path: POCPath) -> str:
    units = {path.units.get(a, "") for a in path.axes}
    if len(units) == 1:
        return next(iter(units)) or "axis units"
    return "axis units: " + ", ".join(f"{a} {path.units.get(a, '?')}" for a in path.axes)


def path_text(path: POCPath) -> str:
    """The path as ``cdpm path`` prints it: the summary, its smallest
    margin, seam crossings, a warning line per suspect step (the first
    PRINT_SUSPECT; the others listed) and the waypoints (the first and last
    PRINT_WAYPOINTS / 2 of a longer path)."""
    kind = "largest smallest margin" if path.maximise_margin else "shortest"
    k = path.n_waypoints
    lines = [
        f"POC path ({kind}) in region {path.region} ({path.region_size} poses): "
        f"{k} waypoint{'s' if k != 1 else ''}, {path.steps} step"
        f"{'s' if path.steps != 1 else ''}, length {path.length:.4g} [{_unit_text(path)}]"
    ]
    if path.margin_variable is not None and np.any(np.isfinite(path.margins)):
        at = int(np.nanargmin(path.margins))
        lines.append(
            f"  smallest {path.margin_variable} along it: {path.min_margin:.4g}"
            f"{' ' + path.margin_unit if path.margin_unit else ''} (waypoint {at})"
        )
    else:
        lines.append("  no margins in this map")
    if path.seam_crossings:
        lines.append(
            f"  crosses the seam of a full-turn axis after waypoint(s) "
            f"{', '.join(map(str, path.seam_crossings))}"
        )
    if path.suspect_steps is None and path.steps:
        lines.append("  no reach_margin in this map: thin NO sets between waypoints not checked")
    lines += ["  " + line for line in path_warnings(path)[:PRINT_SUSPECT]]
    rest = (path.suspect_steps or ())[PRINT_SUSPECT:]
    if rest:
        lines.append(
            f"  warning: {len(rest)} more such step{'s' if len(rest) > 1 else ''}, from "
            f"waypoint{'s' if len(rest) > 1 else ''} {', '.join(map(str, rest))} to the next"
        )
    unit = f" [{path.margin_unit}]" if path.margin_unit else ""
    lines += _waypoint_table(
        path.axes,
        [[path.coordinates[a][i] for a in path.axes] for i in range(k)],
        path.margins if path.margin_variable else None,
        f"  margin{unit}" if path.margin_variable else "",
    )
    return "\n".join(lines)


def path_json(path: POCPath) -> dict:
    """Strict-JSON data of the path (``cdpm path --json``): ``waypoints``
    lists {axis: value} per waypoint (``n_waypoints`` of them), ``margins``
    the margin at each (null where the map has none)."""
    return strict(
        {
            "region": path.region,
            "region_size": path.region_size,
            "start_pose": dict(path.start_pose),
            "goal_pose": dict(path.goal_pose),
            "n_waypoints": path.n_waypoints,
            "steps": path.steps,
            "length": path.length,
            "maximise_margin": path.maximise_margin,
            "margin_variable": path.margin_variable,
            "margin_unit": path.margin_unit,
            "min_margin": path.min_margin,
            "suspect_steps": None if path.suspect_steps is None else list(path.suspect_steps),
            "seam_crossings": list(path.seam_crossings),
            "dims": list(path.dims),
            "axes": list(path.axes),
            "units": dict(path.units),
            "waypoints": [path.waypoint(i) for i in range(path.n_waypoints)],
            "margins": path.margins,
            "indices": path.indices,
            "coordinates": path.coordinates,
            "natural_names": list(path.natural_names),
            "natural": path.natural,
        }
    )


# ----------------------------------------------------------- certified box


def certified_neighbourhood_lines(cn: CertifiedNeighbourhood) -> list[str]:
    """The certified box around a pose in words (``cdpm analyze
    --neighbourhood``; first line: the summary)."""
    varied = ", ".join(cn.coordinates)
    if not cn.proven:
        return [
            f"Certified POC box (q +- h over {varied}, h <= {cn.radius:.4g}): none proven: "
            f"{cn.reason}"
        ]
    whole = " (all of R)" if cn.unproven is None else ""
    out = [
        f"Certified POC box (q +- h over {varied}, h <= {cn.radius:.4g}): half-width "
        f"h = {cn.half_width:.4g}{whole}, proven POC YES at every pose of it; "
        f"r_T >= {cn.margin_lower:.4g} {cn.margin_unit} on it (T {cn.horizon:.3g} s, "
        f"budget {cn.tension_budget:.3g} N)"
    ]
    sides = ", ".join(
        f"{c} [{cn.lower[i]:.5g}, {cn.upper[i]:.5g}]"
        for i, c in enumerate(cn.coordinate_names)
        if c in cn.coordinates
    )
    out.append(f"  box: {sides}" + ("; clipped to the joint limits" if cn.clipped else ""))
    if cn.unproven is not None:
        out.append(
            f"  h in [{cn.half_width:.4g}, {cn.unproven:.4g}): the box of half-width "
            f"{cn.unproven:.4g} was not proven (bisection)"
        )
    out.append(f"  proof: {cn.reason}; {cn.boxes_tried} boxes certified in the search")
    return out


def certified_neighbourhood_json(cn: CertifiedNeighbourhood) -> dict:
    """Strict-JSON data of the certified box (null margin when none is proven)."""
    names = cn.coordinate_names
    return strict(
        {
            "model": cn.model_name,
            "pose": cn.pose_name,
            "coordinates": dict(zip(names, cn.natural.tolist(), strict=True)),
            "varied": list(cn.coordinates),
            "radius": cn.radius,
            "proven": cn.proven,
            "verdict": verdict_key(cn.verdict),
            "half_width": cn.half_width,
            "unproven": cn.unproven,
            "lower": dict(zip(names, cn.lower.tolist(), strict=True)),
            "upper": dict(zip(names, cn.upper.tolist(), strict=True)),
            "clipped": cn.clipped,
            "margin_lower": cn.margin_lower,
            "margin_unit": cn.margin_unit,
            "horizon": cn.horizon,
            "tension_budget": cn.tension_budget,
            "boxes_tried": cn.boxes_tried,
            "reason": cn.reason,
        }
    )


# ---------------------------------------------------------- certified path


def _certified_unit(path: CertifiedPath) -> str:
    units = {u for u in path.units if u}
    if len(units) == 1:
        return next(iter(units))
    return "axis units" if not units else "m or rad"


def certified_path_text(path: CertifiedPath) -> str:
    """The certified path as ``cdpm path`` prints it on a certified map: the
    summary, its smallest margin bound, seam crossings and the waypoints
    (the first and last PRINT_WAYPOINTS / 2 of a longer path), each step
    with its box's margin bound."""
    kind = "largest smallest margin" if path.maximise_margin else "shortest"
    k, n = path.n_waypoints, path.n_steps
    lines = [
        f"certified POC path ({kind}) in certified region {path.region} "
        f"({path.region_boxes} YES boxes, {100 * path.region_volume:.1f}% of the mapped "
        f"volume): {k} waypoint{'s' if k != 1 else ''}, {n} straight step"
        f"{'s' if n != 1 else ''}, each inside one certified YES box "
        f"({np.unique(path.boxes).size} boxes), length {path.length:.4g} "
        f"[{_certified_unit(path)}]",
        "  every pose along it is proven POC (no step can cross a NO set)",
    ]
    if n:
        at = int(np.argmin(path.margins))
        lines.append(
            f"  smallest margin bound along it: r_T >= {path.min_margin:.4g} "
            f"{path.margin_unit} (step {at + 1}, from waypoint {at} to {at + 1}; steered as leg "
            f"{at + 1})"
        )
    if path.seam_crossings:
        lines.append(
            "  crosses the seam of a full-turn axis at waypoint(s) "
            f"{', '.join(map(str, path.seam_crossings))}"
        )
    lines += _waypoint_table(
        path.coordinates,
        path.map_waypoints,
        path.margins[:n],
        f"  r_T >= [{path.margin_unit}] to the next",
    )
    return "\n".join(lines)


def certified_path_json(path: CertifiedPath) -> dict:
    """Strict-JSON data of the certified path (``cdpm path --json`` on a
    certified map): ``waypoints`` lists {coordinate: value} per waypoint,
    ``steps`` each step's two ends in its box's coordinates with the box
    and its margin bound."""
    names = path.coordinates
    shown = path.map_waypoints
    return strict(
        {
            "certified": True,
            "region": path.region,
            "region_boxes": path.region_boxes,
            "region_volume": path.region_volume,
            "n_waypoints": path.n_waypoints,
            "n_steps": path.n_steps,
            "length": path.length,
            "maximise_margin": path.maximise_margin,
            "threshold": path.threshold,
            "min_margin": path.min_margin,
            "margin_unit": path.margin_unit,
            "seam_crossings": list(path.seam_crossings),
            "coordinates": list(names),
            "units": list(path.units),
            "start": dict(zip(names, path.start.tolist(), strict=True)),
            "goal": dict(zip(names, path.goal.tolist(), strict=True)),
            "waypoints": [dict(zip(names, row.tolist(), strict=True)) for row in shown],
            "steps": [
                {
                    "from": dict(zip(names, step[0].tolist(), strict=True)),
                    "to": dict(zip(names, step[1].tolist(), strict=True)),
                    "box": int(box),
                    "margin_lower": float(m),
                }
                for step, box, m in zip(path.steps, path.boxes, path.margins, strict=True)
            ],
            "natural_names": list(path.natural_names),
            "natural": path.natural,
        }
    )


def _waypoint_table(names, rows, margins, margin_head: str) -> list[str]:
    """A path's waypoints, one line each (the middle ones left out beyond
    PRINT_WAYPOINTS): their coordinates ``rows`` (k, d) under ``names``, and
    where ``margins`` has an entry (None: no column) its value."""
    k = len(rows)
    lines = ["  waypoints:  #  " + " ".join(f"{a:>10}" for a in names) + margin_head]
    show = list(range(k))
    if k > PRINT_WAYPOINTS:
        half = PRINT_WAYPOINTS // 2
        show = list(range(half)) + [-1] + list(range(k - half, k))
    for i in show:
        if i < 0:
            lines.append(f"{'':>14}... ({k - PRINT_WAYPOINTS} more)")
            continue
        row = " ".join(f"{v:>10.4g}" for v in rows[i])
        margin = f"  {margins[i]:.4g}" if margins is not None and i < len(margins) else ""
        lines.append(f"  {'':>10}{i:>3}  {row}{margin}")
    return lines
