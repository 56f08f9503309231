"""``python -m edeflare``: the same as the ``edeflare`` command."""

import sys

from .cli import main

sys.exit(main())
