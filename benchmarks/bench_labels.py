"""Labelling simulated pairs: which input events the ground truth holds (``keep_labels``).

``train-head`` labels every sequence it draws rows from, twice where the pair stores its
light. Streams are stored in time order, so each pixel and polarity's events are grouped by
a counting sort that keeps their order (``keep_labels``), where the reference sorts both
streams by pixel and time first (``lexsort``, then the same matching: what
``keep_labels`` still does for streams in any other order). The same labels, checked here.

Each case: ``N`` input events uniform over a 640x480 sensor and 1 s, and a ground truth of
a random 60 % of them, each moved by up to 0.5 ms (sorted again), matched within 1 ms.

Run: ``python benchmarks/bench_labels.py [--events N ...] [--repeat K]``; writes
``results/labels.json``.
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import best_of, random_events, report

from edeflare.models.head_training import _keys_and_times, _match_sorted_by_key, keep_labels


def pair(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` input events and a ground truth of 60 % of them, jittered in time."""
    inp = random_events(n, (640, 480), 0, 1_000_000)
    gt = inp[rng.random(n) < 0.6].copy()
    gt["t"] = np.clip(gt["t"].astype(np.int64) + rng.integers(-500, 501, gt.size), 0, None)
    return inp, np.sort(gt, order="t", kind="stable")


def reference(inp: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Both streams sorted by pixel, polarity and time, then matched."""
    return _match_sorted_by_key(*_keys_and_times(inp, gt), 1_000)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, nargs="+", default=[1_000_000, 5_000_000, 15_000_000])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    rows = []
    for n in args.events:
        inp, gt = pair(n, rng)
        same = np.array_equal(keep_labels(inp, gt, 1_000), reference(inp, gt))
        new = best_of(lambda: keep_labels(inp, gt, 1_000), args.repeat)  # noqa: B023
        old = best_of(lambda: reference(inp, gt), args.repeat)  # noqa: B023
        rows.append({"events": n, "reference_s": round(old, 3), "keep_labels_s": round(new, 3),
                     "speedup": round(old / new, 2), "same_labels": same})  # fmt: skip
    report("labels", rows, list(rows[0]))


if __name__ == "__main__":
    main()
