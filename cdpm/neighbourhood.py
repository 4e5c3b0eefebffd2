"""The POC neighbourhood of a pose: how far around it every pose is POC.

The seed paper (Section IV-C, Lemma 1, Remark 10) places its nominal pose
in a positive output controllable region because a ball of POC equilibria
surrounds it. :func:`poc_neighbourhood` measures that ball on a local
refined map: it decides positive output controllability (Theorem 1) at the
poses of a grid around q with the map pipeline
(:func:`cdpm.maps._evaluate.evaluate_batch`, as :func:`cdpm.workspace_map`
and :func:`cdpm.analyze_pose` do) and reports the largest radius within
which every sampled pose is YES.

Distances are taken in *scaled natural coordinates*: the offset of a pose
from q is ``s_i = dq_i / scale_i`` over the varied coordinates (all nv, or
the ones named), with ``scale_i = 1`` by default, so a radius is in rad
for angles and m for lengths, and in a mixed box (a free-flyer) 1 m of
translation counts as 1 rad of rotation unless ``scale`` says otherwise.
The box is ``|s|_inf <= R``.

What is sampled (``k`` varied coordinates, ``n`` points per axis, odd):

- the grid ``s = (i_1, ..., i_k) * h``, ``|i_j| <= (n - 1) / 2``,
  ``h = 2 R / (n - 1)`` (so q itself is a grid point);
- when ``n < RAY_POINTS`` (coarse grids, many coordinates), also the
  ``2k`` axis rays ``t R (+-e_j)`` and, for ``k <= MAX_CORNER_RAY_COORDINATES``,
  the ``2^k`` corner rays ``t R (+-1, ..., +-1)``, at
  ``t = 1/M, 2/M, ..., 1`` with ``M = (RAY_POINTS - 1) / 2``.

The default ``n`` is the largest odd number (at most
``MAX_DEFAULT_POINTS``) whose grid has at most ``DEFAULT_MAX_POSES`` poses
when the map's zero-load path decides them in closed form (no gravity,
load, damping or pretension and nv <= 2, a few microseconds a pose), else
``DEFAULT_MAX_POSES_LOADED`` (the analyser at about 0.3 ms a pose); when
even ``3^k`` poses exceed that, the grid is q alone plus the rays.

Every pose that is not YES counts against the radius: NO, MARGINAL
(undecided) and not analysed (zero-length cable, singular mass matrix, no
equilibrium, analysis failed). Poses outside the URDF joint limits are
evaluated like the others (a map does too; a revolute joint limited to
+-pi wraps) and counted in ``outside_limits``.
"""

from __future__ import annotations

import html
import itertools
import math
import os
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.errors import InputError
from cdpm.numerics import SPAN_TOL
from cdpm.verdicts import NOT_ANALYSED, STATUS_CODES, STATUS_LABELS, VERDICT_CODES, YES, verdict_key

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.robot import CableRobot

__all__ = ["Neighbourhood", "NonYesPose", "poc_neighbourhood"]

#: default grid budget on the closed-form (zero-load, nv <= 2) path [poses]
DEFAULT_MAX_POSES = 20000
#: default grid budget when poses go through the analyser [poses]
DEFAULT_MAX_POSES_LOADED = 4000
#: most points per axis of a default grid
MAX_DEFAULT_POINTS = 101
#: most poses of a grid with ``points`` given
MAX_POSES = 1_000_000
#: grids with fewer points per axis get rays of this many points through q
RAY_POINTS = 21
#: corner rays (2^k of them) only up to this many varied coordinates
MAX_CORNER_RAY_COORDINATES = 10
#: poses per call of the pipeline
_CHUNK = 4096


