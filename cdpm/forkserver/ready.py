"""Last of the modules the fork server of a map's local workers imports:
Ctrl-C goes back to Python's own handler (:mod:`cdpm.forkserver.quiet`
ignored it while the server imported the rest). The server then protects
itself from Ctrl-C as multiprocessing has it, and the processes it forks
start with Python's handler, as without cdpm's imports; cdpm's workers
ignore Ctrl-C themselves."""

import signal

signal.signal(signal.SIGINT, signal.default_int_handler)
