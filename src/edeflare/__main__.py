"""``python -m edeflare``: the same as the ``edeflare`` command."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