@dataclass(frozen=True)
class NonYesPose:
    """A sampled pose whose verdict is not YES.

    Attributes:
        natural: its natural coordinates, shape (nv,) [rad or m].
        offset: ``dq`` over the varied coordinates, shape (k,) [rad or m].
        distance_box: ``|dq / scale|_inf`` [rad or m, scaled].
        distance_ball: ``|dq / scale|_2`` [rad or m, scaled].
        verdict: its POC verdict code (:data:`cdpm.verdicts.VERDICT_CODES`).
        status: its status code (:data:`cdpm.verdicts.STATUS_CODES`).
        outside_limits: it lies outside the URDF joint limits.
    """

    natural: np.ndarray
    offset: np.ndarray
    distance_box: float
    distance_ball: float
    verdict: int
    status: int
    outside_limits: bool

    def describe(self) -> str:
        """The verdict in words: ``NO``, ``MARGINAL`` or ``not analysed (no equilibrium)``."""
        return _describe(self.verdict, self.status)

    def as_dict(self, coordinate_names: Sequence[str]) -> dict:
        """Plain JSON data (coordinates by name)."""
        return {
            "coordinates": dict(zip(coordinate_names, map(float, self.natural), strict=True)),
            "distance_box": self.distance_box,
            "distance_ball": self.distance_ball,
            "verdict": verdict_key(self.verdict),
            "status": STATUS_LABELS.get(self.status, str(self.status)),
            "description": self.describe(),
            "outside_limits": self.outside_limits,
        }


