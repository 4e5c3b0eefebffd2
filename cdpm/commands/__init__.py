"""One module per CLI command (see :mod:`cdpm.cli`)."""
