"""Evaluate every map quantity at a batch of poses: the one pipeline.

:func:`evaluate_poses` is what one map chunk runs and what
:func:`cdpm.analyze_pose` runs on a batch of one. Each stage takes the
whole batch and hands the next arrays with a leading pose axis:

1. kinematics, M and G: :meth:`cdpm.model.robot.CableRobot.kinematics_batch`
   (one Pinocchio pass per pose);
2. wrench closure (:func:`cdpm.analysis.batch.positively_spanning`);
3. equilibrium tensions by the setting's method
   (:func:`cdpm.dynamics.equilibrium.equilibrium_tensions`) and static feasibility;
4. linearisations (:func:`cdpm.dynamics.linearisation.linearise_batch`);
5. the analysis (:func:`cdpm.analysis.batch.analyse_systems`: vectorised
   exits, the per-system analyser for the rest);
6. the registered criteria (:mod:`cdpm.pipeline.criteria`) read the stages'
   results into the map's variables.

Degenerate poses never raise: they get a ``status`` code and the verdicts
``NOT_ANALYSED``.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import platform
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

import cdpm.pipeline.tension_criteria  # noqa: F401  (registers the tension search's criteria)
from cdpm.dynamics.equilibrium import (
    EQUILIBRIUM_METHODS,
    EquilibriumWarning,
    checked_tensions,
    equilibrium_tensions,
    statics,
)
from cdpm.dynamics.linearisation import linearise_batch, mass_inverse
from cdpm.dynamics.reach import ReachSettings, reach_settings
from cdpm.errors import InputError, check_tol
from cdpm.model.poses import check_poses, configurations
from cdpm.numerics import MIN_SEGMENT_LENGTH, SPAN_TOL
from cdpm.pipeline.criteria import CRITERIA, PoseBatch, missing_criteria_error
from cdpm.verdicts import NO, NOT_ANALYSED, STATUS_CODES, VERDICT_CODES, YES

if TYPE_CHECKING:  # pragma: no cover
    from cdpm.model.robot import CableRobot

__all__ = [
    "MapJob",
    "VERDICT_CODES",
    "STATUS_CODES",
    "evaluate_poses",
    "evaluate_batch",
    "resolve_tension",
    "zero_equilibrium",
    "check_tol",
    "check_poses",
    "EVALUATE_BLOCK",
]

#: most poses :func:`evaluate_poses` takes through the pipeline at once; more
#: go in blocks of this size. The pipeline's arrays grow with the batch: a
#: whole 16384-pose chunk of a 6-DOF model takes hundreds of MB of them,
#: which run slower than a block's (multilink_arm with the margin: about
#: 185 against 130 us a pose) besides holding the memory. Chunks under load
#: hold at most 4096 poses anyway.
EVALUATE_BLOCK = 4096

#: glibc's malloc thresholds while poses are evaluated [bytes]: blocks up to
#: HEAP_BLOCK_MAX come from its heap, and freed memory beyond
#: KEPT_FREE_MEMORY is returned to the system. They are the values glibc's
#: own adjustment grows to; left to it, they stay near the largest freed
#: array (a few MB), so the heap of a block's temporaries is returned and
#: faulted in again for every block (about 0.8 us a pose on the planar
#: model, and more on a busy host)
HEAP_BLOCK_MAX = 32 * 2**20
KEPT_FREE_MEMORY = 64 * 2**20


@functools.cache
def reuse_freed_memory() -> None:
    """Set glibc's malloc thresholds to HEAP_BLOCK_MAX and KEPT_FREE_MEMORY,
    once per process (a process-wide setting); nothing where the C library
    is not glibc (macOS, musl), whose allocators behave otherwise."""

    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # pragma: no cover - no glibc symbols
        return
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's <malloc.h>
    mallopt(m_mmap_threshold, HEAP_BLOCK_MAX)
    mallopt(m_trim_threshold, KEPT_FREE_MEMORY)


def single_threaded_blas():
    """A context limiting BLAS to one thread (threadpoolctl, when installed).

    Maps run a great many tiny linear-algebra calls, which a multithreaded
    BLAS only slows down (its threads spin between calls, and worker
    processes already use the cores). SciPy's own BLAS is loaded first so
    that the limit covers it too. The libraries are looked up once per
    process (a few milliseconds: every loaded library is inspected).
    """

    controller = _blas_controller()
    if controller is None:  # pragma: no cover - optional (the maps extra has it)
        return contextlib.nullcontext()
    return controller.limit(limits=1, user_api="blas")


@functools.cache
def _blas_controller():
    """threadpoolctl's view of this process's BLAS libraries, looked up
    once (None without threadpoolctl)."""
    import scipy.linalg  # noqa: F401 - load SciPy's BLAS before limiting it

    try:
        # optional: cdpm[maps]
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - optional (the maps extra has it)
        return None
    return ThreadpoolController()


def resolve_tension(robot: CableRobot, tension: Any) -> str | list[float]:
    """The equilibrium tension setting as plain data for provenance.

    ``None`` takes the spec's default method; a string names a method; a
    vector gives the tensions [N] (one per cable), checked against the
    bounds by :func:`~cdpm.dynamics.equilibrium.checked_tensions` (the rule
    of :func:`cdpm.linearise`: an entry beyond its bound by round-off is
    put on it, which the returned list has).

    Raises:
        InputError: an unknown method, or tensions that
            :func:`~cdpm.dynamics.equilibrium.checked_tensions` refuses.
    """

    if tension is None:
        tension = str(robot.spec.equilibrium_method)
    if isinstance(tension, str):
        if tension not in EQUILIBRIUM_METHODS:
            raise InputError(
                f"unknown equilibrium method {tension!r}; use one of "
                f"{', '.join(EQUILIBRIUM_METHODS)} or give tensions [N]"
            )
        if EQUILIBRIUM_METHODS[tension].uses_pretension and not robot.spec.pretension:
            warnings.warn(
                f"the {tension!r} method with the spec's pretension of 0 N is the 'min_norm' "
                "method; set equilibrium.pretension in the spec to keep every cable taut",
                EquilibriumWarning,
                stacklevel=3,
            )
        return tension
    # the one rule for given tensions (as cdpm.linearise): round-off beyond
    # a bound is on it, farther is an InputError
    f = checked_tensions(robot, tension)
    return [float(x) for x in f]


def zero_equilibrium(robot: CableRobot, setting) -> bool:
    """True when the equilibrium is f* = 0 at every pose with A^2 = 0: no
    gravity, external load or joint damping, every cable allowed to be
    slack (f_min = 0) and a method (or given tension) that then picks 0.
    Such maps cost little per pose (large chunks)."""
    if np.any(robot.gravity) or np.any(robot.external_wrench):
        return False
    if np.any(robot.joint_damping):
        return False
    if np.any(robot.tension_min != 0) or np.any(robot.tension_max <= 0):
        return False
    if isinstance(setting, str):
        box = EQUILIBRIUM_METHODS[setting].box
        pretension = float(robot.spec.pretension or 0.0)
        return box is None or not np.any(box(robot.tension_min, robot.tension_max, pretension)[0])
    return not any(setting)


@dataclass(frozen=True)
class MapJob:
    """What every chunk of a map computes (plain, picklable data).

    Attributes:
        tension: the tension setting (:func:`resolve_tension`).
        margin: compute the reach margin.
        tol: angle-like tolerance of the span decisions.
        variables: the map's variables (registered criteria).
        reach: horizon and tension budget of the reach margin, or None
            for the model's defaults.
        tension_search: the search over the feasible equilibrium tensions
            and the reach settings of its r_T, ``(TensionSearch,
            ReachSettings)`` (a map with ``tension="best"``), or None to
            skip it.
    """

    tension: str | list[float]
    margin: bool = True
    tol: float = SPAN_TOL
    variables: tuple[str, ...] = ()
    reach: ReachSettings | None = None
    tension_search: Any = None

    def evaluate(self, robot: CableRobot, natural: np.ndarray) -> dict[str, np.ndarray]:
        """:func:`evaluate_poses` of ``natural`` (N, nv) with these settings;
        raises a clear InputError when a map variable's criterion is not
        registered in this (worker) process."""

        error = missing_criteria_error(self.variables)
        if error is not None:
            raise error
        return evaluate_poses(
            robot,
            natural,
            self.tension,
            margin=self.margin,
            tol=self.tol,
            reach=self.reach,
            tension_search=self.tension_search,
        )


def evaluate_poses(
    robot: CableRobot,
    natural: np.ndarray,
    tension: Any = None,
    *,
    margin: bool = True,
    tol: float = SPAN_TOL,
    reach: Any = None,
    tension_search: Any = None,
) -> dict[str, np.ndarray]:
    """Every map quantity at the poses ``natural`` (N, nv natural coordinates).

    Args:
        robot: a :class:`~cdpm.model.robot.CableRobot`.
        natural: poses: natural coordinates, shape (N, nv) [rad or m]; or
            a sequence of poses, each natural coordinates (nv,), a pose
            name of the spec or ``{coordinate: value}`` (coordinates not
            named are 0); or one pose name or mapping.
        tension: equilibrium tension setting (see :func:`resolve_tension`).
        margin: compute the reach margin ``reach_margin`` (else NaN; see
            :func:`cdpm.workspace_map`).
        tol: angle-like tolerance of the span decisions (as in
            :func:`cdpm.positive_output_controllability`).
        reach: the reach margin's :class:`~cdpm.dynamics.reach.ReachSettings`, or
            None for the model's defaults.
        tension_search: a :class:`~cdpm.dynamics.tension_choice.search.TensionSearch`
            (or a pair of it and the :class:`~cdpm.dynamics.reach.ReachSettings` of
            its r_T, default ``reach``) to fill the tension search's criteria
            (``poc_some_tension``, ``reach_margin_best``, ``tension_best``),
            or None to leave them NOT_ANALYSED / NaN.

    Returns:
        dict: criterion name (:data:`cdpm.pipeline.criteria.CRITERIA`) -> array
        with leading dimension N.
    """
    natural = check_poses(robot, natural)
    reuse_freed_memory()
    kwargs = dict(margin=margin, tol=tol, reach=reach, tension_search=tension_search)
    parts = []
    for i in range(0, max(natural.shape[0], 1), EVALUATE_BLOCK):  # one block when empty
        batch = evaluate_batch(robot, natural[i : i + EVALUATE_BLOCK], tension, **kwargs)
        parts.append({name: c.compute(batch) for name, c in CRITERIA.items()})
    if len(parts) == 1:
        return parts[0]
    return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}


def evaluate_batch(
    robot: CableRobot,
    natural: np.ndarray,
    tension: Any = None,
    *,
    margin: bool = True,
    tol: float = SPAN_TOL,
    pretension: float | None = None,
    reach: Any = None,
    tension_search: Any = None,
) -> PoseBatch:
    """The pipeline's stages at N poses (module docstring), as a
    :class:`~cdpm.pipeline.criteria.PoseBatch` for the criteria to read."""
    # scipy: loaded on first use
    from cdpm.analysis.batch import analyse_systems, positively_spanning

    natural = check_poses(robot, natural)
    tol = check_tol(tol)
    setting = resolve_tension(robot, tension)
    n = natural.shape[0]
    kin = robot.kinematics_batch(configurations(robot, natural), dynamics=True)
    status = np.full(n, STATUS_CODES["ok"], dtype=np.int8)
    seg_min = kin.segment_lengths.min(axis=1, initial=np.inf)
    status[~(seg_min >= MIN_SEGMENT_LENGTH)] = STATUS_CODES["zero_length_cable"]
    ok = np.flatnonzero(status == STATUS_CODES["ok"])
    wrench = np.full(n, NOT_ANALYSED, dtype=np.int8)
    static = np.full(n, NOT_ANALYSED, dtype=np.int8)
    batch = PoseBatch(robot, kin, status, wrench, static, np.zeros(0, dtype=int))
    if margin:
        batch.reach = reach_settings(robot, reach)
    if tension_search is not None:
        search, search_reach = (
            tension_search if isinstance(tension_search, tuple) else (tension_search, reach)
        )
        batch.tension_search = (search, reach_settings(robot, search_reach), tol)
    if ok.size == 0:
        return batch
    LT, load = statics(robot, kin)
    LT, load = LT[ok], load[ok]  # (k, nv, m), (k, nv)
    wrench[ok] = positively_spanning(-LT, tol)
    method = setting if isinstance(setting, str) else np.asarray(setting)
    eq = equilibrium_tensions(robot, LT, load, method, pretension)
    if isinstance(method, str) and method == "min_norm":
        feasible_any = eq.feasible
    else:
        feasible_any = equilibrium_tensions(robot, LT, load, "min_norm").feasible
    static[ok] = np.where(feasible_any, YES, NO)
    Minv, regular = mass_inverse(kin.mass_matrix[ok])
    status[ok[~regular]] = STATUS_CODES["singular_mass_matrix"]
    status[ok[regular & ~eq.feasible]] = STATUS_CODES["no_equilibrium"]
    use = regular & eq.feasible
    batch.analysed = ok[use]
    if not use.any():
        return batch
    eq = eq if use.all() else eq.take(use)
    lin = linearise_batch(robot, kin.take(batch.analysed), Minv[use], eq.tension, eq.input_sign)
    verdicts = analyse_systems(
        lin.A, lin.B_cone, lin.C, lin.sign_constrained, margin=False, tol=tol
    )
    status[batch.analysed[verdicts.failed]] = STATUS_CODES["analysis_failed"]
    batch.equilibrium, batch.linearisation, batch.verdicts = eq, lin, verdicts
    return batch
