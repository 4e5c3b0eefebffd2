"""``python -m cdpm``: the command line, the same as the ``cdpm`` script."""

import sys

from cdpm.cli import main

if __name__ == "__main__":
    sys.exit(main())
