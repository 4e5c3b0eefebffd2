"""Modules the fork server of a map's local workers imports for their
effect on Ctrl-C (:mod:`~cdpm.forkserver.quiet` first,
:mod:`~cdpm.forkserver.ready` last); see :mod:`cdpm.maps._workers`."""

__all__: list[str] = []
