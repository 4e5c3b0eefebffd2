"""First of the modules the fork server of a map's local workers imports
(``cdpm.maps._workers``): Ctrl-C, which the terminal sends to the whole
process group, is ignored while the server imports the rest (about a
second), so that an early Ctrl-C does not print the server's traceback
beside the map's own one-line message; the map's process handles it, and
the server ends with it. It lies outside ``cdpm.maps``, whose package
imports numpy first (a tenth of a second left unprotected); ``import
cdpm`` costs a few milliseconds. The last module imported
(:mod:`cdpm.forkserver.ready`) gives Ctrl-C back to Python's handler.
Imported for that effect only, in the fork server's main thread."""

import signal

signal.signal(signal.SIGINT, signal.SIG_IGN)
