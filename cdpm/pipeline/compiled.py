"""The compiled kernels of the maps (numba), and loading them ahead of use.

Five per-pose loops are compiled with numba and cached on disk beside their
modules (or in numba's user cache when the package folder is not
writable): the least-norm equilibrium Newton
(``cdpm.dynamics.equilibrium._newton_kernel``), the cable stiffness
(``cdpm.model.stiffness_kernel``), the Krylov rank tests of the controllability
exits (``cdpm.analysis.rank_kernel``), the wrench-closure certificates
(``cdpm.analysis._span_batch``) and the reach margin's facet search
(``cdpm.analysis._zonotope_kernel``). Their modules are imported on first
use, so ``import cdpm`` does not load numba. The first use after an
install compiles them (several seconds each); later processes load them
from the cache in tenths of a second.

:func:`load_kernels` does that first use on tiny inputs. Maps under load
call it before starting worker processes, so that the workers load the
cache instead of each compiling the same code, and the test suite calls it
once at its start.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable

import numpy as np

from cdpm.dynamics.equilibrium.newton import min_norm_tensions
from cdpm.errors import CdpmError
from cdpm.pipeline.evaluate import resolve_tension, zero_equilibrium

__all__ = [
    "KERNEL_MODULES",
    "load_kernels",
    "load_kernels_for",
    "notice_on_stderr",
]

#: the modules holding compiled kernels (the worker fork server imports them)
KERNEL_MODULES = (
    "cdpm.dynamics.equilibrium._newton_kernel",
    "cdpm.analysis._span_batch",
    "cdpm.analysis._zonotope_kernel",
    "cdpm.model.stiffness_kernel",
    "cdpm.analysis.rank_kernel",
)


#: set once this process has loaded the kernels (:func:`load_kernels`)
_LOADED = threading.Event()


def load_kernels(notice: Callable[[str], None] | None = None) -> None:
    """Compile every kernel (first use after an install) or load it from the
    disk cache, through the functions that call them, on inputs of the
    types maps pass (float64, C order); once per process (later calls
    return at once: a map calls it before its chunks, and calling every
    kernel again cost 0.6 ms a map).

    Args:
        notice: called once with a sentence for the user when numba
            compiles a kernel (not when it loads it from its disk cache:
            :func:`cdpm.jit.compile_notice`); None: say nothing.
    """
    if _LOADED.is_set():
        return
    # numba: loaded on first use
    from cdpm.jit import compile_notice

    with compile_notice(notice):
        _load_kernels()
    _LOADED.set()


def _load_kernels() -> None:
    # scipy: loaded on first use
    from cdpm.analysis.batch import positively_spanning
    from cdpm.analysis.exits import free_controllable, output_controllable
    from cdpm.analysis.rank_kernel import krylov_matrices
    from cdpm.analysis.reach import zonotope_inradii
    from cdpm.model.stiffness_kernel import stiffness_batch

    simplex = np.array([[[1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, -1.0], [0.0, 0.0, 1.0, -1.0]]])
    positively_spanning(simplex)  # (1, 3, 4): d >= 3 goes to the kernel
    zonotope_inradii(simplex, np.zeros((1, 3)), group=2)
    lt = np.array([[[1.0, -1.0]]])  # one joint, two opposed cables
    min_norm_tensions(lt, np.array([[0.5]]), np.zeros(2), np.full(2, np.inf), 1.0)
    # a double integrator with one free input
    A, B = np.array([[[0.0, 1.0], [0.0, 0.0]]]), np.array([[[0.0], [1.0]]])
    free_controllable(A, B, np.zeros((1, 1), dtype=bool))
    output_controllable(A, B, np.array([[[1.0, 0.0]]]))
    # the exits' exact fallback rebuilds the Krylov matrices of undecided systems
    krylov_matrices(A, B, np.ones((1, 1), dtype=bool), None, np.zeros(1, dtype=int))
    stiffness_batch(  # one pose, one segment between two points
        *(np.ones(shape) for shape in ((1, 2, 3, 1), (1, 1, 3), (1, 1), (1, 6, 1))),
        np.ones((1, 1)),
        np.array([[0, 1]]),
        np.zeros(1, int),
        np.ones((1, 1), bool),
        np.ones((2, 1), bool),
    )


def load_kernels_for(robot, tension=None, notice: Callable[[str], None] | None = None) -> None:
    """:func:`load_kernels`, when work at the poses of ``robot`` with this
    tension setting goes through the kernels (not the zero-load path, which
    needs none); a tension setting that is not valid does nothing (the
    caller reports it)."""

    try:
        setting = resolve_tension(robot, tension)
    except CdpmError:
        return
    if not zero_equilibrium(robot, setting):
        load_kernels(notice)


def notice_on_stderr(text: str) -> None:
    """Print a notice for the user on standard error."""
    print(text, file=sys.stderr, flush=True)
