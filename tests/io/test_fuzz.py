"""Fuzzed readers: no input raises a foreign exception, kills the process or hangs.

The mutation harness (``fuzz_harness.py`` beside this file) reads each batch
in a child process, so a crash is counted, not fatal. The default run gives
every format a few dozen inputs; the ``slow`` run gives it 10,000. An
in-process hypothesis test shrinks failures of our own pure-Python codecs.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import fuzz_harness as harness
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from edeflare.errors import EdeflareError
from edeflare.io import read_events

FUZZ_DIR = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "fuzz"


def _fuzz(fmt: str, n_inputs: int, folder: Path, *, real: bool) -> dict:
    seeds = harness.make_seeds(folder, fmt, real=real)
    return harness.fuzz_format(fmt, seeds, n_inputs, seed=0, work=folder)


def _assert_clean(result: dict) -> None:
    counts = result["counts"]
    assert sum(counts.values()) == result["inputs"]
    bad = {k: counts.get(k, 0) for k in ("foreign", "crash", "hang")}
    assert bad == {"foreign": 0, "crash": 0, "hang": 0}, result["findings"][:10]


@pytest.mark.parametrize("fmt", harness.FORMATS)
def test_fuzz_bounded(tmp_path, fmt):
    """40 mutated inputs per format (generated seeds): every one reads or raises ours."""
    _assert_clean(_fuzz(fmt, 40, tmp_path, real=False))


@pytest.mark.slow
@pytest.mark.parametrize("fmt", harness.FORMATS)
def test_fuzz_10000(tmp_path, fmt):
    """The target: 10,000 inputs per format, real recordings among the seeds."""
    _assert_clean(_fuzz(fmt, 10_000, tmp_path, real=True))


def test_harness_counts_a_crash_and_goes_on(tmp_path, monkeypatch):
    """A child that dies mid-batch costs one input, and the next child carries on."""
    seed = tmp_path / "seed.npz"
    seed.write_bytes(b"PK")
    calls = []
    real_popen = subprocess.Popen

    def popen(cmd, **kwargs):
        calls.append(cmd)
        if len(calls) == 1:  # the first child aborts like a Rust panic after input 2 starts
            log = cmd[cmd.index("--log") + 1]
            script = (
                "import os, sys\n"
                f"open({log!r}, 'a').write("
                '\'start 0\\n{"i": 0, "kind": "error"}\\nstart 1\\n'
                '{"i": 1, "kind": "ok"}\\nstart 2\\n\')\n'
                "os.abort()\n"
            )
            return real_popen([sys.executable, "-c", script], **kwargs)
        return real_popen(cmd, **kwargs)

    monkeypatch.setattr(harness.subprocess, "Popen", popen)
    result = harness.fuzz_format(".npz", [seed], 5, work=tmp_path)
    assert result["counts"]["crash"] == 1
    assert result["findings"][0]["i"] == 2 and result["findings"][0]["returncode"] == -6
    assert sum(result["counts"].values()) == 5 and result["children"] == 2
    assert calls[1][calls[1].index("--start") + 1] == "3"


def test_inputs_are_reproducible():
    seeds = [bytes(range(256)) * 8, b"abc" * 100]
    a = harness.input_bytes(seeds, 3, ".h5", 17)
    assert a == harness.input_bytes(seeds, 3, ".h5", 17)
    assert a != harness.input_bytes(seeds, 3, ".h5", 18)


# -- the AEDAT 4 input that once killed the process -----------------------------------------


def _rebuild(spec_name: str, tmp_path: Path) -> Path:
    spec_path = FUZZ_DIR / spec_name
    if not spec_path.is_file():
        from conftest import real_data_dir

        real_data_dir()  # skips (or fails under CI) when the shared data are absent
        pytest.fail(f"{spec_path} is missing")
    spec = json.loads(spec_path.read_text())
    data = bytearray((spec_path.parent / spec["base"]).read_bytes())
    for offset, value in spec["set_bytes"]:
        data[offset] = value
    path = tmp_path / f"broken{Path(spec['base']).suffix}"
    path.write_bytes(bytes(data))
    return path


def test_aedat4_abort_is_a_clear_error(tmp_path):
    """faery aborted (SIGABRT) on this header; now the CLI exits 1 with one line."""
    path = _rebuild("aedat4_abort.json", tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "edeflare", "info", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"edeflare: error: {path}: corrupt AEDAT 4 header")
    assert "not UTF-8" in lines[0]


# -- in process, with shrinking: our own pure-Python codecs ---------------------------------

_SIZE = (32, 24)


def _seed_bytes(tmp_path_factory, suffix: str) -> bytes:
    from edeflare.io import write_events

    rng = np.random.default_rng(3)
    n = 200
    events = np.zeros(n, dtype=[("t", "<i8"), ("x", "<u2"), ("y", "<u2"), ("p", "u1")])
    events["t"] = np.sort(rng.integers(0, 50_000, n)) + 1_000
    events["x"] = rng.integers(0, _SIZE[0], n)
    events["y"] = rng.integers(0, _SIZE[1], n)
    events["p"] = rng.integers(0, 2, n)
    path = tmp_path_factory.mktemp("seed") / f"seed{suffix}"
    write_events(path, events, _SIZE)
    return path.read_bytes()


_MUTATION = st.lists(
    st.one_of(
        st.tuples(st.just("set"), st.integers(0, 1 << 16), st.integers(0, 255)),
        st.tuples(st.just("cut"), st.integers(0, 1 << 16), st.just(0)),
        st.tuples(st.just("del"), st.integers(0, 1 << 16), st.integers(1, 64)),
    ),
    min_size=1,
    max_size=6,
)


@pytest.mark.parametrize("suffix", [".npz", ".dat", ".csv", ".txt"])
def test_own_codecs_raise_only_project_errors(tmp_path_factory, suffix):
    seed = _seed_bytes(tmp_path_factory, suffix)
    folder = tmp_path_factory.mktemp("fuzz")

    @given(_MUTATION)
    def check(ops):
        buf = bytearray(seed)
        for op, pos, value in ops:
            pos %= max(len(buf), 1)
            if op == "set" and buf:
                buf[pos] = value
            elif op == "cut":
                del buf[pos:]
            elif op == "del":
                del buf[pos : pos + value]
        path = folder / f"input{suffix}"
        path.write_bytes(bytes(buf))
        try:
            read_events(path, _SIZE)
        except EdeflareError:
            pass

    check()
