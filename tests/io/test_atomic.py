"""Atomic writes: the target appears whole or not at all; killed writers' temporaries go."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from edeflare.io._atomic import AtomicFile, atomic_path, discard_open_temporaries


def _dead_pid() -> int:
    """The id of a process that has exited (and been reaped)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_an_error_in_the_body_leaves_the_old_target_and_no_temporary(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed in the middle")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_the_temporary_names_its_target_and_its_writer(tmp_path):
    atomic = AtomicFile(tmp_path / "out.h5")
    assert atomic.tmp.name.startswith(f".out.h5.{os.getpid()}-")
    assert atomic.tmp.name.endswith(".partial.h5")  # the suffix picks the writer's format
    atomic.discard()


def test_a_commit_removes_temporaries_of_killed_writers_only(tmp_path):
    target = tmp_path / "out[1].npz"  # glob metacharacters in the name
    dead = tmp_path / f".out[1].npz.{_dead_pid()}-abc.partial.npz"
    alive = tmp_path / f".out[1].npz.{os.getppid()}-def.partial.npz"  # a running writer
    spool = tmp_path / f"{dead.name}.t"  # a writer's file beside its temporary
    other = tmp_path / f".other.npz.{_dead_pid()}-ghi.partial.npz"  # another target's
    for path in (dead, spool, alive, other):
        path.write_bytes(b"half")
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"whole")
    assert target.read_bytes() == b"whole"
    assert not dead.exists() and not spool.exists() and alive.exists() and other.exists()


def test_a_dying_worker_deletes_the_temporaries_it_is_writing_and_nothing_else(tmp_path):
    done = tmp_path / "done.h5"
    with atomic_path(done) as tmp:
        tmp.write_text("whole")
    writing = AtomicFile(tmp_path / "r[1].h5")  # glob metacharacters in the name
    writing.tmp.write_text("half")
    spool = writing.tmp.with_name(writing.tmp.name + ".x")  # a part kept beside it
    spool.write_text("part")
    abandoned = AtomicFile(tmp_path / "gone.h5")
    abandoned.discard()
    discard_open_temporaries()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["done.h5"]
    discard_open_temporaries()  # idempotent: nothing left to delete
    assert done.read_text() == "whole"