@dataclass(frozen=True)
class Neighbourhood:
    """The POC neighbourhood of a pose, measured on a local refined map.

    Distances are in scaled natural coordinates ``s = dq / scale`` over the
    varied coordinates (module docstring), in :attr:`unit`.

    Attributes:
        model_name: name of the spec file.
        pose_name: name of the pose, or None for an explicit q.
        natural: natural coordinates of the pose, shape (nv,).
        coordinate_names: names of all nv natural coordinates.
        coordinates: the k varied coordinates (the box's axes), in robot order.
        units: ``"rad"`` or ``"m"`` per varied coordinate, (k,).
        scale: scale per varied coordinate [its unit per unit of R], (k,).
        radius: R, the box's half-width [scaled units].
        points: grid points per axis n (odd; 1: q alone, rays only).
        step: grid step per varied coordinate [its unit], (k,): ``2 R
            scale / (n - 1)`` (NaN for n = 1).
        axis_rays, corner_rays: numbers of rays sampled besides the grid.
        ray_points: sampled points per ray (beyond q), 0 without rays.
        n_poses: poses evaluated (q included; 1 when q is not YES).
        verdict, status: POC verdict and status codes at q.
        box_radius: the largest sampled shell radius r <= R fully YES: every
            sampled pose with ``|s|_inf <= r`` is YES (0 when q is not, R
            when every sampled pose is).
        box_bracket: (box_radius, inf-norm distance of the nearest non-YES
            pose, one grid step more on a grid; None when there is none).
        ball_radius, ball_bracket: the same in the 2-norm ``|s|_2``, over
            the sampled poses with ``|s|_2 <= R``.
        whole_box_yes: every sampled pose is YES (the radii are then R: at
            least R, as far as the samples show).
        nearest: the non-YES pose nearest in the inf-norm (ties: in the
            2-norm), or None; nearest_ball: the nearest in the 2-norm with
            ``|s|_2 <= R``, or None.
        counts: verdict name -> number of sampled poses.
        status_counts: status name -> number of sampled poses (those > 0).
        outside_limits: sampled poses outside the URDF joint limits.
        tension: the equilibrium tension setting (method name or tensions [N]).
        pretension: the pretension [N] passed, or None (the spec's).
        tol: the span tolerance of the decisions [rad].
        seconds: wall time [s]; reason: what limits the radius, in words.
    """

    model_name: str
    pose_name: str | None
    natural: np.ndarray
    coordinate_names: tuple[str, ...]
    coordinates: tuple[str, ...]
    units: tuple[str, ...]
    scale: np.ndarray
    radius: float
    points: int
    step: np.ndarray
    axis_rays: int
    corner_rays: int
    ray_points: int
    n_poses: int
    verdict: int
    status: int
    box_radius: float
    box_bracket: tuple[float, float | None]
    ball_radius: float
    ball_bracket: tuple[float, float | None]
    whole_box_yes: bool
    nearest: NonYesPose | None
    nearest_ball: NonYesPose | None
    counts: dict[str, int]
    status_counts: dict[str, int]
    outside_limits: int
    tension: str | list[float]
    pretension: float | None
    tol: float
    seconds: float
    reason: str

    @property
    def unit(self) -> str:
        """Unit of the radii: ``"rad"`` or ``"m"``; ``"m or rad"`` for mixed
        units at scale 1 (1 m counts as 1 rad); else ``"scaled units"``."""
        if not np.all(self.scale == 1.0):
            return "scaled units"
        return self.units[0] if len(set(self.units)) == 1 else "m or rad"

    @property
    def grid_shape(self) -> str:
        """``"41-point"`` (k = 1), ``"41x41"``, ``"3^6"`` (k > 3) or ``"1-point"``."""
        k = len(self.coordinates)
        if self.points == 1 or k == 1:
            return f"{self.points}-point"
        return "x".join([str(self.points)] * k) if k <= 3 else f"{self.points}^{k}"

    def lines(self) -> list[str]:
        """The neighbourhood in words, for the pose report (first line: the
        summary)."""
        u, R = self.unit, self.radius
        if self.verdict != YES:
            return [f"POC neighbourhood: radius 0: {self.reason} (no neighbourhood evaluated)"]
        head = (
            f"POC neighbourhood: every sampled pose within {self.box_radius:.4g} {u} (box, "
            f"inf-norm) of the pose is YES on a {self.grid_shape} grid"
            + (" plus rays" if self.axis_rays else "")
            + f" of half-width {R:.4g} {u}"
        )
        if self.whole_box_yes:
            out = [head + f": the whole box, so the radius is at least {R:.4g} {u}"]
        else:
            near = self.nearest
            index = [self.coordinate_names.index(c) for c in self.coordinates]
            where = ", ".join(f"{self.coordinate_names[i]} = {near.natural[i]:.5g}" for i in index)
            lo, hi = self.box_bracket
            out = [
                head + f"; nearest non-YES pose ({where}) is {near.describe()}",
                f"  box radius in [{lo:.4g}, {hi:.4g}] {u}: a non-YES pose at {hi:.4g}, every "
                f"sampled pose below it YES (between samples nothing is known)",
            ]
            if self.ball_bracket[1] is None:
                out.append(f"  ball (2-norm): every sampled pose within {R:.4g} {u} is YES")
            else:
                out.append(
                    f"  ball (2-norm): every sampled pose within {self.ball_radius:.4g} {u} is "
                    f"YES, a non-YES pose at {self.ball_bracket[1]:.4g}"
                )
        out.append("  " + self._sampled_text())
        if u == "m or rad":
            out.append("  mixed units: 1 m of translation counts as 1 rad (set scale= to change)")
        elif u == "scaled units":
            parts = ", ".join(
                f"{c} {x:g} {unit}"
                for c, x, unit in zip(self.coordinates, self.scale, self.units, strict=True)
            )
            out.append(f"  distances in dq / scale; scale: {parts}")
        counts = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in self.counts.items() if v)
        out.append(f"  verdicts: {counts}")
        if self.outside_limits:
            also = self.nearest is not None and self.nearest.outside_limits
            out.append(
                f"  {self.outside_limits} sampled poses lie outside the URDF joint limits "
                "(evaluated anyway)" + ("; the nearest non-YES pose is one of them" if also else "")
            )
        return out

    def _sampled_text(self) -> str:
        u = self.unit
        names = ", ".join(self.coordinates)
        if self.points > 1:
            steps = sorted(
                {f"{s:.3g} {unit}" for s, unit in zip(self.step, self.units, strict=True)}
            )
            text = f"sampled: {self.grid_shape} grid over {names}, step {' / '.join(steps)}"
        else:
            text = f"sampled: over {names}, no grid beyond q"
        rays = self.axis_rays + self.corner_rays
        if rays:
            text += (
                f", plus {self.axis_rays} axis and {self.corner_rays} corner rays of "
                f"{self.ray_points} points (step {self.radius / self.ray_points:.3g} {u})"
            )
        return text + f"; {self.n_poses} poses in {self.seconds:.2g} s"

    def __str__(self) -> str:
        return "\n".join(self.lines())

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(str(self))}</pre>"

    def to_plain(self) -> dict:
        """JSON-serialisable content (None for an unbounded bracket)."""
        from cdpm.analysis._common import to_plain

        names = self.coordinate_names
        return to_plain(
            {
                "model": self.model_name,
                "pose": self.pose_name,
                "coordinates": dict(zip(names, self.natural.tolist(), strict=True)),
                "varied": list(self.coordinates),
                "units": list(self.units),
                "unit": self.unit,
                "scale": dict(zip(self.coordinates, self.scale.tolist(), strict=True)),
                "radius": self.radius,
                "points": self.points,
                "grid": self.grid_shape,
                "step": dict(zip(self.coordinates, self.step.tolist(), strict=True)),
                "rays": {"axis": self.axis_rays, "corner": self.corner_rays},
                "ray_points": self.ray_points,
                "n_poses": self.n_poses,
                "verdict": verdict_key(self.verdict),
                "status": STATUS_LABELS.get(self.status, str(self.status)),
                "box_radius": self.box_radius,
                "box_bracket": list(self.box_bracket),
                "ball_radius": self.ball_radius,
                "ball_bracket": list(self.ball_bracket),
                "whole_box_yes": self.whole_box_yes,
                **{
                    key: None if pose is None else pose.as_dict(names)
                    for key, pose in (
                        ("nearest", self.nearest),
                        ("nearest_ball", self.nearest_ball),
                    )
                },
                "counts": self.counts,
                "status_counts": self.status_counts,
                "outside_limits": self.outside_limits,
                "tension": self.tension,
                "pretension": self.pretension,
                "tol": self.tol,
                "seconds": self.seconds,
                "reason": self.reason,
            }
        )

    as_dict = to_plain


