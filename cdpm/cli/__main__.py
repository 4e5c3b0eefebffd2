"""``python -m cdpm.cli``: the command line, the same as ``cdpm`` and
``python -m cdpm``."""

import sys

from cdpm.cli import main

if __name__ == "__main__":
    sys.exit(main())
