"""End-to-end de-flaring speed: read, window, network, decode, write, as ``edeflare deflare``.

Each case writes a synthetic recording (uniform random events, a night-driving
density: 0.1, 1 or 3 M events/s over 1 s) as DSEC HDF5, then times
:func:`edeflare.methods.deflare_file` (what ``edeflare deflare`` runs)
in a fresh subprocess (model loading included), and reports

- the real-time factor (``rtf``: the time to read, de-flare and write over the
  recording's span; at most 1 is real time), and the process's start-up
  (``startup_s``: imports and loading the model, paid once per stream),
- the streaming latency: the time from a window's last event to its output
  (median ``latency_ms``, ``p95_ms``, ``max_ms``; :class:`DeflareStats`),
- the peak resident memory of the process (``peak_rss_mib``).

The model rows run the network with torch (``--runtime torch``); the mask
presets judge each event in two windowings (the default ``phase_shift_us``; the
"one view" rows with one) and also run through ONNX Runtime
(``--runtime onnx``: the network exported in memory at start-up), which is what
``--runtime auto`` (the default) picks for mask models on CPU where the ``onnx``
extra is installed.

The reference in the same run is the previous default bundled model (``eflare``,
a ``unet2d.lite`` on full-resolution voxel grids): the ``speedup`` column is its
time over each row's, at the same case. ``mask.pixel`` runs the bundled default
``night`` weights; ``mask.fast`` (the fast preset, no per-pixel refinement) and
``mask.lite`` run untrained weights of the same speed. The
baselines are timed on the same files: ``raw`` (only reading and writing: the
I/O floor), EFR, PFD-A, PFD-B, and dv-processing's FastDecay where installed.

Each case runs ``--repeat`` times (default 2) in fresh processes and the fastest run is
kept (the shared machine's noise only ever adds time).

``--baseline-src CHECKOUT`` adds a row per case for the bundled default of another
checkout (``git worktree add /tmp/old COMMIT``) and for each ``--model`` there, run from
its own source in the same run, and a ``vs_baseline`` column (the other checkout's time
over each row's: a ``--model`` row's against the same model there, every other row's
against its default): the comparable number on a machine whose speed drifts. The repeats
go round all methods of a case in turn.

``--model WEIGHTS`` (repeatable) adds a row per case for another model (a bundled
model's name or a weights file), with the default runtime (``auto``).

Run: ``python benchmarks/bench_realtime.py [--quick] [--repeat N] [--only-street]
[--model WEIGHTS] [--baseline-src CHECKOUT] [--only LABEL ...] [--name NAME]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from _common import PEAK_MIB, REAL, add_model_option, random_events, report

_CHILD = (
    PEAK_MIB
    + r"""
import json, sys, time
t0 = time.perf_counter()
try:
    from edeflare.methods import create_method, deflare_file
except ImportError:  # a --baseline-src checkout from before edeflare.methods
    from edeflare.deflare import create_method, deflare_file
src, dst, method, params = sys.argv[1], sys.argv[2], sys.argv[3], json.loads(sys.argv[4])
m = create_method(method, **params)
stats = deflare_file(src, dst, m, progress=False)
print(json.dumps({"total_s": time.perf_counter() - t0, "seconds": stats.seconds,
                  "events_in": stats.events_in,
                  "span_s": stats.span_us / 1e6, "latency_ms": stats.latency_ms,
                  "peak_rss_mib": peak_mib()}))
