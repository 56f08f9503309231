"""Speed and memory of event file I/O.

1. DSEC HDF5 write and read of 10 M events, against ``np.save``/``np.load``
   of the same structured array (uncompressed, the floor for any format).
2. Streaming a DSEC file larger than a chosen memory budget in 20 ms
   windows: peak RSS of the streaming process against a process that reads
   the whole file (each measured in a fresh subprocess).

Run: ``python benchmarks/bench_io.py [--events 10000000] [--stream-events 40000000]``
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import best_of, random_events, report

from edeflare.io import read_events, write_events
from edeflare.io.dsec import DsecWriter

_CHILD = r"""
import sys, time
from edeflare.io import iter_windows, read_events
path, mode = sys.argv[1], sys.argv[2]
t0 = time.perf_counter()
n = windows = 0
if mode == "stream":
    for _, w in iter_windows(path, 20_000):
        n += w.size
        windows += 1
else:
    n = read_events(path).events.size
# VmHWM (peak RSS of this process image); ru_maxrss would include the forking parent's.
hwm = next(l for l in open("/proc/self/status") if l.startswith("VmHWM")).split()[1]
print(n, windows, time.perf_counter() - t0, hwm)
"""


def _child(path: Path, mode: str) -> tuple[int, int, float, float]:
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, str(path), mode], check=True, capture_output=True, text=True
    ).stdout.split()
    return int(out[0]), int(out[1]), float(out[2]), int(out[3]) / 1024  # VmHWM is in KiB


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--events", type=int, default=10_000_000)
    parser.add_argument("--stream-events", type=int, default=40_000_000)
    args = parser.parse_args()
    size = (640, 480)
    rows = []
    with tempfile.TemporaryDirectory(dir=Path(__file__).parent) as tmp:
        tmp = Path(tmp)
        # 10 M events over 10 s (1 Mev/s, a busy driving scene).
        events = random_events(args.events, size, 1_600_000_000_000_000, 10_000_000)
        h5, npy = tmp / "ev.h5", tmp / "ev.npy"
        t_w = best_of(lambda: write_events(h5, events, size), repeat=2)
        t_r = best_of(lambda: read_events(h5), repeat=2)
        assert np.array_equal(read_events(h5).events, events)
        t_ws = best_of(lambda: np.save(npy, events), repeat=2)
        t_rs = best_of(lambda: np.load(npy), repeat=2)
        mb_h5, mb_npy = h5.stat().st_size / 2**20, npy.stat().st_size / 2**20
        for op, t, ref, mb in (("write", t_w, t_ws, mb_h5), ("read", t_r, t_rs, mb_h5)):
            rows.append(
                {
                    "case": f"DSEC {op} 10M",
                    "seconds": t,
                    "Mev_per_s": args.events / t / 1e6,
                    "reference": f"np.{'save' if op == 'write' else 'load'} {ref:.3f}s",
                    "ratio_vs_ref": t / ref,
                    "file_MiB": mb,
                    "peak_RSS_MiB": "",
                }
            )
        rows.append(
            {
                "case": "npy (reference)",
                "seconds": t_ws + t_rs,
                "Mev_per_s": "",
                "reference": "",
                "ratio_vs_ref": 1.0,
                "file_MiB": mb_npy,
                "peak_RSS_MiB": "",
            }
        )

        # A file larger than the memory budget, written chunk by chunk.
        big = tmp / "big.h5"
        n_big = args.stream_events
        per_chunk = 2_000_000
        t0 = time.perf_counter()
        with DsecWriter(big, size) as writer:
            for k in range(0, n_big, per_chunk):
                span = 2_000_000  # 2 s per chunk: 1 Mev/s
                writer.append(
                    random_events(
                        min(per_chunk, n_big - k), size, k // per_chunk * span, span, seed=k
                    )
                )
        t_big = time.perf_counter() - t0
        in_memory_mib = n_big * 13 / 2**20
        n_s, windows, t_s, rss_s = _child(big, "stream")
        n_f, _, t_f, rss_f = _child(big, "full")
        assert n_s == n_f == n_big
        rows.append(
            {
                "case": f"stream {n_big // 10**6}M in 20 ms windows",
                "seconds": t_s,
                "Mev_per_s": n_big / t_s / 1e6,
                "reference": f"read whole {t_f:.2f}s",
                "ratio_vs_ref": rss_s / rss_f,
                "file_MiB": big.stat().st_size / 2**20,
                "peak_RSS_MiB": rss_s,
            }
        )
        rows.append(
            {
                "case": f"read whole {n_big // 10**6}M (reference)",
                "seconds": t_f,
                "Mev_per_s": n_big / t_f / 1e6,
                "reference": "",
                "ratio_vs_ref": 1.0,
                "file_MiB": big.stat().st_size / 2**20,
                "peak_RSS_MiB": rss_f,
            }
        )
    report(
        "io",
        rows,
        ["case", "seconds", "Mev_per_s", "reference", "ratio_vs_ref", "file_MiB", "peak_RSS_MiB"],
    )
    print(
        f"\nstreaming {windows} windows of a file holding {in_memory_mib:.0f} MiB of events "
        f"(written in {t_big:.1f}s): peak RSS {rss_s:.0f} MiB vs {rss_f:.0f} MiB reading it whole"
    )


if __name__ == "__main__":
    main()
