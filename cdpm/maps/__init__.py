"""Workspace maps: verdicts at many poses, stored, resumable, parallel.

:func:`workspace_map` sweeps a robot over a grid (or random samples) of
natural coordinates, decides at every pose positive output controllability
(seed paper Theorem 1) next to the classic cable-robot criteria, and returns
an ``xarray.Dataset`` whose pose dimensions are named after the coordinates.
With ``store=`` the map is written chunk by chunk into a zarr store, and a
run that was interrupted resumes where it stopped. See docs/maps.md.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from typing import Any

from cdpm.errors import InputError
from cdpm.maps._evaluate import STATUS_CODES, VERDICT_CODES, evaluate_poses, resolve_tension
from cdpm.maps._plan import DEFAULT_CHUNK_SIZE, SampledAxes, sample_axes
from cdpm.maps._store import open_map

__all__ = [
    "workspace_map",
    "sample_axes",
    "SampledAxes",
    "open_map",
    "evaluate_poses",
    "VERDICT_CODES",
    "STATUS_CODES",
]

#: chunk size when poses need the analyser's per-pose decision (under load:
#: milliseconds per pose, so small chunks keep progress, interruption and
#: the spread over workers responsive)
PER_POSE_CHUNK_SIZE = 64


def workspace_map(
    robot,
    axes: Mapping[str, Any] | SampledAxes,
    base: Any = None,
    tension: Any = None,
    *,
    samples: int | None = None,
    seed: int | None = 0,
    workers: int | None = None,
    scheduler: Any = None,
    store: str | os.PathLike | None = None,
    overwrite: bool = False,
    chunk_size: int | None = None,
    progress: bool | Callable[[int, int, int], None] = False,
    margin: bool = True,
):
    """Map positive output controllability and classic criteria over poses.

    Args:
        robot: a :class:`~cdpm.robot.CableRobot` or the path of its cable spec.
        axes: coordinate name (see ``robot.coordinate_names``: joints, or
            ``root.x`` style free-flyer coordinates) -> values [rad or m]
            for a grid, e.g. ``{"q1": np.linspace(-3.14, 3.14, 181)}``; or
            :func:`sample_axes` for random poses; or, with ``samples=N``,
            coordinate -> (low, high) ranges to sample.
        base: the pose of the coordinates not on an axis: a pose name, a
            configuration, natural coordinates or ``{coordinate: value}``;
            default the spec's first named pose (else neutral).
        tension: equilibrium tension: None (the spec's method), a method
            name (``zero``, ``min_norm``, ``pretension``) or tensions [N] (m,).
        samples: draw this many random poses uniformly in the ``axes`` ranges.
        seed: random seed for ``samples``.
        workers: local processes computing chunks, this one included
            (``workers - 1`` worker processes are started); default one per
            CPU (at most one per chunk); 1 runs in this process only.
        scheduler: address ``"tcp://host:port"`` of a Dask distributed
            scheduler (or a ``distributed.Client``) to run the chunks on.
        store: path of a zarr store to write chunk by chunk; an existing
            store made with the same settings is resumed (only chunks not
            yet done are computed). None keeps the map in memory.
        overwrite: replace an existing ``store`` instead of resuming it.
        chunk_size: poses per chunk (default 16384; 64 when poses need the
            analyser per pose, e.g. under gravity).
        progress: True prints a progress bar on stderr; a callable is called
            as ``progress(done_poses, total_poses, chunk_index)``.
        margin: compute the POC margin (``poc_margin``). Under load it is
            most of the cost of a pose; ``False`` leaves it NaN and decides
            poses whose taut cables alone reach every output direction
            without the analyser (same verdicts, several times faster).

    Returns:
        ``xarray.Dataset`` with dims the axis names (grid) or ``sample``, and
        variables ``poc``, ``poc_margin``, ``output_controllable``,
        ``positive_controllable``, ``wrench_closure``, ``static_feasible``
        (int8 codes, see :data:`VERDICT_CODES`), ``tension_min``,
        ``tension_max`` [N], ``y`` (..., output) [m],
        ``output_frame_position`` (..., xyz) [m] and ``status`` (see
        :data:`STATUS_CODES`); provenance in ``attrs``. From a store the
        dataset is lazily loaded.

    Raises:
        InputError: unknown coordinates, bad values, or a ``store`` made
            with other settings (the message names the differences).
    """
    from cdpm import __version__
    from cdpm.maps._evaluate import _zero_equilibrium
    from cdpm.maps._plan import make_plan
    from cdpm.maps._runner import ProgressPrinter, run_chunks
    from cdpm.maps._store import MemorySink, ZarrSink
    from cdpm.robot import CableRobot, load_robot

    if not isinstance(robot, CableRobot):
        robot = load_robot(robot)
    if samples is not None:
        if isinstance(axes, SampledAxes):
            raise InputError("give either samples=N with ranges, or sample_axes(...), not both")
        axes = sample_axes(axes, samples, seed)
    setting = resolve_tension(robot, tension)
    if chunk_size is None:
        fast = _zero_equilibrium(robot, setting)
        chunk_size = DEFAULT_CHUNK_SIZE if fast else PER_POSE_CHUNK_SIZE
    plan = make_plan(robot, axes, base, setting, chunk_size, __version__, margin)
    if workers is None:
        workers = os.cpu_count() or 1
    if not isinstance(workers, int) or workers < 1:
        raise InputError(f"workers must be a positive integer, got {workers!r}")
    sink = MemorySink(robot, plan) if store is None else ZarrSink(store, robot, plan, overwrite)
    done = sink.done()
    todo = [k for k in range(plan.n_chunks) if k not in done]
    if progress is True:
        progress = ProgressPrinter(sum(plan.chunk_size(k) for k in todo))
    elif progress is False:
        progress = None
    job = (setting, bool(margin))
    run_chunks(robot, plan, job, todo, sink, workers, scheduler, progress)
    return sink.dataset()
