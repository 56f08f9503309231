"""Ctrl-C that always stops a long run.

Python turns SIGINT into a ``KeyboardInterrupt`` raised in whatever Python
code the main thread runs next. When that is a finaliser (a weak reference's
callback such as ``WeakValueDictionary``'s, which numba's and multiprocessing's
caches run as objects die, or a ``__del__``), Python cannot propagate it: it
prints "Exception ignored in ..." and the run goes on as if nothing happened.

:func:`interruptible` closes that gap for the runs it wraps: SIGINT still
raises ``KeyboardInterrupt`` at once, and also leaves a flag, so that
:func:`check_interrupt`, called at safe points of a long loop (every frame of
the simulator, every sequence of a dataset), raises it again if a finaliser
swallowed it. The swallowed exception is not reported (it is not lost). An
interrupt that comes out of a library wrapped in another error is a
``KeyboardInterrupt`` again when the block ends.

Worker processes are started with SIGINT ignored (:func:`ignore_interrupts`
in their initializer, :func:`sigint_blocked` around their start): a terminal's
Ctrl-C reaches the whole process group, and the parent alone decides to stop.

Examples
--------
>>> with interruptible():
...     check_interrupt()  # nothing pending: returns
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any

__all__ = ["check_interrupt", "ignore_interrupts", "interruptible", "sigint_blocked"]

_pending = False  # a SIGINT arrived within interruptible(); cleared when it ends


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    global _pending
    _pending = True
    raise KeyboardInterrupt


def check_interrupt() -> None:
    """Raise ``KeyboardInterrupt`` if a Ctrl-C arrived (and was swallowed) in this run.

    Cheap (one flag read): call it at every step of a long loop. Outside
    :func:`interruptible`, or where it could not install its handler, it never raises.
    """
    if _pending:
        raise KeyboardInterrupt


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """Within: Ctrl-C raises ``KeyboardInterrupt`` and :func:`check_interrupt` raises it again.

    Any other exception that ends the block after a Ctrl-C becomes a
    ``KeyboardInterrupt`` (chained to it): an interrupt raised inside compiled
    code's callbacks comes out as another error (numba: ``SystemError ...
    returned a result with an exception set``).

    The handler is installed only in the main thread and only over Python's
    default one (an application that handles SIGINT itself keeps its handler);
    nested uses share the outermost one. On exit the previous handler returns.
    """
    global _pending
    install = (
        threading.current_thread() is threading.main_thread()
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )
    if not install:
        yield
        return
    previous_hook = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        if _pending and issubclass(unraisable.exc_type, KeyboardInterrupt):
            return  # swallowed by a finaliser: check_interrupt() raises it again
        previous_hook(unraisable)

    _pending = False
    signal.signal(signal.SIGINT, _on_sigint)
    sys.unraisablehook = hook
    try:
        yield
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        if _pending:  # the interrupt, raised inside a library that wrapped it in its own error
            raise KeyboardInterrupt from exc
        raise
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        if sys.unraisablehook is hook:
            sys.unraisablehook = previous_hook
        _pending = False


def ignore_interrupts() -> None:
    """Ignore SIGINT in this process (a worker's initializer), then let blocked ones go."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a pending one is discarded
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@contextlib.contextmanager
def sigint_blocked() -> Iterator[None]:
    """Hold SIGINT back in this thread meanwhile (delivered on exit, not lost).

    A process started meanwhile inherits the block through ``exec``, so a
    Ctrl-C cannot interrupt it before its initializer ignores SIGINT
    (:func:`ignore_interrupts`). Without ``pthread_sigmask`` (Windows): nothing.
    """
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
