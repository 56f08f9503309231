"""``edeflare deflare IN OUT --method NAME``: stream a file through a de-flaring method.

Given a folder, a glob pattern or several files, it de-flares each into the
output folder (:func:`edeflare.methods.batch.deflare_files`): ``--workers``,
``--shard``, resumed by a rerun, a summary table at the end.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from ..errors import EdeflareError
from ._common import (
    GROUP_HELP,
    SIZE_HELP,
    add_param_options,
    param_options,
    sensor_size_arg,
)

HELP = (
    "De-flare an event file, streaming: with the bundled default model (night: a flare mask "
    "network and its priors), another bundled model or one of yours (--model NAME|PATH), "
    "or a baseline (raw, voxel, efr, pfd-a, pfd-b, "
    "dv-fastdecay, dv-bafilter, dv-knoise: dv-processing's filters, the dv extra)."
)
BATCH_HELP = (
    "Given a folder, a glob pattern (quoted: 'drives/**/*.raw') or several files, OUT is a "
    "folder: one output per input, mirroring the subfolders, in parallel (--workers) or "
    "split over array jobs (--shard); a rerun skips the outputs complete for the same input "
    "and method (OUT/manifest.json) and redoes the others; a file that fails is reported "
    "and the others go on (exit status 1)."
)
_BATCH_DEFAULTS = {"workers": 1, "shard": "0/1", "suffix": ".h5"}


def _param_groups() -> list[tuple[type, tuple[str, ...]]]:
    """Each declared parameter dataclass and the methods using it, in registration order."""
    from ..methods import METHODS

    groups: dict[type, list[str]] = {}
    for name in METHODS:
        params = METHODS.params(name)
        if params is not None:
            groups.setdefault(params, []).append(name)
    return [(params, tuple(names)) for params, names in groups.items()]


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    from ..methods import list_methods

    p = sub.add_parser("deflare", help=HELP, description=HELP + " " + BATCH_HELP, **kwargs)
    p.add_argument(
        "inputs",
        nargs="+",
        metavar="IN",
        help="an event file; or a folder (its files with a binary event suffix, subfolders "
        "included), a glob pattern or several files",
    )
    p.add_argument(
        "output",
        type=Path,
        metavar="OUT",
        help="any writable format, by suffix; a folder for several inputs",
    )
    p.add_argument("-m", "--method", default="model", choices=list_methods())
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    p.add_argument("--group", help=GROUP_HELP)
    p.add_argument("--window-ms", type=float, default=20.0, help="streaming window (ms)")
    p.add_argument("--seed", type=int, help="seed of methods that draw (voxel, model)")
    p.add_argument(
        "--max-lag-ms",
        type=float,
        default=10_000.0,
        help="efr: hold outputs stamped this far in the past at most ('inf': exact, "
        "unbounded memory); later ones are dropped with a warning",
    )
    p.add_argument(
        "--evt-version",
        default="evt2",
        choices=["evt2", "evt3"],
        help="encoding of .raw outputs (EVT 3.0 output must span under 16.8 s)",
    )
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="also print the speed: run time, real-time factor, per-window latency, peak memory",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    g = p.add_argument_group("several files (a folder, a glob pattern or a list as IN)")
    g.add_argument(
        "--workers",
        type=int,
        default=_BATCH_DEFAULTS["workers"],
        metavar="N",
        help="worker processes, each building the method once",
    )
    g.add_argument(
        "--shard",
        default=_BATCH_DEFAULTS["shard"],
        metavar="I/N",
        help="de-flare the files whose index in the sorted list %% N == I "
        "(a SLURM array task: --shard $SLURM_ARRAY_TASK_ID/10)",
    )
    g.add_argument(
        "--suffix",
        default=_BATCH_DEFAULTS["suffix"],
        help="the outputs' format; 'keep' keeps each input's",
    )
    for params, methods in _param_groups():  # --model, --efr-*, --pfd-*, --voxel-*
        add_param_options(p, params, methods)
    p.set_defaults(func=run)


def method_params(args: argparse.Namespace) -> dict[str, Any]:
    """The method parameters given on the command line (only those given)."""
    params: dict[str, Any] = {}
    for group, methods in _param_groups():
        params.update(param_options(args, group, args.method, methods))
    if "window_us" in params and args.method.startswith("pfd"):
        params.setdefault("stage1_window_us", params["window_us"])
    return params


def _peak_memory_mb() -> float:
    """This process's peak resident memory (MB)."""
    try:  # Linux: this process image's own high-water mark
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmHWM")) / 1024
    except (OSError, StopIteration, ValueError):
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return peak / 2**20 if sys.platform == "darwin" else peak / 1024  # bytes / KiB


