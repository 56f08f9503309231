"""Shared fixtures and helpers for the edeflare test suite.

- ``rng``: a seeded :class:`numpy.random.Generator` (seed 1234), fresh per test.
- ``real_data`` / ``golden_data``: the shared real recordings and golden files
  beside the repository (``../shared/data/``); tests using them skip cleanly
  when the folder is absent (as it is for a user who installs the package),
  and FAIL when the environment variable ``CI`` is set: CI must not pass
  without testing. :func:`require` does the same for any other requirement
  (:func:`browser` finds Chromium on ``PATH``).
- :func:`random_events`: a sorted random stream of :data:`EVENT_DTYPE`.
- :func:`load_benchmark`: a script of ``benchmarks/`` as a module, for its tests.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import types
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from edeflare.events import EVENT_DTYPE, SensorSize

# Deterministic property tests that write no example database into the repository.
settings.register_profile(
    "edeflare",
    database=None,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
settings.load_profile("edeflare")

SHARED_DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(monkeypatch: pytest.MonkeyPatch, name: str) -> types.ModuleType:
    """``benchmarks/<name>.py`` imported as a module (its folder on ``sys.path`` for the
    test's duration, so that its ``_common`` and sibling scripts import)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ON_CI = bool(os.environ.get("CI"))
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def require(missing: str) -> None:
    """Skip the calling test for want of ``missing``; under CI (``$CI`` set), fail it."""
    if ON_CI:
        pytest.fail(f"{missing} (CI is set: required, not skipped)", pytrace=False)
    pytest.skip(missing)


def real_data_dir() -> Path:
    """``../shared/data/real`` (resolved); skip the calling test when absent (fail under CI)."""
    path = (SHARED_DATA / "real").resolve()
    if not path.is_dir():
        require("shared real recordings absent")
    return path


def golden_data_dir() -> Path:
    """``../shared/data/golden`` (resolved); skip the calling test when absent (fail under CI)."""
    path = (SHARED_DATA / "golden").resolve()
    if not path.is_dir():
        require("shared golden files absent")
    return path


def browser() -> str:
    """Path of a Chromium found on ``PATH``; skip the calling test when none (fail under CI)."""
    for name in BROWSERS:
        found = shutil.which(name)
        if found:
            return found
    require(f"no browser on PATH (looked for {', '.join(BROWSERS)}; apt install chromium)")
    raise AssertionError("unreachable")


@pytest.fixture(autouse=True, scope="session")
def _ctrl_c_reaches_the_tests():
    """Ctrl-C raises KeyboardInterrupt in the tests and the programs they start, also in a
    run started with SIGINT ignored (a background job of a non-interactive shell, or
    ``nohup``), which Python and every child would otherwise inherit."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield


@pytest.fixture
def rng() -> np.random.Generator:
    """A freshly seeded generator, so every test draws the same numbers on every run."""
    return np.random.default_rng(1234)


@pytest.fixture
def real_data() -> Path:
    """Folder of the shared real recordings (skips when absent)."""
    return real_data_dir()


@pytest.fixture
def golden_data() -> Path:
    """Folder of the shared golden reference files (skips when absent)."""
    return golden_data_dir()


def random_events(
    rng: np.random.Generator,
    n: int,
    sensor_size: SensorSize,
    t0: int = 0,
    span_us: int = 1_000_000,
) -> np.ndarray:
    """``n`` random events on ``sensor_size`` with ``t`` in ``[t0, t0 + span_us)``, sorted.

    Timestamps are drawn with replacement, so ties occur; the sort is stable.
    """
    width, height = sensor_size
    events = np.empty(n, dtype=EVENT_DTYPE)
    events["t"] = np.sort(rng.integers(0, span_us, n)) + t0
    events["x"] = rng.integers(0, width, n)
    events["y"] = rng.integers(0, height, n)
    events["p"] = rng.integers(0, 2, n)
    return events


def write_left_flare_pairs(
    folder: Path, rng: np.random.Generator, n_train: int, size: SensorSize = (48, 32)
) -> None:
    """Paired sequences under ``folder/train`` (``n_train`` files) and ``folder/test`` (one):
    a dense random burst of flare in the left half (not in gt), a sparse scene in the right,
    60 ms, at ``size``; no window holds a light the light test finds."""
    from edeflare.io.dsec import write_dsec_groups

    for split, k in (("train", n_train), ("test", 1)):
        for i in range(k):
            scene = random_events(rng, 300, (size[0] // 2, size[1]), t0=0, span_us=60_000)
            scene["x"] += size[0] // 2
            flare = random_events(rng, 3_000, (size[0] // 2, size[1]), t0=0, span_us=60_000)
            inp = np.sort(np.concatenate([scene, flare]), order="t", kind="stable")
            write_dsec_groups(folder / split / f"s{i}.h5", {"input": inp, "gt": scene}, size)


def same_events(a: np.ndarray, b: np.ndarray) -> bool:
    """True when two streams hold the same events in the same order (field by field)."""
    return (
        a.dtype == EVENT_DTYPE
        and b.dtype == EVENT_DTYPE
        and a.shape == b.shape
        and all(np.array_equal(a[k], b[k]) for k in ("t", "x", "y", "p"))
    )


def tree_bytes(path: Path) -> dict[str, bytes]:
    """Every file under ``path`` by relative name with its bytes (a file: ``{"": bytes}``)."""
    if path.is_file():
        return {"": path.read_bytes()}
    files = sorted(p for p in path.rglob("*") if p.is_file())
    return {str(p.relative_to(path)): p.read_bytes() for p in files}


def kill_at_random_moments(
    argv: list[str],
    out: Path,
    reference: Path,
    seeds: range,
    *,
    kept_current: Mapping[str, Callable[[bytes, bytes, bool], None]] | None = None,
) -> int:
    """SIGKILL ``edeflare argv`` (which writes ``out``) at random moments, rerun, compare.

    ``argv`` names ``out``; a straight run into ``reference`` (same arguments, the
    output swapped) sets the clock: each kill lands at a uniform random moment of
    the first three quarters of its wall time, start-up included; the run's pool
    workers (if any) are given 10 s to notice and stop. After every kill nothing may sit under the
    output's name but complete files equal to the reference's, and a rerun
    must give the reference's bytes exactly (temporary files included: none).

    ``kept_current`` names files that a run rewrites as it goes (a manifest of
    the outputs so far), each with a check ``(data, reference_data, finished)``
    that asserts, instead of equal bytes: after a kill (``finished`` False) and
    after the rerun (True). Returns how many kills landed before the run ended
    (the caller asserts that most did).
    """
    import signal
    import subprocess
    import sys
    import time

    current = dict(kept_current or {})
    swapped = [str(reference) if a == str(out) else a for a in argv]
    start = time.monotonic()
    assert subprocess.run([sys.executable, "-m", "edeflare", *swapped]).returncode == 0
    wall = time.monotonic() - start
    expected = tree_bytes(reference)
    killed = 0
    for seed in seeds:
        if out.is_dir():
            shutil.rmtree(out)
        else:
            out.unlink(missing_ok=True)
        # within the first three quarters of the straight run's time: a busier or quieter
        # machine changes the run's length by tens of percent between runs
        moment = np.random.default_rng(seed).uniform(0.0, 0.75 * wall)
        child = subprocess.Popen(
            [sys.executable, "-m", "edeflare", *argv],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        time.sleep(moment)
        workers = children(child.pid) if Path("/proc/self/stat").exists() else []
        child.send_signal(signal.SIGKILL)
        child.wait()
        killed += child.returncode == -signal.SIGKILL
        deadline = time.monotonic() + 10  # orphaned workers notice, delete their temporaries
        while any(alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        if out.exists():  # whatever is there under final names is complete
            for name, data in tree_bytes(out).items():
                if name in current:
                    current[name](data, expected[name], False)
                elif ".partial" not in name and not Path(name).name.startswith("."):
                    assert data == expected.get(name), f"{name} half-written at {moment:.2f} s"
        rerun = subprocess.run([sys.executable, "-m", "edeflare", *argv], capture_output=True)
        assert rerun.returncode == 0, rerun.stderr.decode()
        got = tree_bytes(out)
        assert sorted(got) == sorted(expected), f"rerun after a kill at {moment:.2f} s: files"
        for name, check in current.items():
            check(got.pop(name), expected[name], True)
        assert got == {k: v for k, v in expected.items() if k not in current}, (
            f"rerun after a kill at {moment:.2f} s differs"
        )
    return killed


def children(pid: int) -> list[int]:
    """Live processes whose parent is ``pid`` (Linux /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            found.append(int(stat.parent.name))
    return found


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (not gone, not a zombie; Linux /proc)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def sigkill_main_process(
    argv: list[str], log: Path, ready: Callable[[], bool], *, poll_s: float = 0.01
) -> tuple[int, list[int]]:
    """Run ``argv`` with this checkout's ``src`` first on the path, wait (at most 120 s)
    until ``ready()``, and SIGKILL its main process only, as a scheduler would; return
    its exit status and the workers it had then, after waiting up to 10 s for them to
    notice and stop."""
    import signal
    import subprocess
    import time

    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    with open(log, "wb") as err:
        proc = subprocess.Popen(argv, env=env, stderr=err)
        try:
            deadline = time.monotonic() + 120
            while not ready() and time.monotonic() < deadline:
                if proc.poll() is not None:
                    break
                time.sleep(poll_s)
            workers = children(proc.pid)
            proc.send_signal(signal.SIGKILL)
        finally:
            proc.wait()
    deadline = time.monotonic() + 10
    while any(alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    return proc.returncode, workers


def strip_fences(text: str) -> str:
    """The text without fenced code blocks (``` or ~~~ fences, any indentation)."""
    kept, fence = [], None
    for line in text.splitlines():
        marker = line.lstrip()[:3]
        if fence is None and marker in ("```", "~~~"):
            fence = marker
        elif fence is not None and marker == fence:
            fence = None
        elif fence is None:
            kept.append(line)
    return "\n".join(kept)