def _describe(verdict: int, status: int) -> str:
    if verdict == NOT_ANALYSED:
        return f"not analysed ({STATUS_LABELS.get(int(status), str(status))})"
    return verdict_key(verdict).upper()


def _check_radius(radius: Any) -> float:
    from cdpm.expressions import parse_number

    try:
        if isinstance(radius, bool) or not isinstance(radius, (int, float, str, np.number)):
            raise TypeError
        value = parse_number(radius) if isinstance(radius, str) else float(radius)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"radius must be a number [rad or m], e.g. 0.1 or 'pi/20', got {radius!r}"
        ) from exc
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"radius must be a positive finite number [rad or m], got {radius!r}")
    return value


def _check_points(points: Any, k: int) -> int:
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)):
        raise InputError(f"points must be an odd integer >= 1 (points per axis), got {points!r}")
    n = int(points)
    if n < 1 or n % 2 == 0:
        raise InputError(
            f"points must be odd and >= 1 so that q itself is a grid point, got {points!r}"
        )
    if n > 1 and n**k > MAX_POSES:
        raise InputError(
            f"points={n} over {k} coordinates is a grid of {n**k:,} poses; at most "
            f"{MAX_POSES:,}: give fewer points or fewer coordinates"
        )
    return n


def _check_coordinates(robot: CableRobot, coordinates: Any) -> list[int]:
    names = list(robot.coordinate_names)
    if coordinates is None:
        return list(range(robot.nv))
    try:
        chosen = [coordinates] if isinstance(coordinates, str) else list(coordinates)
    except TypeError as exc:
        raise InputError(f"coordinates must be coordinate names ({', '.join(names)})") from exc
    unknown = [c for c in chosen if c not in names]
    if unknown:
        raise InputError(
            f"unknown coordinates {', '.join(map(repr, unknown))}; coordinates: {', '.join(names)}"
        )
    if not chosen or len(set(chosen)) != len(chosen):
        raise InputError(f"coordinates must name distinct coordinates, got {coordinates!r}")
    return sorted(names.index(c) for c in chosen)


def _check_scale(robot: CableRobot, scale: Any, columns: list[int]) -> np.ndarray:
    out = np.ones(len(columns))
    if scale is None:
        return out
    if not isinstance(scale, Mapping):
        raise InputError(f"scale must be a mapping coordinate -> positive number, got {scale!r}")
    varied = [robot.coordinate_names[i] for i in columns]
    for name, value in scale.items():
        if name not in varied:
            raise InputError(
                f"scale given for {name!r}, which is not a varied coordinate ({', '.join(varied)})"
            )
        try:
            x = float(value)
        except (TypeError, ValueError):
            x = math.nan
        if isinstance(value, bool) or not (math.isfinite(x) and x > 0):
            raise InputError(f"scale of {name!r} must be a positive number, got {value!r}")
        out[varied.index(name)] = x
    return out


