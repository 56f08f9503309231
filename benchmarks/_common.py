"""Shared helpers of the benchmark scripts: timing, tables, JSON output."""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
"""The real recordings (``../shared/data/real`` beside the clone)."""


PEAK_MIB = r"""
def peak_mib():
    # VmHWM: this process's own high-water mark (ru_maxrss is carried over from the
    # parent across fork and exec, so it would report the benchmark's own peak)
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) for l in f if l.startswith("VmHWM")) / 1024
"""
"""Source of ``peak_mib()`` for the ``python -c`` children of the benchmarks."""


def best_of(fn: Callable[[], object], repeat: int = 3) -> float:
    """Best wall time of ``repeat`` calls (after one warm-up call), in seconds."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def random_events(
    n: int, sensor_size: tuple[int, int], t0: int, span_us: int, seed: int = 0
) -> np.ndarray:
    """``n`` sorted uniform random events in ``[t0, t0 + span_us)``."""
    from edeflare.events import EVENT_DTYPE

    rng = np.random.default_rng(seed)
    ev = np.empty(n, dtype=EVENT_DTYPE)
    ev["t"] = np.sort(rng.integers(t0, t0 + span_us, n))
    ev["x"] = rng.integers(0, sensor_size[0], n)
    ev["y"] = rng.integers(0, sensor_size[1], n)
    ev["p"] = rng.integers(0, 2, n)
    return ev


def add_model_option(parser: argparse.ArgumentParser, what: str = "also this model") -> None:
    """The repeatable ``--model WEIGHTS`` of the scripts that add rows for other models."""
    parser.add_argument(
        "--model",
        action="append",
        default=[],
        metavar="WEIGHTS",
        help=f"{what} (a bundled model's name or a .safetensors file; repeatable)",
    )


def report(name: str, rows: list[dict[str, object]], columns: list[str]) -> None:
    """Print rows as a table and write ``results/<name>.json`` with machine info."""
    widths = [max(len(c), *(len(_fmt(r.get(c, ""))) for r in rows)) for c in columns]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=True)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(_fmt(r.get(c, "")).ljust(w) for c, w in zip(columns, widths, strict=True)))
    RESULTS.mkdir(exist_ok=True)
    payload = {
        "benchmark": name,
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor(),
            "system": platform.platform(),
            "numpy": np.__version__,
        },
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "rows": rows,
    }
    (RESULTS / f"{name}.json").write_text(json.dumps(payload, indent=2))
    print(f"\nwrote {RESULTS / f'{name}.json'}")


def _fmt(v: object) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def model_label(weights: str) -> str:
    """A model row's name: a run's folder for a weights file, else the bundled name.

    Examples
    --------
    >>> model_label("runs/near/model.safetensors"), model_label("learned")
    ('near', 'learned')
    """
    return Path(weights).parent.name if weights.endswith(".safetensors") else weights
