"""Atomic file writes: a temporary file in the target folder, then ``os.replace``."""

from __future__ import annotations

import contextlib
import glob
import os
import re
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

__all__ = ["AtomicFile", "atomic_path", "discard_open_temporaries", "remove_stale_temporaries"]

# The temporaries this process is writing now: a pool worker whose parent was
# killed deletes them before it exits (the rerun cannot: their writer still runs).
_open: set[Path] = set()
_open_lock = threading.Lock()


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _running(pid: int) -> bool:
    """True when a process ``pid`` exists on this machine (whoever owns it)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_temporaries(path: str | os.PathLike[str]) -> None:
    """Delete the temporaries of target ``path`` whose writing process no longer runs.

    Those are :class:`AtomicFile` temporaries left by killed writers, with the
    files a writer keeps beside its temporary (``<temporary>.<part>``). A
    temporary of a running process (another worker writing the same target)
    is left alone.
    """
    path = Path(path)
    pattern = re.compile(
        rf"\.{re.escape(path.name)}\.(\d+)-.*\.partial{re.escape(path.suffix)}(\..+)?"
    )
    name, suffix = glob.escape(path.name), glob.escape(path.suffix)
    for stale in path.parent.glob(f".{name}.*.partial{suffix}*"):  # spools too
        match = pattern.fullmatch(stale.name)
        if match and not _running(int(match.group(1))):
            with contextlib.suppress(FileNotFoundError):
                stale.unlink()


class AtomicFile:
    """A temporary path beside ``path`` that becomes ``path`` on :meth:`commit`.

    The temporary name keeps the target's suffix (writers that choose the
    format by suffix still work), starts with ``.``, holds the writer's
    process id and contains ``.partial``. Until :meth:`commit`, ``path`` is
    untouched: an error or a killed process leaves the old file or none, never
    a half-written one. A commit also deletes the temporaries that killed
    writers of the same target left behind (their process is gone), with the
    files a writer keeps beside its temporary (``<temporary>.<part>``).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(
            prefix=f".{self.path.name}.{os.getpid()}-",
            suffix=f".partial{self.path.suffix}",
            dir=self.path.parent,
        )
        os.close(fd)
        self.tmp = Path(name)
        with _open_lock:
            _open.add(self.tmp)

    def commit(self) -> None:
        """Move the finished temporary file onto the target (with the usual umask mode)."""
        os.chmod(self.tmp, 0o666 & ~_umask())
        os.replace(self.tmp, self.path)
        with _open_lock:
            _open.discard(self.tmp)
        self._remove_orphans()

    def _remove_orphans(self) -> None:
        """Delete temporaries of this target whose writing process no longer runs."""
        remove_stale_temporaries(self.path)

    def discard(self) -> None:
        """Delete the temporary file (idempotent)."""
        with _open_lock:
            _open.discard(self.tmp)
        with contextlib.suppress(FileNotFoundError):
            self.tmp.unlink()


def discard_open_temporaries() -> None:
    """Delete every temporary this process is writing, with the parts kept beside them.

    For a process about to exit unfinished (a pool worker whose parent died):
    its writes stop, and nothing of them stays behind.
    """
    with _open_lock:
        temporaries = list(_open)
        _open.clear()
    for tmp in temporaries:
        for path in (tmp, *tmp.parent.glob(f"{glob.escape(tmp.name)}.*")):
            with contextlib.suppress(FileNotFoundError):
                path.unlink()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it onto ``path`` if the body succeeds.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "out.txt"
    >>> with atomic_path(target) as tmp:
    ...     _ = tmp.write_text("done")
    >>> target.read_text()
    'done'
    """
    atomic = AtomicFile(path)
    try:
        yield atomic.tmp
        atomic.commit()
    finally:
        atomic.discard()
