"""The run machinery of maps, for other resumable computations over chunks
(certified maps, :func:`cdpm.certify.map.certify_map`): the chunk runner
(in this process, local worker processes or a Dask cluster), the lock of a
store, interrupts held while a store is written, the checks of a script's
``if __name__ == "__main__":`` guard and of a Dask scheduler's address,
the settings comparison of a resumed store, and the zarr calls of map
stores.

A computation run by :func:`run_chunks` gives it duck-typed parts:

- ``plan``: ``n_chunks``, ``n_poses``, ``chunk_size(k)`` (the units the
  progress counts) and ``natural(k)`` (chunk k's input, picklable);
- ``job``: ``tension`` (a tension setting: ``"zero"`` for a computation
  that needs no compiled kernels) and ``evaluate(robot, chunk_input)`` ->
  {name: array}, picklable;
- ``sink``: ``write(k, data)``, ``path`` (None in memory) and ``writer``
  (None, or a picklable object whose ``write(k, data)`` worker processes
  call themselves).

Everything here behaves as it does for :func:`cdpm.workspace_map`.
"""

from __future__ import annotations

from cdpm.maps import default_workers
from cdpm.maps._dask import check_scheduler_address
from cdpm.maps._lock import StoreBusyError, lock_path, store_lock
from cdpm.maps._progress import MapRunInfo, ProgressPrinter
from cdpm.maps._runner import interrupts_held, run_chunks
from cdpm.maps._store import StoreSettingsError, store_path_problem
from cdpm.maps._workers import RobotSource, prestart_workers, unimportable_main
from cdpm.maps._zarr_calls import file_store, sync, write_metadata, zarr_warnings_silenced
from cdpm.maps.plan import settings_difference

__all__ = [
    "run_chunks",
    "MapRunInfo",
    "ProgressPrinter",
    "RobotSource",
    "prestart_workers",
    "unimportable_main",
    "default_workers",
    "check_scheduler_address",
    "interrupts_held",
    "store_lock",
    "lock_path",
    "StoreBusyError",
    "StoreSettingsError",
    "settings_difference",
    "store_path_problem",
    "file_store",
    "sync",
    "write_metadata",
    "zarr_warnings_silenced",
]
