"""The decorator of cdpm's compiled kernels (numba).

Imported only by the kernel modules (:data:`cdpm.pipeline.compiled.KERNEL_MODULES`
and the Gaussian elimination they share), so that ``import cdpm`` does not
load numba.
"""

from __future__ import annotations

__all__ = ["kernel"]


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
    # scipy: loaded on first use
    import numba

    return numba.njit(*args, cache=True, nogil=True, **options)
