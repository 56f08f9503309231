"""Speed of the metrics.

1. Chamfer + Gaussian distance (one nearest-neighbour search) for N restored
   vs N ground-truth events in one 20 ms window on 640x480, N = 200 k and 1 M,
   against a brute-force chunked numpy reference (all pairwise distances).
   The reference is timed on a subsample of restored events and scaled
   linearly (its cost is exactly proportional to the number of restored
   events), and checked to give the same distances on that subsample.
   Target: at least 100x at 200 k; 1 M vs 1 M within a few seconds.
2. The whole eight-metric suite on one 20 ms 640x480 segment pair of about
   200 k events each: milliseconds per segment.
3. Finding one stream's events in another (``edeflare.events.isin_keys``, what
   the deletion shares and the simulator's sparse sensing use) against
   ``numpy.isin`` on the same keys: 1.3 M sorted events of 100 ms on 346x260
   against a 0.6 M subset of them, checked equal.

Run: ``python benchmarks/bench_metrics.py``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import best_of, random_events, report

from edeflare.eval.metrics import (
    event_distances,
    nearest_distances,
    normalize_events,
    segment_metrics,
)
from edeflare.events import event_keys, isin_keys, merge_events

SIZE, START, WIN = (640, 480), 1_000_000, 20_000


def brute_force(gt_pts: np.ndarray, pred_pts: np.ndarray, chunk: int = 256) -> np.ndarray:
    """Exact nearest distances by computing every pair, ``chunk`` restored events at a time."""
    gt_sq = (gt_pts * gt_pts).sum(1)
    out = np.empty(len(pred_pts))
    for i in range(0, len(pred_pts), chunk):
        p = pred_pts[i : i + chunk]
        d2 = (p * p).sum(1)[:, None] + gt_sq[None, :] - 2.0 * p @ gt_pts.T
        out[i : i + chunk] = np.sqrt(np.maximum(d2.min(axis=1), 0.0))
    return out


def pair(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Ground truth and a restored stream sharing 70 % of its events plus 30 % noise."""
    gt = random_events(n, SIZE, START, WIN, seed=seed)
    keep = np.random.default_rng(seed + 1).random(n) < 0.7
    noise = random_events(n - int(keep.sum()), SIZE, START, WIN, seed=seed + 2)
    return gt, merge_events(gt[keep], noise)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--subsample", type=int, default=2000, help="restored events timed brute force"
    )
    args = parser.parse_args()
    rows = []
    for n in (200_000, 1_000_000):
        gt, pred = pair(n, seed=n)
        t_ours = best_of(lambda gt=gt, pred=pred: event_distances(gt, pred, SIZE, START, WIN), 2)
        sub = pred[np.random.default_rng(0).choice(len(pred), args.subsample, replace=False)]
        sub.sort(order="t", kind="stable")
        gt_pts = normalize_events(gt, SIZE, START, WIN)
        sub_pts = normalize_events(sub, SIZE, START, WIN)
        t0 = time.perf_counter()
        ref = brute_force(gt_pts, sub_pts)
        t_sub = time.perf_counter() - t0
        ours_sub = nearest_distances(gt, sub, SIZE, START, WIN)
        np.testing.assert_allclose(ours_sub, ref, rtol=1e-6, atol=1e-5)  # expansion rounding
        t_ref = t_sub * len(pred) / args.subsample
        rows.append(
            {
                "case": f"Chamfer+Gaussian {n // 1000}k vs {n // 1000}k",
                "seconds": t_ours,
                "reference_s": t_ref,
                "speedup": t_ref / t_ours,
                "note": f"reference: brute force on {args.subsample} events, scaled",
            }
        )
    gt, pred = pair(200_000, seed=7)
    t_suite = best_of(lambda: segment_metrics(gt, pred, SIZE, START, WIN), 3)
    rows.append(
        {
            "case": "all 8 metrics, one 20 ms 640x480 segment, 200k events",
            "seconds": t_suite,
            "reference_s": "",
            "speedup": "",
            "note": f"{t_suite * 1000:.0f} ms per segment",
        }
    )
    size = (346, 260)  # an eflare-night sequence's input and its true events
    ev = random_events(1_300_000, size, 0, 100_000, seed=3)
    keys = event_keys(ev, size)
    part = event_keys(ev[np.random.default_rng(4).random(ev.size) < 0.48], size)
    assert np.array_equal(isin_keys(keys, part), np.isin(keys, part))
    t_isin = best_of(lambda: isin_keys(keys, part), 3)
    t_numpy = best_of(lambda: np.isin(keys, part), 3)
    rows.append(
        {
            "case": "events of one stream in another, 1.3 M in 0.6 M",
            "seconds": t_isin,
            "reference_s": t_numpy,
            "speedup": t_numpy / t_isin,
            "note": "reference: numpy.isin on the same keys",
        }
    )
    report("metrics", rows, ["case", "seconds", "reference_s", "speedup", "note"])


if __name__ == "__main__":
    main()