def _resolve_setting(robot: CableRobot, tension: Any, pretension: Any):
    """(tension setting, pretension) validated as the map code does."""
    from cdpm.equilibrium import EQUILIBRIUM_METHODS, EquilibriumWarning, resolve_method
    from cdpm.maps._evaluate import resolve_tension

    with warnings.catch_warnings():
        if isinstance(pretension, (int, float)) and pretension > 0:
            # the warning is about the spec's pretension of 0 N, not used here
            warnings.simplefilter("ignore", EquilibriumWarning)
        setting = resolve_tension(robot, tension)
    if isinstance(setting, str):
        _, value = resolve_method(robot, setting, pretension)
        pretension = None if pretension is None else value
        return setting, pretension, EQUILIBRIUM_METHODS[setting].uses_pretension
    return setting, pretension, False


def _default_points(k: int, budget: int) -> int:
    if 3**k > budget:
        return 1
    n = 3
    while n + 2 <= MAX_DEFAULT_POINTS and (n + 2) ** k <= budget:
        n += 2
    return n


def _limits(robot: CableRobot) -> tuple[np.ndarray, np.ndarray]:
    """URDF position limits in natural coordinates, (nv,) each; +-inf
    where a coordinate has none (rotations of multi-DOF joints)."""
    from cdpm.configuration import _kind

    model = robot.model
    lower_q = np.asarray(model.lowerPositionLimit, dtype=float)
    upper_q = np.asarray(model.upperPositionLimit, dtype=float)
    lower = np.full(robot.nv, -np.inf)
    upper = np.full(robot.nv, np.inf)
    for j in range(1, model.njoints):
        joint = model.joints[j]
        kind = _kind(joint)
        count = {"euclidean": joint.nv, "freeflyer": 3, "planar": 2}.get(kind, 0)
        iq, iv = joint.idx_q, joint.idx_v
        lower[iv : iv + count] = lower_q[iq : iq + count]
        upper[iv : iv + count] = upper_q[iq : iq + count]
    return lower, upper


