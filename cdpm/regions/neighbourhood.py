"""The POC neighbourhood of a pose: how far around it every pose is POC.

The seed paper (Section IV-C, Lemma 1, Remark 10) places its nominal pose
in a POC region because a ball of POC equilibria surrounds it.
:func:`poc_neighbourhood` measures that ball: it decides POC (Theorem 1) and
the reach margin r_T on a grid around q with the map pipeline
(:func:`cdpm.pipeline.evaluate.evaluate_batch`) and reports the largest radius
within which every sampled pose is YES and r_T stays clear of 0 between
neighbouring samples (:func:`cdpm.regions.paths.suspect_edges`: an estimate
from r_T's sampled slopes, not a proof; each suspect step is resampled at
NEIGHBOURHOOD_REFINE_POINTS poses and judged again on the finer steps, which
clears the steps where r_T only looked steep). Distances are in
scaled natural coordinates ``s = dq / scale`` (rad for angles, m for
lengths at scale 1); the box is ``|s|_inf <= R``. docs/analysis.md, "The
POC neighbourhood", gives the sampling rules, the defaults and examples.
"""

from __future__ import annotations

import itertools
import math
import os
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpm.dynamics.equilibrium import EQUILIBRIUM_METHODS, EquilibriumWarning, resolve_method
from cdpm.dynamics.reach import reach_settings, reach_unit
from cdpm.errors import InputError, is_integer
from cdpm.expressions import parse_number
from cdpm.model.coordinates import coordinate_limits, coordinate_units
from cdpm.model.robot import CableRobot, load_robot
from cdpm.numerics import NEIGHBOURHOOD_REFINE_POINTS, SPAN_TOL
from cdpm.pipeline.criteria import CRITERIA
from cdpm.pipeline.evaluate import (
    check_tol,
    evaluate_batch,
    resolve_tension,
    single_threaded_blas,
    zero_equilibrium,
)
from cdpm.printing import TextRepr
from cdpm.regions.paths import suspect_edges
from cdpm.verdicts import (
    MARGINAL,
    NO,
    NOT_ANALYSED,
    STATUS_CODES,
    STATUS_LABELS,
    VERDICT_CODES,
    YES,
    verdict_key,
)

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.dynamics.reach import ReachSettings

__all__ = [
    "Neighbourhood",
    "SampledPose",
    "NonYesPose",
    "poc_neighbourhood",
    "CertifiedNeighbourhood",
    "certified_neighbourhood",
]

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
#: suspect edges resampled at least, however few poses the grid has
_MIN_RESAMPLED_EDGES = 16
#: certified_neighbourhood: half-widths R 2^(-j/2), j = 0 .. this, tried
#: at once (the smallest is R / 2^15, about 3e-5 R)
CERTIFIED_NEIGHBOURHOOD_HALVINGS = 30
#: ... then this many half-widths evenly inside the bracket, twice (the
#: bracket shrinks by a factor of 17 each time)
CERTIFIED_NEIGHBOURHOOD_REFINE = 16
#: ... each box bisected while undecided into about this many pieces at
#: most (a box is proven when every piece is)
CERTIFIED_NEIGHBOURHOOD_PIECES = 64


@dataclass(frozen=True)
class SampledPose:
    """A sampled pose that is not YES, or an end of a suspect edge.

    Attributes:
        natural: its natural coordinates, shape (nv,) [rad or m].
        offset: ``dq`` over the varied coordinates, shape (k,) [rad or m].
        distance_box, distance_ball: ``|dq / scale|`` in the inf- and 2-norm.
        verdict, status: its POC verdict and status codes (cdpm.verdicts).
        outside_limits: it lies outside the URDF joint limits.
        margin: its reach margin r_T [output units] (NaN when not analysed).
    """

    natural: np.ndarray
    offset: np.ndarray
    distance_box: float
    distance_ball: float
    verdict: int
    status: int
    outside_limits: bool
    margin: float = math.nan

    def describe(self) -> str:
        """The verdict in words: ``NO``, ``MARGINAL`` or ``not analysed (no equilibrium)``."""
        return _describe(self.verdict, self.status)


NonYesPose = SampledPose  # the nearest non-YES poses are SampledPose too


