"""Peak memory of ``info``, ``convert`` and ``deflare`` on a long file, in every format.

For each format, a recording of ``--events`` uniform random events (default
40 M over 40 s at 640x480) is written once; then each command runs in a fresh
process (``edeflare.cli.main``) and reports its peak resident memory
(``VmHWM``). The reference in the same run is reading the same file whole
(``edeflare.io.read_events``): the ``vs whole`` column is that peak over the
command's. Streaming holds one chunk and one 20 ms window, so a command's peak
should not grow with the recording (``--events`` at two sizes shows it).

Run: ``python benchmarks/bench_memory.py [--events 40000000] [--formats .h5 .raw ...]
[--name memory]`` (``--name``: the results file, for a run of some formats only).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from _common import PEAK_MIB, random_events, report

_CHILD = (
    PEAK_MIB
    + r"""
import json, sys, time
args = json.loads(sys.argv[1])
t0 = time.perf_counter()
if args[0] == "read-whole":
    from edeflare.io import read_events
    n = read_events(args[1]).events.size
    code = 0
else:
    from edeflare.cli import main
    code = main(args)
print(json.dumps({"code": code, "seconds": time.perf_counter() - t0,
                  "peak_mib": peak_mib()}))
"""
)

FORMATS = (".h5", ".npz", ".raw", ".aedat4", ".es", ".dat", ".csv")


def _run(args: list[str]) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, json.dumps(args)], capture_output=True, text=True
    )
    if out.returncode != 0:
        raise RuntimeError(out.stderr.strip().splitlines()[-1] if out.stderr else "failed")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _write(path: Path, n: int, size: tuple[int, int], chunk: int = 5_000_000) -> None:
    """Write ``n`` events over ``n`` microseconds (1 M events/s) in chunks (bounded memory)."""
    from edeflare.io import write_event_chunks

    def chunks() -> Iterator[np.ndarray]:
        for k, start in enumerate(range(0, n, chunk)):
            m = min(chunk, n - start)
            ev = random_events(m, size, start, m, seed=k)
            yield ev

    write_event_chunks(path, chunks(), size)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--events", type=int, default=40_000_000)
    parser.add_argument("--formats", nargs="+", default=list(FORMATS))
    parser.add_argument("--name", default="memory", help="results/<name>.json")
    args = parser.parse_args()
    size = (640, 480)
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        for suffix in args.formats:
            src = tmp / f"rec{suffix}"
            t0 = time.perf_counter()
            try:
                _write(src, args.events, size)
            except Exception as exc:  # a format that cannot hold this recording
                print(f"skip {suffix}: {exc}", file=sys.stderr)
                continue
            write_s = time.perf_counter() - t0
            whole = _run(["read-whole", str(src)])
            commands = {
                "info": ["info", str(src)],
                "convert to .h5": ["convert", str(src), str(tmp / "out.h5")],
                "deflare -m pfd-a": ["deflare", str(src), str(tmp / f"out{suffix}"), "-m", "pfd-a"],
            }
            for name, cmd in commands.items():
                r = _run(cmd)
                rows.append(
                    {
                        "format": suffix,
                        "events": args.events,
                        "MB": round(src.stat().st_size / 1e6),
                        "command": name,
                        "peak_mib": r["peak_mib"],
                        "whole_read_mib": whole["peak_mib"],
                        "vs_whole": whole["peak_mib"] / r["peak_mib"],
                        "seconds": r["seconds"],
                        "write_s": write_s,
                    }
                )
                print(rows[-1], file=sys.stderr)
                for out in tmp.glob("out*"):
                    out.unlink()
            src.unlink()
    report(
        args.name,
        rows,
        ["format", "events", "MB", "command", "peak_mib", "whole_read_mib", "vs_whole", "seconds"],
    )


if __name__ == "__main__":
    main()
