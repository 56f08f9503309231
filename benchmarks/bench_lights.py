"""Light detection speed: the detector against its first form, scipy over the whole frame.

:func:`edeflare.lights.detect_light_source` smooths a window's count map with a 3x3
median and a Gaussian (sigma 2), computed only where they can differ from 0
(:func:`~edeflare.lights.detect.median3`, :func:`~edeflare.lights.detect.gaussian_on_support`:
the same numbers, tested to the bit), and takes each region's size and peak from its own
pixels. The reference in the same run (``reference_detect``) is the detector as first
written: ``scipy.ndimage``'s median and Gaussian filters and ``sum_labels`` / ``maximum``
over the whole frame. Timed
per window (best of ``--repeat`` passes over the same windows), on 2 ms windows (what
:func:`~edeflare.lights.track_lights`, and so ``edeflare score --detect-lights``, runs)
and 20 ms ones, of the real recordings in ``../shared/data/real`` and, with
``--faery DIR``, faery's 1280x720 night recording (``DIR/evt3.raw``). Every case also
checks that both find the same circles.

Run: ``python benchmarks/bench_lights.py [--faery DIR] [--repeat 3] [--windows 60]``
(writes ``results/lights.json``)
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from _common import REAL, report
from scipy import ndimage

from edeflare.errors import ParameterError
from edeflare.events import iter_time_windows
from edeflare.io import read_events
from edeflare.lights import Circle
from edeflare.lights.detect import count_map_of, detect_light_source


def reference_detect(events: np.ndarray, size: tuple[int, int], max_sources: int) -> list:
    """The detector as first written: scipy's filters and region statistics over the frame."""
    counts = count_map_of(events, size)
    smooth = ndimage.gaussian_filter(
        ndimage.median_filter(counts, size=3, mode="nearest"), 2.0, mode="nearest"
    )
    peak = float(smooth.max())
    if peak <= 0:
        raise ParameterError("no events")
    labels, n = ndimage.label(smooth >= 0.5 * peak, structure=np.ones((3, 3), dtype=bool))
    index = np.arange(1, n + 1)
    area = np.asarray(ndimage.sum_labels(np.ones_like(smooth), labels, index))
    peaks = np.asarray(ndimage.maximum(smooth, labels, index))
    order = [int(i) for i in np.argsort(-peaks, kind="stable") if area[i] >= 4]
    if not order:
        raise ParameterError("no bright region")
    out = []
    for i in order[:max_sources]:
        cy, cx = ndimage.center_of_mass(smooth, labels, i + 1)
        out.append(Circle(float(cx), float(cy), math.sqrt(area[i] / math.pi) + 1.0))
    return out


def _circles(detector, windows: list[np.ndarray], size: tuple[int, int]) -> list:
    out = []
    for w in windows:
        try:
            out.append(detector(w, size, max_sources=2))
        except ParameterError as exc:  # a window without a region: compare the error
            out.append(type(exc).__name__)
    return out


def _time(detector, windows: list[np.ndarray], size: tuple[int, int], repeat: int):
    best, found = np.inf, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        found = _circles(detector, windows, size)
        best = min(best, time.perf_counter() - t0)
    return best / len(windows) * 1000.0, found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--faery", type=Path, help="faery 0.7.1's tests/data (its evt3.raw)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--windows", type=int, default=60, help="windows per case, evenly spread")
    args = parser.parse_args()
    cases = [
        ("Prophesee Gen3 light, 640x480", REAL / "prophesee_gen3_rotating_light.raw"),
        ("DAVIS lamps, 346x260", REAL / "davis346_flicker_lamps.aedat4"),
        ("Gen4.1 day street, 1280x720", REAL / "prophesee_gen41_street.raw"),
    ]
    if args.faery is not None:
        cases.append(("night recording, 1280x720", args.faery / "evt3.raw"))
    rows = []
    for name, path in cases:
        events, size = read_events(path)
        for window_us in (2_000, 20_000):
            windows = [w for _, w in iter_time_windows(events, window_us) if w.size]
            pick = np.unique(np.linspace(0, len(windows) - 1, args.windows).astype(int))
            windows = [windows[i] for i in pick]
            ms, found = _time(detect_light_source, windows, size, args.repeat)
            ref_ms, ref_found = _time(reference_detect, windows, size, args.repeat)
            if found != ref_found:
                raise SystemExit(f"{name}, {window_us} us: the circles differ from the reference")
            rows.append({
                "case": name, "window (ms)": window_us / 1000, "windows": len(windows),
                "detector (ms / window)": round(ms, 2), "reference (ms / window)": round(ref_ms, 2),
                "speedup": round(ref_ms / ms, 2), "same circles": True,
            })  # fmt: skip
    report("lights", rows, list(rows[0]))


if __name__ == "__main__":
    main()
