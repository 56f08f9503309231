"""``edeflare deflare IN OUT --method NAME``: stream a file through a de-flaring method."""

from __future__ import annotations

import argparse
import math
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
    "De-flare an event file, streaming: with the bundled E-DeflareNet (default), "
    "a model of yours (--model PATH), or a baseline (raw, voxel, efr, pfd-a, pfd-b, "
    "dv-fastdecay, dv-bafilter, dv-knoise: dv-processing's filters, the dv extra)."
)


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

    p = sub.add_parser("deflare", help=HELP, description=HELP, **kwargs)
    p.add_argument("input", type=Path)
    p.add_argument("output", type=Path, help="any writable format, by suffix")
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
        import sys

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return peak / 2**20 if sys.platform == "darwin" else peak / 1024  # bytes / KiB


def run(args: argparse.Namespace) -> int:
    """Build the method, stream the input through it, write the output atomically."""
    from ..methods import deflare_file

    window_us = round(args.window_ms * 1000)
    if window_us <= 0:
        raise EdeflareError(f"--window-ms must be positive, got {args.window_ms}")
    if math.isinf(args.max_lag_ms) and args.max_lag_ms > 0:
        max_lag_us = None
    elif args.max_lag_ms >= 0:
        max_lag_us = round(args.max_lag_ms * 1000)
    else:
        raise EdeflareError(f"--max-lag-ms must be >= 0 or inf, got {args.max_lag_ms}")
    stats = deflare_file(
        args.input,
        args.output,
        args.method,
        window_us,
        args.sensor_size,
        params=method_params(args),
        rng=args.seed,
        max_lag_us=max_lag_us,
        evt_version=args.evt_version,
        group=args.group,
    )
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