def _lattice(k: int, n: int, rays: bool) -> tuple[np.ndarray, int, int, int]:
    """Sampled offsets as integers: ``U`` (N, k) with ``s = U R / L``.

    Returns:
        (U without the zero row, L, axis rays, corner rays).
    """
    half = (n - 1) // 2
    m = (RAY_POINTS - 1) // 2 if rays else 1
    L = math.lcm(max(half, 1), m)
    parts = []
    if half:
        axis = np.arange(-half, half + 1) * (L // half)
        parts.append(np.stack(np.meshgrid(*[axis] * k, indexing="ij"), -1).reshape(-1, k))
    n_axis = n_corner = 0
    if rays:
        eye = np.eye(k, dtype=np.int64)
        directions = [eye, -eye]
        n_axis = 2 * k
        if k <= MAX_CORNER_RAY_COORDINATES and k > 1:
            directions.append(np.array(list(itertools.product((-1, 1), repeat=k))))
            n_corner = 2**k
        d = np.vstack(directions)
        t = np.arange(1, m + 1) * (L // m)
        parts.append((d[:, None, :] * t[None, :, None]).reshape(-1, k))
    U = np.unique(np.vstack(parts).astype(np.int64), axis=0)
    U = U[np.any(U != 0, axis=1)]
    return U, L, n_axis, n_corner


def _evaluate(robot, natural, setting, pretension, tol) -> tuple[np.ndarray, np.ndarray]:
    """POC verdict and status codes (N,) of the poses ``natural`` (N, nv),
    by the map pipeline in chunks."""
    from cdpm.maps._evaluate import evaluate_batch
    from cdpm.maps.criteria import CRITERIA

    n = natural.shape[0]
    poc = np.full(n, NOT_ANALYSED, dtype=np.int8)
    status = np.full(n, STATUS_CODES["pending"], dtype=np.int8)
    for start in range(0, n, _CHUNK):
        stop = min(n, start + _CHUNK)
        batch = evaluate_batch(
            robot, natural[start:stop], setting, margin=False, tol=tol, pretension=pretension
        )
        poc[start:stop] = CRITERIA["poc"].compute(batch)
        status[start:stop] = CRITERIA["status"].compute(batch)
    return poc, status


def _shell(distance: np.ndarray, good: np.ndarray, within: np.ndarray, unit: float, root: bool):
    """(largest sampled distance fully YES, distance of the nearest non-YES
    pose) over the poses ``within``, from exact integer distances (squared
    when ``root``) times ``unit``; None for the second when all are YES."""
    bad = within & ~good
    if not bad.any():
        return None, None
    first = distance[bad].min()
    below = within & good & (distance < first)
    pair = np.array([distance[below].max() if below.any() else 0, first], dtype=float)
    lo, hi = (np.sqrt(pair) if root else pair) * unit
    return float(lo), float(hi)


def poc_neighbourhood(
    robot: CableRobot | str | os.PathLike,
    q: Any,
    radius: Any,
    *,
    points: int | None = None,
    coordinates: Sequence[str] | None = None,
    tension: Any = None,
    pretension: float | None = None,
    scale: Mapping[str, float] | None = None,
    rays: bool | None = None,
    tol: float = SPAN_TOL,
) -> Neighbourhood:
    """How far around the pose q every sampled pose is positive output
    controllable (module docstring: what is sampled, the units).

    Args:
        robot: a :class:`~cdpm.robot.CableRobot` or the path of its cable spec.
        q: a pose name from the spec, a configuration vector (nq,) or
            natural coordinates (nv,) (as :func:`cdpm.analyze_pose`).
        radius: R > 0, the half-width of the box ``|dq_i / scale_i| <= R``
            [rad for angles, m for lengths]; a number or an expression
            such as ``"pi/20"``.
        points: grid points per axis n, odd (q is the centre point; 1: q
            and the rays only); default from the pose budget.
        coordinates: names of the coordinates to vary (default all nv);
            the others stay at q.
        tension: equilibrium tension: None (the spec's method), a method
            name (``zero``, ``min_norm``, ``pretension``) or tensions [N] (m,).
        pretension: least tension [N] for the ``pretension`` method (None:
            the spec's).
        scale: coordinate name -> positive scale (default 1): that
            coordinate spans ``+-R scale`` and its distances are divided by
            the scale (e.g. ``{"platform_joint.x": 0.5}`` counts 0.5 m of
            translation as 1 unit of R).
        rays: sample the axis and corner rays; default when n < RAY_POINTS.
        tol: angle-like tolerance of the span decisions [rad] (as for maps).

    Returns:
        :class:`Neighbourhood` (radii, brackets, nearest non-YES pose, counts).

    Raises:
        InputError: a radius that is not a positive finite number, points
            not an odd integer (or beyond MAX_POSES poses), unknown or
            repeated coordinates, a bad scale, tension, pretension, tol or q.
    """
    from cdpm.equilibrium import EquilibriumWarning
    from cdpm.maps._evaluate import check_tol, zero_equilibrium
    from cdpm.maps._plan import coordinate_units
    from cdpm.maps._runner import single_threaded_blas
    from cdpm.robot import CableRobot, load_robot

    started = time.perf_counter()
    if not isinstance(robot, CableRobot):
        robot = load_robot(robot)
    R = _check_radius(radius)
    columns = _check_coordinates(robot, coordinates)
    k = len(columns)
    scale_k = _check_scale(robot, scale, columns)
    tol = check_tol(tol)
    setting, pretension, uses_pretension = _resolve_setting(robot, tension, pretension)
    if points is None:  # the map's zero-load path decides in closed form (cheap)?
        closed = robot.nv <= 2 and zero_equilibrium(robot, setting)
        closed = closed and not (uses_pretension and pretension)
        n = _default_points(k, DEFAULT_MAX_POSES if closed else DEFAULT_MAX_POSES_LOADED)
    else:
        n = _check_points(points, k)
    with_rays = n < RAY_POINTS if rays is None else bool(rays)
    if n == 1 and not with_rays:
        raise InputError("points=1 samples q alone: leave rays on (rays=None or True)")
    pose_name = q if isinstance(q, str) else None
    natural = robot.to_natural(robot.as_q(q))
    units = [coordinate_units(robot.model)[i] for i in columns]
    names = [robot.coordinate_names[i] for i in columns]
    step = 2 * R * scale_k / (n - 1) if n > 1 else np.full(k, np.nan)
    U, L, n_axis, n_corner = _lattice(k, n, with_rays)
    lower, upper = _limits(robot)

    offsets = np.zeros((U.shape[0] + 1, robot.nv))
    offsets[1:, columns] = U * (R / L) * scale_k
    poses = natural + offsets  # (N, nv), q first
    with single_threaded_blas(), warnings.catch_warnings():
        # the pipeline repeats, per chunk, the tension warning given above
        warnings.simplefilter("ignore", EquilibriumWarning)
        poc0, status0 = _evaluate(robot, natural[None], setting, pretension, tol)
        verdict, status = int(poc0[0]), int(status0[0])
        if verdict == YES:
            poc_rest, status_rest = _evaluate(robot, poses[1:], setting, pretension, tol)
            poc = np.concatenate([poc0, poc_rest])
            status_all = np.concatenate([status0, status_rest])
        else:
            poses, poc, status_all = poses[:1], poc0, status0
    n_eval = poses.shape[0]
    U_all = np.vstack([np.zeros((1, k), dtype=np.int64), U])[:n_eval]
    inf_int = np.abs(U_all).max(axis=1)
    sq_int = (U_all**2).sum(axis=1)
    outside = np.any((poses < lower - 1e-12) | (poses > upper + 1e-12), axis=1)
    good = poc == YES
    in_ball = sq_int <= L * L

    def pose_at(index: int) -> NonYesPose:
        return NonYesPose(
            natural=poses[index].copy(),
            offset=offsets[index, columns].copy(),
            distance_box=float(inf_int[index] * R / L),
            distance_ball=float(math.sqrt(sq_int[index]) * R / L),
            verdict=int(poc[index]),
            status=int(status_all[index]),
            outside_limits=bool(outside[index]),
        )

    if verdict != YES:
        box = ball = (0.0, 0.0)
        nearest = nearest_ball = pose_at(0)
        reason = f"the pose itself is {_describe(verdict, status)}"
    else:
        box = _shell(inf_int, good, np.ones(n_eval, dtype=bool), R / L, False)
        ball = _shell(sq_int, good, in_ball, R / L, True)
        box, ball = [(R, None) if lo is None else (lo, hi) for lo, hi in (box, ball)]
        bad = np.flatnonzero(~good)
        nearest = nearest_ball = None
        if bad.size:
            nearest = pose_at(int(bad[np.lexsort((sq_int[bad], inf_int[bad]))[0]]))
            bad_ball = bad[in_ball[bad]]
            if bad_ball.size:
                nearest_ball = pose_at(
                    int(bad_ball[np.lexsort((inf_int[bad_ball], sq_int[bad_ball]))[0]])
                )
            reason = (
                f"the nearest non-YES sampled pose is {nearest.describe()} at "
                f"{nearest.distance_box:.3g} (inf-norm)"
            )
        else:
            reason = "every sampled pose in the box is YES"
    counts = {name: int(np.count_nonzero(poc == code)) for name, code in VERDICT_CODES.items()}
    status_counts = {
        STATUS_LABELS[code]: int(np.count_nonzero(status_all == code))
        for code in STATUS_CODES.values()
        if np.any(status_all == code)
    }
    return Neighbourhood(
        model_name=robot.spec.path.name,
        pose_name=pose_name,
        natural=natural,
        coordinate_names=tuple(robot.coordinate_names),
        coordinates=tuple(names),
        units=tuple(units),
        scale=scale_k,
        radius=R,
        points=n,
        step=step,
        axis_rays=n_axis,
        corner_rays=n_corner,
        ray_points=(RAY_POINTS - 1) // 2 if with_rays else 0,
        n_poses=int(n_eval),
        verdict=verdict,
        status=status,
        box_radius=box[0],
        box_bracket=box,
        ball_radius=ball[0],
        ball_bracket=ball,
        whole_box_yes=bool(verdict == YES and good.all()),
        nearest=nearest,
        nearest_ball=nearest_ball,
        counts=counts,
        status_counts=status_counts,
        outside_limits=int(np.count_nonzero(outside)),
        tension=setting,
        pretension=pretension,
        tol=tol,
        seconds=time.perf_counter() - started,
        reason=reason,
    )
