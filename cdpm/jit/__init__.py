"""The decorator of cdpm's compiled kernels (numba), and the notice that
they are being compiled.

Imported only by the kernel modules (:data:`cdpm.pipeline.compiled.KERNEL_MODULES`
and the Gaussian elimination they share) and by the code that loads them
ahead of use, so that ``import cdpm`` does not load numba.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["kernel", "COMPILE_NOTICE", "compile_notice"]

#: what the user is told when cdpm's kernels are compiled (not loaded from
#: numba's disk cache)
COMPILE_NOTICE = "compiling cdpm's numba kernels: once after installing, about half a minute"

#: the packages whose kernels the notice speaks of
_KERNEL_PACKAGE = __name__.split(".")[0]


def kernel(*args, **options):
    """``numba.njit`` with the options every cdpm kernel has: compiled
    code cached on disk (:mod:`cdpm.pipeline.compiled` loads the kernels ahead of
    use), and the GIL released while the kernel runs (``nogil``: kernels
    touch no Python object), so that the other threads of a program that
    maps in a thread of its own (a GUI, a server) keep running meanwhile.

    Used as ``@kernel``, ``@kernel(fastmath=...)`` or
    ``@kernel(signature, ...)``; ``args`` and ``options`` go to
    ``numba.njit``.

    numba's disk cache is keyed on each kernel's own module file, not on
    these options: after changing them here, delete the caches
    (``__pycache__/*.nbi`` and ``*.nbc`` beside the kernel modules), or
    the kernels compiled with the old options are loaded again.
    """
    # numba: loaded on first use
    import numba

    return numba.njit(*args, cache=True, nogil=True, **options)


@contextmanager
def compile_notice(notice: Callable[[str], None] | None) -> Iterator[None]:
    """Within the block, call ``notice(COMPILE_NOTICE)`` once, as soon as
    numba starts compiling one of cdpm's kernels; never when the kernels
    are loaded from numba's disk cache, however long that takes.

    numba broadcasts its ``"numba:compile"`` event (``numba.core.event``)
    only after its dispatcher missed the disk cache for a signature
    (``Dispatcher.compile``: ``_cache.load_overload`` first, a hit returns
    without the event), so the notice is given exactly when compiling
    starts, before the half minute it takes. Functions of other packages
    compiled meanwhile (a program's own numba code) do not count.

    Args:
        notice: called with the sentence for the user (from the thread that
            compiles); None: the block runs as it is.
    """
    if notice is None:
        yield
        return
    # numba: loaded on first use
    from numba.core import event

    told = threading.Event()

    class _Listener(event.Listener):
        def on_start(self, ev) -> None:
            dispatcher = (ev.data or {}).get("dispatcher")
            module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
            if module.split(".")[0] == _KERNEL_PACKAGE and not told.is_set():
                told.set()
                notice(COMPILE_NOTICE)

        def on_end(self, ev) -> None:
            pass

    with event.install_listener("numba:compile", _Listener()):
        yield
