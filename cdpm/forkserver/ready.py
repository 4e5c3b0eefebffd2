"""Last of the modules the fork server of a map's local workers imports:
Ctrl-C goes back to Python's own handler (:mod:`cdpm.forkserver.quiet`
ignored it while the server imported the rest). The server then protects
itself from Ctrl-C as multiprocessing has it, and the processes it forks
start with Python's handler, as without cdpm's imports; cdpm's workers
ignore Ctrl-C themselves.

The server was started with Ctrl-C blocked (``cdpm.maps._workers``: a
Ctrl-C while its interpreter started would kill it with "Fatal Python
error"); it is unblocked here while still ignored, so that a Ctrl-C that
came meanwhile is dropped, not delivered to the handler."""

import signal

if hasattr(signal, "pthread_sigmask"):
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
signal.signal(signal.SIGINT, signal.default_int_handler)
