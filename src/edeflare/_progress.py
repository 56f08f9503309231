"""Progress bars: shown on a terminal only, never written into logs or pipes.

Every progress bar of the package is made by :func:`progress_bar`. A bar redraws
itself with carriage returns, which a log file, a pipe or a batch job's output
keeps as clutter; so a bar is drawn only when the stream it writes to (stderr
by default) is a terminal, and never when the caller turned it off.

Examples
--------
>>> import io
>>> log = io.StringIO()  # not a terminal
>>> sum(progress_bar(range(4), file=log, desc="sum")), log.getvalue()
(6, '')
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import IO, TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["is_terminal", "progress_bar"]


def is_terminal(stream: IO[str] | None) -> bool:
    """True when ``stream`` is an open terminal (False for files, pipes, None, closed streams)."""
    try:
        return bool(stream is not None and stream.isatty())
    except (AttributeError, ValueError, OSError):  # no isatty, or closed
        return False


def progress_bar(
    iterable: Iterable[Any] | None = None,
    *,
    enabled: bool | None = True,
    file: IO[str] | None = None,
    **kwargs: Any,
) -> tqdm:
    """A ``tqdm`` bar drawn only when ``enabled`` and its stream is a terminal.

    Parameters
    ----------
    iterable : iterable, optional
        Wrapped as ``tqdm(iterable)`` does; leave it out for a bar updated by hand.
    enabled : bool or None
        False: no bar, whatever the stream (a caller's ``progress=False``).
        True or None: a bar on a terminal only.
    file : text stream, optional
        Where the bar is drawn (default: ``sys.stderr`` at the call).
    **kwargs
        Any other ``tqdm`` argument (``total``, ``desc``, ``unit``, ``leave``...),
        except ``disable``, which this function decides.

    Returns
    -------
    tqdm
        A bar; a disabled one still iterates and takes ``update``/``close``, drawing nothing.
    """
    from tqdm import tqdm  # on first use: importing edeflare stays light

    stream = sys.stderr if file is None else file
    shown = enabled is not False and is_terminal(stream)
    return tqdm(iterable, file=stream, disable=not shown, **kwargs)
