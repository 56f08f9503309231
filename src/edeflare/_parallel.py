"""Helpers shared by the commands that split work over processes and array jobs.

Dataset generation (:mod:`edeflare.data.generate`) and batch de-flaring
(:mod:`edeflare.methods.batch`) run the same way: ``shard="i/n"`` takes the
items whose index in a fixed order has ``index % n == i`` (one task of a SLURM
array or a Kubernetes indexed job each), and a ``spawn`` process pool runs
them (numba and ``fork`` do not mix). Workers ignore Ctrl-C (the parent
decides), limit their numba threads to their share of the cores, and exit on
their own when the parent dies, so a run killed with SIGKILL leaves no busy
orphans.

Examples
--------
>>> parse_shard("1/4"), parse_shard((0, 1))
((1, 4), (0, 1))
>>> parse_shard("4/4")
Traceback (most recent call last):
...
edeflare.errors.ParameterError: shard i/n needs n >= 1 and 0 <= i < n, got 4/4
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor

from ._interrupt import ignore_interrupts
from .errors import ParameterError

__all__ = ["init_worker", "parse_shard", "stop_workers", "watch_parent"]


def parse_shard(shard: tuple[int, int] | str) -> tuple[int, int]:
    """``"i/n"`` or ``(i, n)`` as ``(i, n)``, checked (``n >= 1``, ``0 <= i < n``)."""
    if isinstance(shard, str):
        try:
            i, n = (int(v) for v in shard.split("/"))
        except ValueError:
            raise ParameterError(f"shard must look like 0/4 (i/n), got {shard!r}") from None
    else:
        try:
            i, n = shard
        except (TypeError, ValueError):
            raise ParameterError(f"shard must be (i, n) or 'i/n', got {shard!r}") from None
    if not (n >= 1 and 0 <= i < n):
        raise ParameterError(f"shard i/n needs n >= 1 and 0 <= i < n, got {i}/{n}")
    return int(i), int(n)


def watch_parent(parent: int) -> None:
    """Exit when the parent process dies (a killed run must not leave busy orphans).

    The files this worker was writing are deleted first: a rerun started
    meanwhile leaves them alone while their writer lives, so nobody else would.
    """
    from .io._atomic import discard_open_temporaries

    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            discard_open_temporaries()
            os._exit(1)


def init_worker(parent: int, threads: int) -> None:
    """A pool worker's start: deaf to Ctrl-C, ``threads`` numba threads, watching its parent."""
    ignore_interrupts()  # Ctrl-C at a terminal reaches every worker: the parent decides
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    threading.Thread(target=watch_parent, args=(parent,), daemon=True).start()


def stop_workers(pool: ProcessPoolExecutor) -> None:
    """Terminate the pool's workers now (their files are temporary until written whole)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(5)
