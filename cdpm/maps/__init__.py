"""Workspace maps: verdicts at many poses, stored, resumable, parallel.

:func:`workspace_map` sweeps a robot over a grid (or random samples) of
natural coordinates, decides at every pose positive output controllability
(seed paper Theorem 1) next to the classic cable-robot criteria, and returns
an ``xarray.Dataset`` whose pose dimensions are named after the coordinates.
With ``store=`` the map is written chunk by chunk into a zarr store, and a
run that was interrupted resumes where it stopped. See docs/maps.md.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import warnings
from collections.abc import Callable, Mapping
from contextlib import nullcontext
from typing import Any

import numpy as np
from numpy import bool_

from cdpm._version import __version__
from cdpm.dynamics.reach import reach_settings
from cdpm.dynamics.tension_choice.search import tension_search
from cdpm.errors import InputError, is_integer
from cdpm.maps._dask import check_scheduler_address
from cdpm.maps._lock import store_lock
from cdpm.maps._progress import MapRunInfo, ProgressPrinter
from cdpm.maps._runner import interrupts_held, run_chunks
from cdpm.maps._store import (
    RESULT_IN_MEMORY_MAX,
    MemorySink,
    StoreSettingsError,
    ZarrSink,
    open_map,
    store_path_problem,
)
from cdpm.maps._workers import RobotSource, prestart_workers, unimportable_main
from cdpm.maps.plan import (
    DEFAULT_CHUNK_SIZE,
    IN_MEMORY_MAX,
    MAX_MAP_POSES,
    SampledAxes,
    make_plan,
    override_robot,
    sample_axes,
)
from cdpm.maps.regions import attach_new_regions
from cdpm.model.robot import CableRobot, load_robot
from cdpm.numerics import SPAN_TOL
from cdpm.pipeline.criteria import bytes_per_pose
from cdpm.pipeline.evaluate import (
    STATUS_CODES,
    VERDICT_CODES,
    MapJob,
    check_tol,
    evaluate_poses,
    resolve_tension,
    zero_equilibrium,
)

__all__ = [
    "workspace_map",
    "sample_axes",
    "SampledAxes",
    "open_map",
    "StoreSettingsError",
    "override_robot",
    "MapRunInfo",
    "evaluate_poses",
    "VERDICT_CODES",
    "STATUS_CODES",
    "RESULT_IN_MEMORY_MAX",
    "store_path_problem",
    "check_scheduler_address",
    "interrupts_held",
]


#: most points one grid axis may have
MAX_AXIS_POINTS = 10**7

#: most local processes a map starts by default (more cores than this
#: rarely pay off against the chunks' writing, and a default should not
#: fill a shared many-core machine)
DEFAULT_MAX_WORKERS = 16

#: largest chunk when poses go through the analyser (under load: tens to
#: hundreds of microseconds per pose): writing a chunk costs about 10 ms
#: whatever its size (a file per variable), and a chunk of this size 0.1 to
#: 2 s
PER_POSE_CHUNK_SIZE = 4096

#: smallest default chunk under load: a map of up to 2048 poses is one
#: chunk (a tenth of a second on the cheaper models, less than a worker
#: process takes to start, so a second chunk would only add its writing);
#: smaller chunks would spend as long writing as computing on those models
MIN_PER_POSE_CHUNK_SIZE = 2048

#: chunk size of maps with the tension search (``tension="best"``: tens of
#: LPs and candidate analyses per pose, 0.03 to 1 s a pose)
TENSION_SEARCH_CHUNK_SIZE = 64


def _per_pose_chunk_size(n_poses: int) -> int:
    """Chunk size under load: a thirty-second of the map (so that progress
    and the spread over workers stay even: two processes end at most about
    a chunk apart), rounded up to a multiple of 512 and kept within
    MIN_PER_POSE_CHUNK_SIZE and PER_POSE_CHUNK_SIZE."""
    share = 512 * -(-n_poses // (32 * 512))
    return int(min(PER_POSE_CHUNK_SIZE, max(MIN_PER_POSE_CHUNK_SIZE, share)))


def workspace_map(
    robot: CableRobot | str | os.PathLike,
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
    tol: float = SPAN_TOL,
    horizon: Any = None,
    tension_budget: Any = None,
    pretension: float | None = None,
    announce: Callable[[MapRunInfo], None] | None = None,
    tension_objective: str = "poc",
):
    """Map positive output controllability and classic criteria over poses.

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot` or the path of its cable spec.
        axes: coordinate name (see ``robot.coordinate_names``: joints, or
            ``<joint>.x`` ... ``<joint>.yaw`` for a free-flyer) -> values [rad or m]
            for a grid, e.g. ``{"q1": np.linspace(-3.14, 3.14, 181)}``; or
            :func:`sample_axes` for random poses; or, with ``samples=N``,
            coordinate -> (low, high) ranges to sample.
        base: the pose of the coordinates not on an axis: a pose name, a
            configuration, natural coordinates or ``{coordinate: value}``;
            default the spec's first named pose (else neutral).
        tension: equilibrium tension: None (the spec's method), a method
            name (``zero``, ``min_norm``, ``pretension``) or tensions [N] (m,);
            or ``"best"``: the spec's method, and beside its verdicts the
            search over the feasible equilibrium tensions at every pose
            (:func:`cdpm.dynamics.tension_choice.best_tension_batch`: variables
            ``poc_some_tension``, ``reach_margin_best``, ``tension_best``,
            which other maps leave NOT_ANALYSED / NaN). Other gravity or tension bounds: map
            ``cdpm.maps.override_robot(robot, gravity=..., tension_bounds=...)``.
        samples: draw this many random poses uniformly in the ``axes`` ranges.
        seed: random seed for ``samples``.
        workers: local processes computing chunks, this one included
            (``workers - 1`` worker processes are started); default one per
            CPU this process may use, at most DEFAULT_MAX_WORKERS = 16 (and at
            most one per chunk); 1 runs in this process only. Worker
            processes run the main script again, so a script calling this
            outside ``if __name__ == "__main__":`` (or piped on stdin) runs
            the map in this process only, with a warning saying so.
        scheduler: address ``"tcp://host:port"`` of a Dask distributed
            scheduler (or a ``distributed.Client``) to run the chunks on
            (its workers compute them: give no ``workers`` with it).
        store: path of a zarr store (a directory, ``*.zarr`` by convention,
            not an image or other file name) to write chunk by chunk; an
            existing store made with the same settings is resumed (only
            chunks not yet done are computed). None keeps the map in memory.
        overwrite: replace an existing ``store`` instead of resuming it.
        chunk_size: poses per chunk (default 16384; under load, when poses
            go through the analyser, a thirty-second of the map within 2048
            and 4096).
        progress: True prints what runs where (see ``announce``) and a
            progress bar on stderr; a callable is called as
            ``progress(done_poses, total_poses, chunk_index)``.
        margin: compute the reach margin (``reach_margin``); ``False``
            leaves it NaN (same verdicts, faster).
        tol: angle-like tolerance of the span decisions, as in
            :func:`cdpm.positive_output_controllability` (stored with the map).
        horizon: T [s] of the reach margin, one for every pose; default
            the model's (:func:`cdpm.dynamics.reach.reach_settings`; stored in the
            map's ``reach_horizon`` attribute).
        tension_budget: tension increase [N] above equilibrium allowed to
            cables without an upper bound in the reach margin; default the
            model's (attribute ``tension_budget``).
        pretension: least tension [N] of every cable for the ``pretension``
            method (default: the spec's ``equilibrium.pretension``); only
            with that method. Stored in the settings (a resume compares it).
        tension_objective: the search's objective with ``tension="best"``:
            ``"poc"`` or ``"margin"`` (:func:`cdpm.dynamics.tension_choice.best_tension`).
        announce: called once before the chunks run with a
            :class:`MapRunInfo`: chunks already in the
            store, chunks to compute, and where they run (``.lines()`` says
            it in words).

    Returns:
        ``xarray.Dataset`` with dims the axis names (grid) or ``sample``, and
        variables ``poc``, ``reach_margin`` [m] (and its error bound
        ``reach_margin_error``), ``output_controllable``,
        ``positive_controllable``, ``wrench_closure``, ``static_feasible``
        (int8 codes, see :data:`VERDICT_CODES`), ``tension_min``,
        ``tension_max`` [N], ``y`` (..., output) [m],
        ``output_frame_position`` (..., xyz) [m] and ``status`` (see
        :data:`STATUS_CODES`); provenance in ``attrs``. With a ``store``,
        the dataset :func:`open_map` reads (values, coordinates, attributes,
        ``encoding["source"]``): lazily loaded from the store, except a map
        of at most :data:`RESULT_IN_MEMORY_MAX` bytes (64 MiB) whose every
        chunk this process computed, which is returned from memory (its
        variables without the store's chunk and codec encoding).

    Raises:
        InputError: unknown coordinates or bad values; ``workers`` with
            ``scheduler``; ``pretension`` with a method other than
            ``pretension``; a ``store`` named like an image or other file.
        StoreSettingsError: ``store`` holds a map made with other settings
            (an InputError; the message names each difference).
    """

    _refuse_in_worker_bootstrap()
    _check_executor(workers, scheduler)

    if progress is None or isinstance(progress, bool_):
        progress = bool(progress)
    if not (isinstance(progress, bool) or callable(progress)):
        raise InputError(
            "progress must be True (a progress bar on stderr), False (or None) or a callable "
            f"progress(done_poses, total_poses, chunk_index), got {progress!r}"
        )
    if announce is not None and not callable(announce):
        raise InputError(f"announce must be a callable announce(info) or None, got {announce!r}")
    if store is not None and store_path_problem(store):
        name = os.fspath(store)
        raise InputError(
            f"store {name!r} is named like {store_path_problem(store)}, but a map store is a "
            f"zarr directory: name it e.g. {os.path.splitext(name)[0]}.zarr, and draw an image "
            "from the map with cdpm.plotting.save_map_plot(ds, path)"
        )
    # set-up: loading the model and the imports a map needs; an interrupt
    # waits for it (one inside an import broke it: interrupts_held)
    with interrupts_held():
        if not isinstance(robot, CableRobot):
            robot = load_robot(robot)
        if pretension is not None:
            _check_pretension_method(robot, tension, pretension)
            robot = override_robot(robot, pretension=pretension)
        if samples is not None:
            if isinstance(axes, SampledAxes):
                raise InputError("give either samples=N with ranges, or sample_axes(...), not both")
            axes = sample_axes(axes, samples, seed)
        n_poses = _n_poses(axes)
        if n_poses > MAX_MAP_POSES:
            raise InputError(
                f"a map of {n_poses:,} poses is more than the {MAX_MAP_POSES:,} one map may have; "
                "use fewer points per axis, or split the map into several"
            )
        search = None
        if isinstance(tension, str) and tension == "best":
            search = tension_search(tension_objective)
            tension = None
        elif tension_objective != "poc":
            raise InputError(
                f"tension_objective={tension_objective!r} applies to the tension search: pass "
                "tension='best', or leave out tension_objective"
            )
        setting = resolve_tension(robot, tension)
        if chunk_size is None and search is not None:
            chunk_size = TENSION_SEARCH_CHUNK_SIZE
        loaded = not zero_equilibrium(robot, setting)  # poses go through the analyser
        if chunk_size is None:
            chunk_size = _per_pose_chunk_size(_n_poses(axes)) if loaded else DEFAULT_CHUNK_SIZE
        tol = check_tol(tol)
        reach = reach_settings(robot, horizon, tension_budget) if margin else None
        source = RobotSource.from_robot(robot)  # with the robot's departures from its spec
        searched = None
        if search is not None:
            used = reach_settings(robot, horizon, tension_budget)
            searched = {
                **search.as_dict(),
                "reach_horizon": used.horizon,
                "tension_budget": used.tension_budget,
            }
        plan = make_plan(
            robot,
            axes,
            base,
            setting,
            chunk_size,
            __version__,
            margin,
            tol,
            reach,
            source.overrides,
            tension_search=searched,
        )
        if store is None:
            _check_in_memory_size(robot, plan)
        if workers is None:
            workers = default_workers()
        if not is_integer(workers) or workers < 1:
            raise InputError(f"workers must be a positive integer, got {workers!r}")
        if scheduler is None and workers > 1 and (why := unimportable_main()) is not None:
            warnings.warn(f"workspace_map runs with workers=1, not {workers}: {why}", stacklevel=2)
            workers = 1
        if scheduler is None and workers > 1:
            # their start-up overlaps the store's creation
            prestart_workers(kernels=loaded)
    # one run per store: a second run on a busy store refuses before touching it
    owner = nullcontext() if store is None else store_lock(store)
    with owner:
        sink = None
        try:
            with interrupts_held():  # zarr's import, the store's first files
                if store is None:
                    sink = MemorySink(robot, plan)
                else:
                    sink = ZarrSink(store, robot, plan, overwrite)
            done = sink.done()
            todo = [k for k in range(plan.n_chunks) if k not in done]
            if store is not None and scheduler is None and workers > 1 and len(todo) > 1:
                sink.keep = False  # worker processes write chunks this one never holds
            if progress is True:
                if announce is None:
                    announce = _print_to_stderr
                progress = ProgressPrinter(sum(plan.chunk_size(k) for k in todo)) if todo else None
            elif progress is False:
                progress = None
            job = MapJob(
                setting,
                bool(margin),
                float(tol),
                tuple(plan.settings["variables"]),
                reach,
                None
                if search is None
                else (search, reach_settings(robot, horizon, tension_budget)),
            )
            run_chunks(robot, plan, job, todo, sink, workers, scheduler, progress, announce, source)
            # a store this run did not create is read back (sink.dataset)
            read = store is not None and sink.group is None
            return attach_new_regions(sink.dataset(), store, sink.group, read_from_store=read)
        except KeyboardInterrupt as exc:
            if isinstance(progress, ProgressPrinter):
                progress.stopped()
            if store is not None and sink is not None:  # the store this run opened
                exc.map_store = str(sink.path)  # its chunks kept
            raise
        finally:
            if sink is not None:
                sink.close()  # the store's files written, under its lock


def _print_to_stderr(info: MapRunInfo) -> None:
    for line in info.lines():
        print(line, file=sys.stderr)


def _check_executor(workers: Any, scheduler: Any) -> None:
    """``workers`` counts local processes: with a Dask scheduler its
    workers compute the chunks, and a ``workers`` given too would be
    ignored."""
    if scheduler is not None and workers is not None:
        raise InputError(
            f"workers={workers!r} counts local processes, and with scheduler= the Dask "
            "cluster's workers compute the chunks: leave out workers (add Dask workers with "
            "`dask worker ADDRESS`), or leave out scheduler to run locally"
        )
    if isinstance(scheduler, str):
        check_scheduler_address(scheduler)  # before the store is created


def _check_pretension_method(robot: CableRobot, tension: Any, pretension: Any) -> None:
    """A pretension only means something for the ``pretension`` method."""
    if tension is None or (isinstance(tension, str) and tension == "best"):
        method = str(robot.spec.equilibrium_method)
    else:
        method = tension if isinstance(tension, str) else "given tensions"
    if method != "pretension":
        raise InputError(
            f"pretension={pretension!r} applies only to the 'pretension' method, and this map "
            f"uses {method!r}: pass tension='pretension', or leave out pretension"
        )


def _refuse_in_worker_bootstrap() -> None:
    """Refuse to run while a worker process imports the main script.

    Local workers start like Python's ``spawn``: each imports the calling
    script as a module, so a script calling :func:`workspace_map` at its
    top level would run the map again in every worker (replacing the store
    being written).
    """

    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise InputError(
            "workspace_map was called while a worker process was importing the main script: "
            "with workers > 1, put the script's map call under "
            '`if __name__ == "__main__":` (local workers import the script), or pass workers=1'
        )


def _n_poses(axes) -> int:
    """Number of poses of ``axes`` (a grid's product, or the samples)."""

    if isinstance(axes, SampledAxes):
        return int(axes.n)
    try:
        return int(np.prod([np.size(v) for v in axes.values()]))
    except (AttributeError, TypeError, ValueError):
        return 1  # make_plan explains what is wrong with the axes (ragged ones too)


def default_workers() -> int:
    """The default number of local processes of a map: one per CPU this
    process may run on (its affinity, which containers and ``taskset``
    limit), at most DEFAULT_MAX_WORKERS."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, DEFAULT_MAX_WORKERS))


def _check_in_memory_size(robot: CableRobot, plan) -> None:
    """Refuse an in-memory map larger than IN_MEMORY_MAX before any work."""

    n = int(np.prod(plan.shape))
    per_pose = bytes_per_pose(robot)
    if n * per_pose > IN_MEMORY_MAX:
        raise InputError(
            f"a map of {n:,} poses needs about {n * per_pose / 1024**3:.1f} GiB in memory; "
            "write it to a store (store=..., CLI --out STORE), which keeps memory bounded by "
            "the chunk size, or map fewer poses"
        )
