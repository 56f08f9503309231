"""Speed of the voxel codec.

- encode: 10 M events into an 8x480x640 grid, against the ``np.bincount``
  reference (flat index + weighted bincount + float32 cast) in the same run.
  Target: at least 3x faster.
- decode: a grid holding about 20 M events back into sorted events.
  Target: at least 20 M events/s.

Run: ``python benchmarks/bench_voxel.py [--events 10000000]``
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import best_of, random_events, report

from edeflare.voxel import decode, encode


def bincount_reference(
    events: np.ndarray, sensor_size: tuple[int, int], start: int, window: int, bins: int
) -> np.ndarray:
    """The straightforward numpy encoder the fast path is measured against."""
    width, height = sensor_size
    b = (events["t"] - start) * bins // window
    flat = (b * height + events["y"]) * width + events["x"]
    sign = events["p"].astype(np.float32) * 2 - 1
    grid = np.bincount(flat, weights=sign, minlength=bins * height * width)
    return grid.astype(np.float32).reshape(bins, height, width)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--events", type=int, default=10_000_000)
    args = parser.parse_args()
    size, window, bins = (640, 480), 20_000, 8
    events = random_events(args.events, size, 1_000_000, window)
    ours = encode(events, size, 1_000_000, window, bins)
    ref = bincount_reference(events, size, 1_000_000, window, bins)
    assert np.array_equal(ours, ref), "encode disagrees with the reference"
    t_ours = best_of(lambda: encode(events, size, 1_000_000, window, bins))
    t_ref = best_of(lambda: bincount_reference(events, size, 1_000_000, window, bins))

    rng = np.random.default_rng(1)
    target = 2 * args.events  # about 20 M events to decode
    lam = target / (bins * size[0] * size[1])
    grid = rng.poisson(lam, (bins, size[1], size[0])) * rng.choice(
        [-1, 1], (bins, size[1], size[0])
    )
    grid = grid.astype(np.float32)
    n_dec = int(np.abs(grid).sum())
    t_dec = best_of(lambda: decode(grid, 0, window, rng=0))
    rows = [
        {
            "operation": "encode (edeflare, numba)",
            "events": args.events,
            "seconds": t_ours,
            "Mev_per_s": args.events / t_ours / 1e6,
            "vs_reference": t_ref / t_ours,
        },
        {
            "operation": "encode (np.bincount reference)",
            "events": args.events,
            "seconds": t_ref,
            "Mev_per_s": args.events / t_ref / 1e6,
            "vs_reference": 1.0,
        },
        {
            "operation": "decode (edeflare)",
            "events": n_dec,
            "seconds": t_dec,
            "Mev_per_s": n_dec / t_dec / 1e6,
            "vs_reference": "",
        },
    ]
    report("voxel", rows, ["operation", "events", "seconds", "Mev_per_s", "vs_reference"])
    print(f"\nencode speed-up over np.bincount: {t_ref / t_ours:.1f}x (target >= 3x)")
    print(f"decode throughput: {n_dec / t_dec / 1e6:.1f} M events/s (target >= 20)")


if __name__ == "__main__":
    main()