def _is_batch(inputs: list[str]) -> bool:
    """Several inputs, a folder, or a pattern that is not a file's name."""
    if len(inputs) > 1:
        return True
    path = Path(inputs[0])
    return path.is_dir() or (not path.exists() and any(c in inputs[0] for c in "*?["))


def run(args: argparse.Namespace) -> int:
    """Build the method, stream the input through it, write the output atomically."""
    from ..methods import deflare_file

    window_us, max_lag_us = _run_options(args)
    if _is_batch(args.inputs):
        args.resumes = True  # an interrupted batch says how to resume
        return _run_batch(args, window_us, max_lag_us)
    given = [f"--{k}" for k, v in _BATCH_DEFAULTS.items() if getattr(args, k) != v]
    if given:
        raise EdeflareError(
            f"{', '.join(given)} apply to several files: give a folder, a glob pattern or "
            "several files as IN"
        )
    args.input = Path(args.inputs[0])
    stats = deflare_file(args.input, args.output, **_stream_options(args, window_us, max_lag_us))
    kept = stats.events_out / stats.events_in if stats.events_in else 0.0
    print(
        f"{args.method}: {stats.events_in:,} events in, {stats.events_out:,} out "
        f"({kept:.1%}); wrote {args.output}"
    )
    if args.verbose:
        p50, p95, worst = stats.latency_ms
        peak_mb = _peak_memory_mb()
        print(
            f"{args.method}: {stats.seconds:.2f} s for {stats.span_us / 1e6:.3f} s of events "
            f"(real-time factor {stats.real_time_factor:.3g}); latency from a "
            f"{args.window_ms:g} ms window's last event to its output: median {p50:.1f} ms, "
            f"p95 {p95:.1f} ms, max {worst:.1f} ms; peak memory {peak_mb:,.0f} MB"
        )
    return 0


def _run_options(args: argparse.Namespace) -> tuple[int, int | None]:
    """``--window-ms`` and ``--max-lag-ms`` in microseconds (checked)."""
    window_us = round(args.window_ms * 1000)
    if window_us <= 0:
        raise EdeflareError(f"--window-ms must be positive, got {args.window_ms}")
    if math.isinf(args.max_lag_ms) and args.max_lag_ms > 0:
        max_lag_us = None
    elif args.max_lag_ms >= 0:
        max_lag_us = round(args.max_lag_ms * 1000)
    else:
        raise EdeflareError(f"--max-lag-ms must be >= 0 or inf, got {args.max_lag_ms}")
    return window_us, max_lag_us


def _stream_options(
    args: argparse.Namespace, window_us: int, max_lag_us: int | None
) -> dict[str, Any]:
    """What one file and a batch are de-flared with: the method and the streaming options."""
    return {
        "method": args.method,
        "window_us": window_us,
        "sensor_size": args.sensor_size,
        "params": method_params(args),
        "rng": args.seed,
        "max_lag_us": max_lag_us,
        "evt_version": args.evt_version,
        "group": args.group,
        "progress": False if args.no_progress else None,
    }


def _run_batch(args: argparse.Namespace, window_us: int, max_lag_us: int | None) -> int:
    """De-flare every input file into the output folder; a summary table; 1 if any failed."""
    from ..methods.batch import FileResult, deflare_files

    if args.verbose:
        raise EdeflareError("-v applies to one file; the summary table gives each file's time")

    def report_failure(result: FileResult) -> None:
        if result.status == "failed":
            from tqdm import tqdm  # writes above a progress bar, if one is drawn

            tqdm.write(f"edeflare: error: {result.error}", file=sys.stderr)

    report = deflare_files(
        args.inputs,
        args.output,
        **_stream_options(args, window_us, max_lag_us),
        suffix=None if args.suffix == "keep" else args.suffix,
        workers=args.workers,
        shard=args.shard,
        on_file=report_failure,
    )
    print(report.table())
    n = len(report.files)
    state = "all inputs complete" if report.complete else "not all inputs complete"
    print(
        f"{args.method}: {len(report.done)} de-flared, {len(report.skipped)} already done, "
        f"{len(report.failed)} failed, of {n} file{'s' if n != 1 else ''} "
        f"({report.seconds:.1f} s); {state}; manifest {report.manifest_path}"
    )
    return 1 if report.failed else 0