@dataclass(frozen=True)
class Neighbourhood(TextRepr):
    """The POC neighbourhood of a pose, measured on a local refined map;
    distances in scaled natural coordinates ``s = dq / scale``, in :attr:`unit`.

    Printing it gives a short summary; :func:`cdpm.text.neighbourhood_text`
    prints it in full, :func:`cdpm.text.neighbourhood_json` gives its JSON
    data.

    Attributes:
        model_name: name of the spec file.
        pose_name: name of the pose, or None for an explicit q.
        natural: natural coordinates of the pose, shape (nv,).
        coordinate_names: names of all nv natural coordinates.
        coordinates: the k varied coordinates (the box's axes), in robot order.
        units, scale: ``"rad"`` or ``"m"``, and the scale [unit per unit of
            R], per varied coordinate (k,).
        radius: R, the box's half-width [scaled units].
        points: grid points per axis n (odd; 1: q alone, rays only).
        step: grid step per varied coordinate [its unit], (k,): ``2 R
            scale / (n - 1)`` (NaN for n = 1).
        axis_rays, corner_rays, ray_points: rays sampled besides the grid
            and points per ray (beyond q).
        n_poses: poses evaluated (q included; 1 when q is not YES).
        verdict, status: POC verdict and status codes at q.
        box_radius: the largest sampled radius r <= R within which every
            sampled pose is YES and no suspect edge starts (``|s|_inf``).
        box_bracket: (box_radius, where the region may end: the nearest
            non-YES pose or far end of a suspect edge; None: nothing does).
        ball_radius, ball_bracket: the same in the 2-norm ``|s|_2 <= R``.
        whole_box_yes: every sampled pose is YES and no edge is suspect
            (the radii are then R: at least R, as far as the samples show).
        nearest: the non-YES pose nearest in the inf-norm (ties: 2-norm), or
            None; nearest_ball: the nearest in the 2-norm inside the ball.
        suspect_edges: number of suspect edges (still suspect after
            resampling); nearest_suspect: the ends (nearer first) of the one
            whose nearer end is nearest.
        reach: the reach margin's horizon and tension budget.
        counts, status_counts: verdict and status name -> sampled poses.
        outside_limits: sampled poses outside the URDF joint limits.
        tension, pretension: the equilibrium tension setting (method name
            or tensions [N]) and the pretension [N] passed (None: the spec's).
        tol: the span tolerance [rad]; seconds: wall time [s]; reason: what
            limits the radius, in words.
        refined_poses: poses evaluated along suspect edges (besides n_poses),
            NEIGHBOURHOOD_REFINE_POINTS per edge resampled.
        suspect_cleared: suspect edges whose finer steps all cleared them.
        suspect_least: along the nearest suspect edge, the resampled pose
            of least r_T (or its first non-YES one), or None.
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
    nearest: SampledPose | None
    nearest_ball: SampledPose | None
    suspect_edges: int
    nearest_suspect: tuple[SampledPose, SampledPose] | None
    reach: ReachSettings
    counts: dict[str, int]
    status_counts: dict[str, int]
    outside_limits: int
    tension: str | list[float]
    pretension: float | None
    tol: float
    seconds: float
    reason: str
    margin_unit: str = "m"
    refined_poses: int = 0
    suspect_cleared: int = 0
    suspect_least: SampledPose | None = None

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

    def __str__(self) -> str:
        # a summary; cdpm.text.neighbourhood_text gives the pose report's text
        where = f"pose {self.pose_name!r}" if self.pose_name else "the given q"
        head = f"POC neighbourhood of {where} ({self.model_name})"
        if self.verdict != YES:
            return f"{head}: radius 0 ({self.reason})"
        u = self.unit
        least = "at least " if self.whole_box_yes else ""
        return (
            f"{head}: radius {least}{self.box_radius:.4g} {u} (box, inf-norm), "
            f"{least}{self.ball_radius:.4g} {u} (ball, 2-norm)\n"
            f"  {self.reason}; {self.n_poses} poses sampled within {self.radius:.4g} {u}"
        )


def _describe(verdict: int, status: int) -> str:
    if verdict == NOT_ANALYSED:
        return f"not analysed ({STATUS_LABELS.get(int(status), str(status))})"
    return verdict_key(verdict).upper()


def _check_radius(radius: Any) -> float:
    try:
        value = parse_number(radius)
    except ValueError as exc:
        raise InputError(
            f"radius must be a number [rad or m], e.g. 0.1 or 'pi/20', got {radius!r}"
        ) from exc
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"radius must be a positive finite number [rad or m], got {radius!r}")
    return value


def _check_points(points: Any, k: int) -> int:
    if not is_integer(points):
        raise InputError(f"points must be an odd integer >= 1 (points per axis), got {points!r}")
    n = int(points)
    if n < 1 or n % 2 == 0:
        raise InputError(f"points must be odd and >= 1 so that q is a grid point, got {points!r}")
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
    if scale is not None and not isinstance(scale, Mapping):
        raise InputError(f"scale must be a mapping coordinate -> positive number, got {scale!r}")
    varied = [robot.coordinate_names[i] for i in columns]
    for name, value in (scale or {}).items():
        if name not in varied:
            raise InputError(
                f"scale given for {name!r}, which is not a varied coordinate ({', '.join(varied)})"
            )
        try:
            x = math.nan if isinstance(value, bool) else float(value)
        except (TypeError, ValueError):
            x = math.nan
        if not (math.isfinite(x) and x > 0):
            raise InputError(f"scale of {name!r} must be a positive number, got {value!r}")
        out[varied.index(name)] = x
    return out


def _resolve_setting(robot: CableRobot, tension: Any, pretension: Any):
    """(tension setting, pretension) validated as the map code does."""

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
    odd = [n for n in range(3, MAX_DEFAULT_POINTS + 1, 2) if n**k <= budget]
    return odd[-1] if odd else 1


def _lattice(k: int, n: int, rays: bool) -> tuple[np.ndarray, int, int, int, np.ndarray]:
    """Sampled offsets as integers ``U`` (N, k), ``s = U R / L``: (U without
    the zero row, L, axis rays, corner rays, the steps (V, k) between
    neighbouring samples: the grid step along each axis and a ray step
    along each ray, one sign each)."""
    half = (n - 1) // 2
    m = (RAY_POINTS - 1) // 2 if rays else 1
    L = math.lcm(max(half, 1), m)
    parts, steps = [], []
    if half:
        axis = np.arange(-half, half + 1) * (L // half)
        parts.append(np.stack(np.meshgrid(*[axis] * k, indexing="ij"), -1).reshape(-1, k))
        steps.append(np.eye(k, dtype=np.int64) * (L // half))
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
        first = d[np.arange(d.shape[0]), np.argmax(d != 0, axis=1)]
        steps.append(d[first > 0] * (L // m))
    U = np.unique(np.vstack(parts).astype(np.int64), axis=0)
    return U[np.any(U != 0, axis=1)], L, n_axis, n_corner, np.unique(np.vstack(steps), axis=0)


def _edges(U: np.ndarray, steps: np.ndarray, refined: int) -> np.ndarray:
    """Pairs (2, E) of rows i, j of ``U`` (N, k) with ``U[j] = U[i] + v``
    for a step v of ``steps``: the neighbouring samples; grid steps of
    length ``refined`` along an axis through q, where the finer axis rays
    sample, are left out."""
    U = np.ascontiguousarray(U, dtype=np.int64)
    row = {u.tobytes(): i for i, u in enumerate(U)}
    out = [np.zeros((2, 0), dtype=np.intp)]
    for v in steps.astype(np.int64):
        j = np.fromiter((row.get(u.tobytes(), -1) for u in U + v), dtype=np.intp, count=len(U))
        i = np.flatnonzero(j >= 0)
        if np.count_nonzero(v) == 1 and np.abs(v).max() == refined:
            i = i[np.any((U[i] != 0) & (v == 0), axis=1)]  # off the axis through q
        out.append(np.stack([i, j[i]]))
    return np.concatenate(out, axis=1)


def _evaluate(robot, natural, setting, pretension, tol, reach):
    """POC verdict and status codes (N,) and reach margins r_T (N,) [m] of
    the poses ``natural`` (N, nv), by the map pipeline in chunks."""

    n = natural.shape[0]
    poc = np.full(n, NOT_ANALYSED, dtype=np.int8)
    status = np.full(n, STATUS_CODES["pending"], dtype=np.int8)
    margin = np.full(n, np.nan)
    for start in range(0, n, _CHUNK):
        stop = min(n, start + _CHUNK)
        batch = evaluate_batch(
            robot, natural[start:stop], setting, tol=tol, pretension=pretension, reach=reach
        )
        poc[start:stop] = CRITERIA["poc"].compute(batch)
        status[start:stop] = CRITERIA["status"].compute(batch)
        margin[start:stop] = CRITERIA["reach_margin"].compute(batch)
    return poc, status, margin


def _resample_edges(robot, poses, edges, lengths, margin, args, budget: int):
    """Resample the suspect edges (2, E) (nearest first) at
    NEIGHBOURHOOD_REFINE_POINTS poses each, as many as ``budget`` poses
    allow, and judge each edge's finer steps by the same rule
    (:func:`~cdpm.regions.paths.suspect_edges`; the slopes now sampled
    along the edge): an edge stays suspect when a finer step is suspect or
    a resampled pose is not YES; edges not resampled stay suspect.

    Returns:
        (still (E,) bool; for the resampled edges, (natural (E', nv) of the
        pose of least r_T along each, or of its first non-YES pose;
        verdict and status codes (E', 2); that r_T (E',))).
    """
    k = NEIGHBOURHOOD_REFINE_POINTS
    count = min(edges.shape[1], budget // k)
    still = np.ones(edges.shape[1], dtype=bool)
    nv = poses.shape[1]
    if count == 0:
        return still, (np.zeros((0, nv)), np.zeros((0, 2), dtype=int), np.zeros(0))
    a, b = edges[:, :count]
    t = np.arange(1, k + 1) / (k + 1)
    chain = poses[a][:, None, :] + t[None, :, None] * (poses[b] - poses[a])[:, None, :]
    poc, status, r = (x.reshape(count, k) for x in _evaluate(robot, chain.reshape(-1, nv), *args))
    # each edge as a chain a, its k poses, b: k + 1 steps of a (k+1)-th of its length
    nodes = np.arange(count * (k + 2)).reshape(count, k + 2)
    steps = np.stack([nodes[:, :-1].reshape(-1), nodes[:, 1:].reshape(-1)])
    step_lengths = np.repeat(lengths[:count] / (k + 1), k + 1)
    r_chain = np.concatenate([margin[a][:, None], r, margin[b][:, None]], axis=1)
    finer = suspect_edges(steps, step_lengths, r_chain.reshape(-1), np.ones(steps.shape[1], bool))
    bad = poc != YES
    still[:count] = finer.reshape(count, k + 1).any(axis=1) | bad.any(axis=1)
    rows = np.arange(count)
    pick = np.where(
        bad.any(axis=1), bad.argmax(axis=1), np.nanargmin(np.where(bad, np.inf, r), axis=1)
    )
    codes = np.stack([poc[rows, pick], status[rows, pick]], axis=1)
    return still, (chain[rows, pick], codes, r[rows, pick])


def _radius(distance, within, bad, ends, unit: float, root: bool):
    """(radius, where the region may end) from integer distances (squared
    when ``root``) times ``unit``: the largest sampled distance ``within``
    below every ``bad`` pose and not beyond the nearer end of a suspect
    edge (``ends`` (2, E); one on a shell counts like a bad pose there)."""
    near, far = ends.min(axis=0), ends.max(axis=0)
    strict = np.concatenate([distance[bad & within], near[near == far]])
    upper = np.concatenate([distance[bad & within], far])
    if upper.size == 0:
        return None, None
    top = np.iinfo(np.int64).max
    ok = within & (distance < strict.min(initial=top))
    ok &= distance <= near[near < far].min(initial=top)
    pair = np.array([distance[ok].max(), upper.min()], dtype=float)
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
    horizon: Any = None,
    tension_budget: Any = None,
    pose_name: str | None = None,
) -> Neighbourhood:
    """How far around the pose q every sampled pose is positive output
    controllable, with r_T clear of 0 between neighbouring samples.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` or the path of its cable spec.
        q: a pose name from the spec, a configuration vector (nq,) or
            natural coordinates (nv,) (as :func:`cdpm.analyze_pose`).
        radius: R > 0, the half-width of the box ``|dq_i / scale_i| <= R``
            [rad or m]; a number or an expression such as ``"pi/20"``.
        points: grid points per axis n, odd (q is the centre; 1: q and the
            rays only); default from the pose budget. More points refine it.
        coordinates: names of the coordinates to vary (default all nv).
        tension: equilibrium tension: None (the spec's method), a method
            name (``zero``, ``min_norm``, ``pretension``) or tensions [N] (m,).
        pretension: least tension [N] for ``pretension`` (None: the spec's).
        scale: coordinate name -> positive scale (default 1): that
            coordinate spans ``+-R scale`` and its distances are divided by
            it (``{"platform_joint.x": 0.5}``: 0.5 m counts as 1 unit of R).
        rays: sample the axis and corner rays; default when n < RAY_POINTS.
        tol: angle-like tolerance of the span decisions [rad] (as for maps).
        horizon, tension_budget: T [s] and tension budget [N] of r_T
            (:func:`cdpm.dynamics.reach.reach_settings`; default: the model's).
        pose_name: the pose's name in the result when q is given as numbers
            (default: q when q is a name, else None).

    Returns:
        :class:`Neighbourhood`: radii, brackets, what limits them, counts.

    Raises:
        InputError: a radius not positive and finite, points not an odd
            integer (or beyond MAX_POSES poses), unknown or repeated
            coordinates, a bad scale, tension, pretension, tol, horizon,
            tension budget or q.
    """

    started = time.perf_counter()
    robot = robot if isinstance(robot, CableRobot) else load_robot(robot)
    R = _check_radius(radius)
    columns = _check_coordinates(robot, coordinates)
    k = len(columns)
    scale_k = _check_scale(robot, scale, columns)
    tol = check_tol(tol)
    setting, pretension, uses_pretension = _resolve_setting(robot, tension, pretension)
    reach = reach_settings(robot, horizon, tension_budget)
    if points is None:  # the map's zero-load path decides in closed form (cheap)?
        closed = robot.nv <= 2 and zero_equilibrium(robot, setting)
        closed = closed and not (uses_pretension and pretension)
        n = _default_points(k, DEFAULT_MAX_POSES if closed else DEFAULT_MAX_POSES_LOADED)
    else:
        n = _check_points(points, k)
    with_rays = n < RAY_POINTS if rays is None else bool(rays)
    if n == 1 and not with_rays:
        raise InputError("points=1 samples q alone: leave rays on (rays=None or True)")
    pose_name = q if pose_name is None and isinstance(q, str) else pose_name
    natural = robot.to_natural(robot.as_q(q))
    U, L, n_axis, n_corner, steps = _lattice(k, n, with_rays)
    U = np.vstack([np.zeros((1, k), dtype=np.int64), U])  # q first
    offsets = np.zeros((U.shape[0], robot.nv))
    offsets[:, columns] = U * (R / L) * scale_k
    poses = natural + offsets
    with single_threaded_blas(), warnings.catch_warnings():
        # the pipeline repeats, per chunk, the tension warning given above
        warnings.simplefilter("ignore", EquilibriumWarning)
        args = (setting, pretension, tol, reach)
        poc, status_all, margin = _evaluate(robot, poses[:1], *args)
        verdict, status = int(poc[0]), int(status_all[0])
        if verdict == YES:
            rest = _evaluate(robot, poses[1:], *args)
            poc, status_all, margin = (
                np.concatenate(p) for p in zip(*[(poc, status_all, margin), rest], strict=True)
            )
        U, offsets, poses = U[: poc.size], offsets[: poc.size], poses[: poc.size]
    inf_int, sq_int = np.abs(U).max(axis=1), (U**2).sum(axis=1)
    lower, upper = coordinate_limits(robot.model)
    outside = np.any((poses < lower - 1e-12) | (poses > upper + 1e-12), axis=1)
    good, in_ball = poc == YES, sq_int <= L * L

    def pose_at(i: int) -> SampledPose:
        d = float(inf_int[i] * R / L), float(math.sqrt(sq_int[i]) * R / L)
        codes = int(poc[i]), int(status_all[i]), bool(outside[i]), float(margin[i])
        return SampledPose(poses[i].copy(), offsets[i, columns].copy(), *d, *codes)

    nearest = nearest_ball = nearest_suspect = suspect_least = None
    refined_poses = suspect_cleared = 0
    edges = np.zeros((2, 0), dtype=np.intp)
    if verdict != YES:
        box = ball = (0.0, 0.0)
        nearest = nearest_ball = pose_at(0)
        reason = f"the pose itself is {_describe(verdict, status)}"
    else:
        edges = _edges(U, steps, L // ((n - 1) // 2) if n_axis and 1 < n < RAY_POINTS else 0)
        lengths = np.linalg.norm(U[edges[1]] - U[edges[0]], axis=1) * (R / L)
        flagged = suspect_edges(edges, lengths, margin, good[edges].all(axis=0))
        edges, lengths = edges[:, flagged], lengths[flagged]
        ends = [sq_int[edges].min(0), inf_int[edges].max(0), inf_int[edges].min(0)]
        order = np.lexsort(ends)  # nearest first; on a shell before across one
        edges, lengths = edges[:, order], lengths[order]
        with single_threaded_blas(), warnings.catch_warnings():
            warnings.simplefilter("ignore", EquilibriumWarning)
            budget = max(poc.size, _MIN_RESAMPLED_EDGES * NEIGHBOURHOOD_REFINE_POINTS)
            still, least = _resample_edges(robot, poses, edges, lengths, margin, args, budget)
        refined_poses = int(least[0].shape[0] * NEIGHBOURHOOD_REFINE_POINTS)
        suspect_cleared = int(np.count_nonzero(~still))
        edges = edges[:, still]
        if edges.size:
            pair = sorted(edges[:, 0], key=lambda i: (inf_int[i], sq_int[i]))
            nearest_suspect = (pose_at(pair[0]), pose_at(pair[1]))
            first = int(np.flatnonzero(still)[0])
            if first < least[0].shape[0]:  # resampled: its least r_T, or a non-YES pose
                where, codes, r = least[0][first], least[1][first], least[2][first]
                dq = (where - natural)[columns]
                suspect_least = SampledPose(
                    where,
                    dq,
                    float(np.abs(dq / scale_k).max()),
                    float(np.linalg.norm(dq / scale_k)),
                    int(codes[0]),
                    int(codes[1]),
                    bool(np.any((where < lower - 1e-12) | (where > upper + 1e-12))),
                    float(r),
                )
        box, ball = (
            _radius(d, w, ~good, d[edges][:, w[edges].all(axis=0)], R / L, root)
            for d, w, root in ((inf_int, np.ones_like(good), False), (sq_int, in_ball, True))
        )
        box, ball = ((R, None) if lo is None else (lo, hi) for lo, hi in (box, ball))
        bad = np.flatnonzero(~good)
        if bad.size:
            nearest = pose_at(int(bad[np.lexsort((sq_int[bad], inf_int[bad]))[0]]))
        if np.any(in_ball[bad]):
            inside = bad[in_ball[bad]]
            nearest_ball = pose_at(int(inside[np.lexsort((inf_int[inside], sq_int[inside]))[0]]))
        by_poses = _radius(inf_int, good | ~good, ~good, np.zeros((2, 0), np.int64), R / L, False)
        if box[1] is None:
            reason = "every sampled pose in the box is YES and no edge is suspect"
        elif nearest is not None and by_poses[0] == box[0]:  # the poses alone stop it there
            reason = (
                f"the nearest non-YES sampled pose is {nearest.describe()} at "
                f"{nearest.distance_box:.3g} (inf-norm)"
            )
        else:
            every = "; every sampled pose is YES" if good.all() else ""
            falls = "r_T comes within one step's change of 0"
            if suspect_least is not None and suspect_least.verdict != YES:
                falls = f"a {suspect_least.describe()} pose lies"
            elif suspect_least is not None:
                falls = (
                    f"r_T falls to {suspect_least.margin:.3g} "
                    f"{reach_unit(robot.output_units)}, still within one step's change of 0,"
                )
            reason = (
                f"{falls} between the sampled poses at "
                + " and ".join(f"{p.distance_box:.3g}" for p in nearest_suspect)
                + " (inf-norm), where a NO set thinner than the grid may pass (an estimate "
                f"from r_T's sampled slopes, not a proof{every})"
            )
    codes = status_all.tolist()
    return Neighbourhood(
        model_name=robot.spec.path.name,
        pose_name=pose_name,
        natural=natural,
        coordinate_names=tuple(robot.coordinate_names),
        coordinates=tuple(robot.coordinate_names[i] for i in columns),
        units=tuple(coordinate_units(robot.model)[i] for i in columns),
        scale=scale_k,
        radius=R,
        points=n,
        step=2 * R * scale_k / (n - 1) if n > 1 else np.full(k, np.nan),
        axis_rays=n_axis,
        corner_rays=n_corner,
        ray_points=(RAY_POINTS - 1) // 2 if with_rays else 0,
        n_poses=int(poc.size),
        verdict=verdict,
        status=status,
        box_radius=box[0],
        box_bracket=box,
        ball_radius=ball[0],
        ball_bracket=ball,
        whole_box_yes=bool(verdict == YES and good.all() and not edges.size),
        nearest=nearest,
        nearest_ball=nearest_ball,
        suspect_edges=int(edges.shape[1]),
        nearest_suspect=nearest_suspect,
        reach=reach,
        counts={name: int(np.count_nonzero(poc == c)) for name, c in VERDICT_CODES.items()},
        status_counts={
            STATUS_LABELS[c]: codes.count(c) for c in STATUS_CODES.values() if c in codes
        },
        outside_limits=int(np.count_nonzero(outside)),
        tension=setting,
        pretension=pretension,
        tol=tol,
        seconds=time.perf_counter() - started,
        reason=reason,
        margin_unit=reach_unit(robot.output_units),
        refined_poses=refined_poses,
        suspect_cleared=suspect_cleared,
        suspect_least=suspect_least,
    )


# ------------------------------------------------------- certified boxes


@dataclass(frozen=True)
class CertifiedNeighbourhood(TextRepr):
    """The largest box around a pose on which POC is proven
    (:func:`certified_neighbourhood`): every pose of the box, not only
    sampled ones, is POC.

    Printing it gives a short summary; :func:`cdpm.text.regions.certified_neighbourhood_lines`
    gives the report's lines and :func:`cdpm.text.regions.certified_neighbourhood_json`
    its JSON data.

    Attributes:
        model_name: name of the spec file.
        pose_name: name of the pose, or None for an explicit q.
        natural: natural coordinates of the pose (nv,) [rad or m].
        coordinate_names: names of all nv natural coordinates.
        coordinates: the varied coordinates (the box's sides), robot order.
        radius: R, the largest half-width tried [rad or m].
        half_width: h, the largest half-width proven (0 when none is):
            the box is ``natural +- h`` along the varied coordinates (clipped
            to the joint limits).
        lower, upper: that box (nv,) [rad or m]; the pose itself when none
            is proven.
        clipped: the box was clipped to the joint limits (not centred).
        verdict: YES when a box is proven; else NO (the smallest box tried
            is proven NO) or MARGINAL (undecided), cdpm's codes.
        margin_lower: a lower bound [margin_unit] of the reach margin r_T on
            the box (within ``horizon`` and ``tension_budget``); NaN if none.
        margin_unit: the unit of ``margin_lower``.
        horizon: T [s] of that bound; tension_budget: its budget [N].
        unproven: the least half-width tried that was not proven (the
            bracket's upper end), or None when R itself is proven.
        boxes_tried: boxes certified in the search.
        reason: the proof's or the failure's reason, in words.
    """

    model_name: str
    pose_name: str | None
    natural: np.ndarray
    coordinate_names: tuple[str, ...]
    coordinates: tuple[str, ...]
    radius: float
    half_width: float
    lower: np.ndarray
    upper: np.ndarray
    clipped: bool
    verdict: int
    margin_lower: float
    margin_unit: str
    horizon: float
    tension_budget: float
    unproven: float | None
    boxes_tried: int
    reason: str

    @property
    def proven(self) -> bool:
        """A box of positive half-width is proven POC YES."""
        return self.verdict == YES and self.half_width > 0

    def __str__(self) -> str:
        # a summary; cdpm.text.regions.certified_neighbourhood_lines gives the report's lines
        where = f"pose {self.pose_name!r}" if self.pose_name else "the given q"
        head = f"certified POC box around {where} ({self.model_name})"
        if not self.proven:
            return f"{head}: none proven within {self.radius:.4g}: {self.reason}"
        return (
            f"{head}: half-width {self.half_width:.4g} (of at most {self.radius:.4g}); "
            f"r_T >= {self.margin_lower:.4g} {self.margin_unit} on it"
        )


def certified_neighbourhood(
    robot: CableRobot | str | os.PathLike,
    q: Any,
    radius: Any,
    *,
    coordinates: Sequence[str] | None = None,
    horizon: Any = None,
    tension_budget: Any = None,
    pose_name: str | None = None,
) -> CertifiedNeighbourhood:
    """The largest box ``q +- h`` (h <= radius, along every varied
    coordinate) on which POC YES is proven by
    :func:`cdpm.certify.box.certify_boxes`: every pose of it is POC.

    The half-width is found by bisection without a loop of single boxes:
    one batch of half-widths ``R 2^(-j / 2)`` (j = 0 ..
    CERTIFIED_NEIGHBOURHOOD_HALVINGS) brackets it between the largest proven
    and the next larger one; then two batches of
    CERTIFIED_NEIGHBOURHOOD_REFINE half-widths evenly inside the bracket
    narrow it. A larger box holds the smaller ones, so a proven box
    proves every box inside it; the search reports the largest proven.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` or the path of its cable spec.
        q: a pose name, a configuration (nq,) or natural coordinates (nv,).
        radius: R > 0 [rad or m], the largest half-width tried (a number
            or an expression such as ``"pi/20"``).
        coordinates: the coordinates to vary (default all nv); the others
            stay at q.
        horizon, tension_budget: of the reach-margin bound (as
            :func:`cdpm.certify_box`).
        pose_name: the pose's name in the result (default q when a name).

    Returns:
        :class:`CertifiedNeighbourhood` (``proven`` False, with the reason,
        for a robot outside the certified case, e.g. under load or with a
        joint type certified boxes do not support, or a pose with no
        provable box).

    Raises:
        InputError: a bad radius, coordinates or pose.
    """
    # loaded on first use
    from cdpm.certify.subdivide import certify_cells

    robot = robot if isinstance(robot, CableRobot) else load_robot(robot)
    R = _check_radius(radius)
    columns = _check_coordinates(robot, coordinates)
    pose_name = q if pose_name is None and isinstance(q, str) else pose_name
    natural = np.asarray(robot.to_natural(robot.as_q(q)), dtype=float)
    low, high = coordinate_limits(robot.model)
    reach = reach_settings(robot, horizon, tension_budget)
    unit = reach_unit(robot.output_units)

    def boxes(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lo = np.tile(natural, (h.size, 1))
        hi = lo.copy()
        lo[:, columns] -= h[:, None]
        hi[:, columns] += h[:, None]
        return np.maximum(lo, low), np.minimum(hi, high)

    def result(h, lo, hi, verdict, margin, unproven, tried, reason):
        return CertifiedNeighbourhood(
            model_name=robot.spec.path.name,
            pose_name=pose_name,
            natural=natural.copy(),
            coordinate_names=tuple(robot.coordinate_names),
            coordinates=tuple(robot.coordinate_names[i] for i in columns),
            radius=R,
            half_width=float(h),
            lower=lo,
            upper=hi,
            clipped=bool(np.any(lo[columns] > natural[columns] - h))
            or bool(np.any(hi[columns] < natural[columns] + h)),
            verdict=int(verdict),
            margin_lower=float(margin),
            margin_unit=unit,
            horizon=float(reach.horizon),
            tension_budget=float(reach.tension_budget),
            unproven=unproven,
            boxes_tried=tried,
            reason=reason,
        )

    outside = np.flatnonzero((natural < low) | (natural > high))
    if outside.size:
        name = robot.coordinate_names[int(outside[0])]
        raise InputError(f"the pose is outside the joint limits of {name}: no box to certify")
    k = len(columns)
    # pieces per box at most about CERTIFIED_NEIGHBOURHOOD_PIECES: bisections per side
    depth = max(int(math.log2(CERTIFIED_NEIGHBOURHOOD_PIECES) // k), 0)
    fraction = 2.0**-depth

    def prove(h: np.ndarray):
        """Each box q +- h, bisected while undecided down to ``fraction``
        of its side (:func:`cdpm.certify.subdivide.certify_cells`): (proven
        (n,), r_T lower bound (n,), pieces (n,), reason (n,), NO (n,), lo,
        hi)."""
        lo, hi = boxes(h)
        out = (np.zeros(h.size, bool), np.full(h.size, np.nan), np.zeros(h.size, int))
        reasons, no = [""] * h.size, np.zeros(h.size, bool)
        for i in range(h.size):
            widths = np.maximum(2.0 * h[i], np.finfo(float).tiny) * np.ones(k)
            pieces, _ = certify_cells(
                robot,
                natural,
                columns,
                lo[i : i + 1, columns],
                hi[i : i + 1, columns],
                widths,
                fraction,
                reach,
            )
            verdict = np.asarray(pieces.verdict)
            out[0][i] = bool(np.all(verdict == YES))
            out[2][i] = verdict.size
            if out[0][i]:
                out[1][i] = float(np.min(pieces.margin_lower))
                reasons[i] = (
                    f"proven POC YES on each of {verdict.size} box(es) that tile it"
                    if verdict.size > 1
                    else str(pieces.reason[0])
                )
            else:
                bad = int(np.flatnonzero(verdict != YES)[0])
                no[i] = bool(np.any(verdict == NO))
                reasons[i] = str(pieces.reason[bad])
        return (*out, np.array(reasons, dtype=object), no, lo, hi)

    h = R * 2.0 ** (-np.arange(CERTIFIED_NEIGHBOURHOOD_HALVINGS + 1) / 2.0)
    # the halvings from R down until one is proven (the smaller ones are inside it)
    tried, best, found = 0, -1, None
    for start in range(0, h.size, CERTIFIED_NEIGHBOURHOOD_REFINE):
        part = h[start : start + CERTIFIED_NEIGHBOURHOOD_REFINE]
        try:
            found = prove(part)
        except InputError as exc:  # a joint type certified boxes do not support
            return result(0.0, natural, natural, MARGINAL, math.nan, R, tried, str(exc))
        tried += int(found[2].sum())
        ok = np.flatnonzero(found[0])
        if ok.size:
            best = start + int(ok[0])
            break
    if best < 0:
        last = found[3].size - 1  # the smallest box: what holds it back
        reason = str(found[3][last])
        verdict = MARGINAL
        if found[4][last]:
            verdict = NO
            reason = f"a NO box lies within {h[-1]:.3g} of the pose: {reason}"
        return result(0.0, natural, natural, verdict, math.nan, float(h[-1]), tried, reason)
    j = best - start
    h_yes, h_no = float(h[best]), (float(h[best - 1]) if best > 0 else None)
    chosen = (found[5][j], found[6][j], float(found[1][j]), str(found[3][j]))
    for _ in range(2):
        if h_no is None:
            break
        inner = np.linspace(h_yes, h_no, CERTIFIED_NEIGHBOURHOOD_REFINE + 2)[1:-1]
        refined = prove(inner)
        tried += int(refined[2].sum())
        ok = np.flatnonzero(refined[0])
        if ok.size:
            i = int(ok[-1])  # the largest proven
            h_yes = float(inner[i])
            chosen = (refined[5][i], refined[6][i], float(refined[1][i]), str(refined[3][i]))
        larger = np.flatnonzero(~refined[0] & (inner > h_yes))
        if larger.size:
            h_no = float(inner[larger[0]])
    return result(h_yes, chosen[0], chosen[1], YES, chosen[2], h_no, tried, chosen[3])
