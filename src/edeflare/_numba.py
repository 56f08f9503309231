"""numba settings the package relies on, applied by the modules that run parallel kernels.

numba's default threading layer here is GNU OpenMP, which kills any child
process forked after a parallel kernel ran (data-loader workers,
dataset-generation pools). The workqueue layer is fork-safe; users can still
choose with ``NUMBA_THREADING_LAYER``. :mod:`edeflare.events` (imported by every
module with a parallel kernel) calls :func:`use_fork_safe_threading` when it is
first imported, so ``import edeflare`` alone changes nothing.
"""

from __future__ import annotations

import os

__all__ = ["use_fork_safe_threading"]


def use_fork_safe_threading() -> None:
    """Select numba's fork-safe ``workqueue`` threading layer unless the user chose one."""
    if "NUMBA_THREADING_LAYER" not in os.environ:
        import numba

        numba.config.THREADING_LAYER = "workqueue"
