"""The decorator of cdpm's compiled kernels (numba).

Imported only by the kernel modules (:data:`cdpm.compiled.KERNEL_MODULES`
and the Gaussian elimination they share), so that ``import cdpm`` does not
load numba.
"""

from __future__ import annotations

__all__ = ["kernel"]


def kernel(*args, **options):
    """``numba.njit`` with the options every cdpm kernel has: compiled
    code cached on disk, and the GIL released while the kernel runs
    (``nogil``: kernels touch no Python object), so that another thread
    of the process runs meanwhile (a new map store's files are written
    while its first chunk computes: :class:`cdpm.maps._store.ZarrSink`;
    :mod:`cdpm.compiled` loads the kernels ahead of use).

    Used as ``@kernel``, ``@kernel(fastmath=...)`` or
    ``@kernel(signature, ...)``; ``args`` and ``options`` go to
    ``numba.njit``.
    """
    import numba

    return numba.njit(*args, cache=True, nogil=True, **options)