"""
)


def _run(code: str, *args: str, src: str | None = None) -> dict[str, float]:
    """Run a child; with ``src``, importing edeflare from that source folder instead."""
    env = None if src is None else {**os.environ, "PYTHONPATH": src}
    out = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, check=True, env=env
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _checkout_src(checkout: str) -> tuple[str, str]:
    """A checkout's ``src`` folder and a label naming its commit."""
    src = Path(checkout).resolve() / "src"
    if not (src / "edeflare").is_dir():
        raise SystemExit(f"--baseline-src: no src/edeflare in {checkout}")
    head = subprocess.run(
        ["git", "-C", checkout, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    )
    return str(src), head.stdout.strip() or Path(checkout).name


def _weights(tmp: Path, preset: str) -> str:
    """Bundled weights for the preset if shipped, else an untrained (same-speed) model."""
    from edeflare.models import create_model
    from edeflare.models.infer import bundled_weights
    from edeflare.models.weights import ModelCard, load_model, save_model

    for name in ("night", "eflare"):
        try:
            path = bundled_weights(name)
        except Exception:
            continue
        if load_model(path, "cpu")[1].preset == preset:
            return str(path)
    path = tmp / f"{preset}.safetensors"
    save_model(path, create_model(preset), ModelCard(preset=preset))
    return str(path)


_STREET = "prophesee_gen41_street.raw"
_STREET_SPAN_US = 180_000


def _tiled_street(dst: Path) -> tuple[int, int] | None:
    """The Gen4.1 street tiled in time to 0.18 s, written to ``dst``; its sensor size, or
    None where ../shared/data/real is absent."""
    from edeflare.events import concat_events
    from edeflare.io import read_events, write_events

    if not (REAL / _STREET).is_file():
        return None
    rec = read_events(REAL / _STREET)
    t = rec.events["t"].astype(np.int64) - int(rec.events["t"][0])
    span = int(t[-1]) + 1
    tiles = []
    for k in range(-(-_STREET_SPAN_US // span)):
        tile = rec.events.copy()
        tile["t"] = t + k * span
        tiles.append(tile)
    tiled = concat_events(tiles)
    write_events(dst, tiled[tiled["t"] < _STREET_SPAN_US], rec.sensor_size)
    return rec.sensor_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="640x480 at 1 M ev/s only")
    parser.add_argument("--repeat", type=int, default=2, help="runs per case; the fastest is kept")
    parser.add_argument(
        "--only-street",
        action="store_true",
        help="the tiled Gen4.1 street case alone (writes realtime_street.json)",
    )
    add_model_option(parser, "also time this model on every case, with the default runtime")
    parser.add_argument(
        "--baseline-src",
        metavar="CHECKOUT",
        help="also time the default model of another checkout of edeflare (e.g. a git "
        "worktree of an older commit) on every case, in the same run",
    )
    parser.add_argument(
        "--only",
        nargs="+",
        metavar="LABEL",
        help="time only the methods of these row labels (e.g. 'model learned' for --model "
        "learned, 'model mask.pixel (onnx)' for the default, raw); the speedup column needs "
        "'model unet2d.lite'",
    )
    parser.add_argument(
        "--name", help="the results' file name (default: realtime, or realtime_street)"
    )
    args = parser.parse_args()
    baseline = None if args.baseline_src is None else _checkout_src(args.baseline_src)
    only = None if args.only is None else set(args.only)
    from edeflare.io import write_events

    synthetic = (
        [((640, 480), 1_000_000)]
        if args.quick
        else [
            ((640, 480), 100_000),
            ((640, 480), 1_000_000),
            ((640, 480), 3_000_000),
            ((1280, 720), 1_000_000),
        ]
    )
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        presets = ("unet2d.lite", "mask.pixel", "mask.fast", "mask.lite")
        models = {p: _weights(tmp, p) for p in presets}
        methods: list[tuple[str, str, dict[str, str]]] = [
            (f"model {p}", "model", {"weights": w, "runtime": "torch"}) for p, w in models.items()
        ]
        methods += [
            (f"model {p} (onnx)", "model", {"weights": models[p], "runtime": "onnx"})
            for p in ("mask.pixel", "mask.fast")
        ]
        # mask models judge each event in two windowings by default; one is half the work
        methods += [
            (f"model {p} (onnx, one view)", "model", {**params, "phase_shift_us": 0})
            for p, params in (
                ("mask.pixel", {"weights": models["mask.pixel"], "runtime": "onnx"}),
                ("mask.fast", {"weights": models["mask.fast"], "runtime": "onnx"}),
            )
        ]
        extra = [(f"model {Path(w).stem}", "model", {"weights": w}) for w in args.model]
        methods += extra
        methods += [(m, m, {}) for m in ("raw", "efr", "pfd-a", "pfd-b", "dv-fastdecay")]
        if only is not None:
            methods = [m for m in methods if m[0] in only]
        cases: list[tuple[Path, tuple[int, int], str, list[tuple[str, str, dict[str, str]]]]] = []
        if not args.only_street:
            for size, rate in synthetic:
                src = tmp / f"in_{size[0]}_{rate}.h5"
                write_events(src, random_events(rate, size, 0, 1_000_000, seed=1), size)
                cases.append((src, size, f"{rate / 1e6:g}", methods))
        street = tmp / "gen41_street_tiled.h5"
        street_size = None if args.quick else _tiled_street(street)
        if street_size is not None:
            dense = [
                (f"model {p} (onnx)", "model", {"weights": w, "runtime": "onnx"})
                for p, w in (("mask.pixel", models["mask.pixel"]), ("general", "general"))
            ]
            one_view = {**dense[0][2], "phase_shift_us": 0}
            dense.insert(1, ("model mask.pixel (onnx, one view)", "model", one_view))
            dense += extra
            dense += [(m, m, {}) for m in ("raw", "pfd-a", "dv-fastdecay")]
            if only is not None:
                dense = [m for m in dense if m[0] in only]
            cases.append((street, street_size, "Gen4.1 street x20", dense))
        elif not args.quick:
            print(f"skip the street case: no {REAL / _STREET}", file=sys.stderr)
        for src, size, rate_label, case_methods in cases:
            ref = None
            # the other checkout's rows: its default, and each --model run by its code; a
            # --model row is compared with its own model's there, every other with the default
            tag = None if baseline is None else f" @ {baseline[1]}"
            base_label = None if tag is None else f"default{tag}"
            base_rows: list[tuple[str, str, dict[str, str]]] = []
            if tag is not None:
                base_rows = [(base_label, "model", {})]
                base_rows += [(f"{label}{tag}", m, prm) for label, m, prm in extra]
                case_methods = [*base_rows, *case_methods]
            base_labels = {label for label, _, _ in base_rows}
            # the repeats go round the methods, so a drift in the machine's speed touches
            # every method alike
            runs: dict[str, list[dict[str, float]]] = {}
            failed: set[str] = set()
            for _ in range(max(1, args.repeat)):
                for label, method, params in case_methods:
                    if label in failed:
                        continue
                    dst = tmp / "out.h5"
                    code_src = baseline[0] if label in base_labels else None
                    try:
                        run = _run(
                            _CHILD, str(src), str(dst), method, json.dumps(params), src=code_src
                        )
                    except subprocess.CalledProcessError as exc:
                        err = exc.stderr.strip().splitlines()[-1]
                        print(f"skip {label}: {err}", file=sys.stderr)
                        failed.add(label)
                        continue
                    dst.unlink(missing_ok=True)
                    runs.setdefault(label, []).append(run)
            best = {label: min(r, key=lambda run: run["seconds"]) for label, r in runs.items()}
            for label, _, _ in case_methods:
                if label in failed or label not in runs:
                    continue
                r = best[label]
                own = f"{label.removesuffix(tag)}{tag}" if tag is not None else None
                against = own if own in base_labels and own != base_label else base_label
                base = best[against]["seconds"] if against in best else None
                if label == "model unet2d.lite":
                    ref = r["seconds"]
                p50, p95, worst = r["latency_ms"]
                row: dict[str, object] = {
                    "sensor": f"{size[0]}x{size[1]}",
                    "Mev/s": rate_label,
                    "method": label,
                    "rtf": r["seconds"] / r["span_s"],
                    "speedup": (ref / r["seconds"]) if ref else "",
                    "vs_baseline": (base / r["seconds"]) if base else "",
                    "throughput": r["events_in"] / r["seconds"] / 1e6,
                    "latency_ms": p50,
                    "p95_ms": p95,
                    "max_ms": worst,
                    "startup_s": r["total_s"] - r["seconds"],
                    "peak_rss_mib": r["peak_rss_mib"],
                }
                rows.append(row)
                print(row, file=sys.stderr)
    report(
        args.name or ("realtime_street" if args.only_street else "realtime"),
        rows,
        [
            "sensor",
            "Mev/s",
            "method",
            "rtf",
            "speedup",
            *(["vs_baseline"] if baseline is not None else []),
            "throughput",
            "latency_ms",
            "p95_ms",
            "max_ms",
            "startup_s",
            "peak_rss_mib",
        ],
    )


if __name__ == "__main__":
    main()
