"""``python -m sparsekin``: the command line of `sparsekin.cli`."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
