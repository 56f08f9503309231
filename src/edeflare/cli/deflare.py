"""``edeflare deflare IN OUT --method NAME``: stream a file through a de-flaring method."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import EdeflareError, ParameterError
from ._common import GROUP_HELP, SIZE_HELP, sensor_size_arg

HELP = (
    "De-flare an event file, streaming: with the bundled E-DeflareNet (default), "
    "a model of yours (--model PATH), or a baseline (raw, voxel, efr, pfd-a, pfd-b, "
    "dv-fastdecay, dv-bafilter, dv-knoise: dv-processing's filters, the dv extra)."
)


def _ms(value: float) -> int:
    return round(value * 1000)


# option dest -> (methods it applies to, parameter name, converter from the parsed value).
# These options default to SUPPRESS: absent unless given, so a misplaced one is caught.
_OPTIONS: dict[str, tuple[tuple[str, ...], str, Any]] = {
    "efr_frequency": (("efr",), "frequency_hz", float),
    "rho1": (("efr",), "rho1", float),
    "efr_merge_ms": (("efr",), "merge_us", _ms),
    "efr_threshold": (("efr",), "threshold", float),
    "efr_min_bias_events": (("efr",), "min_bias_events", int),
    "efr_shift_back": (("efr",), "shift_back", bool),
    "efr_warmup": (("efr",), "keep_warmup", bool),
    "pfd_window_ms": (("pfd-a", "pfd-b"), "window_us", _ms),
    "pfd_stage1_window_ms": (("pfd-a", "pfd-b"), "stage1_window_us", _ms),
    "pfd_min_support": (("pfd-a", "pfd-b"), "min_support", int),
    "pfd_min_active": (("pfd-a", "pfd-b"), "min_active", int),
    "pfd_fifo_size": (("pfd-a", "pfd-b"), "fifo_size", int),
    "pfd_flip_against_previous": (("pfd-a", "pfd-b"), "flip_against_previous", bool),
    "pfd_real_score": (("pfd-a", "pfd-b"), "real_valued_score", bool),
    "model": (("model",), "weights", str),
    "decoder": (("model",), "decoder", str),
    "device": (("model",), "device", str),
    "batch_windows": (("model",), "batch_windows", int),
    "voxel_window_ms": (("voxel",), "window_us", _ms),
    "voxel_bins": (("voxel",), "bins", int),
}


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    from ..deflare import list_methods

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
    g = p.add_argument_group("model (E-DeflareNet)")
    g.add_argument(
        "--model",
        type=Path,
        default=argparse.SUPPRESS,
        metavar="PATH",
        help="weights (.safetensors) [the bundled model]",
    )
    g.add_argument(
        "--decoder",
        choices=["keep", "paper"],
        default=argparse.SUPPRESS,
        help="keep: edit the input's own events; paper: resample the grid [keep]",
    )
    g.add_argument("--device", default=argparse.SUPPRESS, help="auto, cpu, cuda, cuda:1 [auto]")
    g.add_argument(
        "--batch-windows",
        type=int,
        default=argparse.SUPPRESS,
        metavar="N",
        help="20 ms windows per network call [4]",
    )
    g = p.add_argument_group("efr (paper: 50 Hz, rho1 0.6)")
    g.add_argument(
        "--efr-frequency",
        default=argparse.SUPPRESS,
        type=float,
        metavar="HZ",
        help="base frequency [50]",
    )
    g.add_argument(
        "--rho1",
        default=argparse.SUPPRESS,
        type=float,
        help="feedback gain of the first comb [0.6]",
    )
    g.add_argument(
        "--efr-merge-ms",
        default=argparse.SUPPRESS,
        type=float,
        metavar="MS",
        help="merge window [10]",
    )
    g.add_argument(
        "--efr-threshold",
        default=argparse.SUPPRESS,
        type=float,
        metavar="X",
        help="sampler threshold [0.7]",
    )
    g.add_argument(
        "--efr-bias",
        type=Path,
        default=argparse.SUPPRESS,
        metavar="FILE.npy",
        help="per-pixel bias map (H, W); default: computed over the input (a first pass)",
    )
    g.add_argument(
        "--efr-min-bias-events",
        type=int,
        default=argparse.SUPPRESS,
        metavar="N",
        help="events for a pixel's bias [20]",
    )
    g.add_argument(
        "--efr-shift-back",
        action="store_true",
        default=argparse.SUPPRESS,
        help="move outputs back by the filter delay (then the warm-up is not kept)",
    )
    g.add_argument(
        "--efr-warmup",
        action=argparse.BooleanOptionalAction,
        default=argparse.SUPPRESS,
        help="keep the input events of the first d1+d2 unchanged [yes, unless shifted back]",
    )
    g = p.add_argument_group("pfd-a / pfd-b (paper: 20 ms windows, 3 neighbours)")
    g.add_argument(
        "--pfd-window-ms",
        type=float,
        default=argparse.SUPPRESS,
        metavar="MS",
        help="stage-2 window, and stage-1 unless --pfd-stage1-window-ms [20]",
    )
    g.add_argument(
        "--pfd-stage1-window-ms",
        default=argparse.SUPPRESS,
        type=float,
        metavar="MS",
        help="stage-1 window [20]",
    )
    g.add_argument(
        "--pfd-min-support",
        default=argparse.SUPPRESS,
        type=int,
        metavar="N",
        help="stage-1 'var' [1]",
    )
    g.add_argument(
        "--pfd-min-active",
        type=int,
        default=argparse.SUPPRESS,
        metavar="N",
        help="stage-2 'neibor': keep needs more [3]",
    )
    g.add_argument(
        "--pfd-fifo-size",
        default=argparse.SUPPRESS,
        type=int,
        metavar="N",
        help="flip times kept per pixel [5]",
    )
    g.add_argument(
        "--pfd-flip-against-previous",
        action="store_true",
        default=argparse.SUPPRESS,
        help="count flips against the previous event, not the pixel's first (not the original)",
    )
    g.add_argument(
        "--pfd-real-score",
        action="store_true",
        default=argparse.SUPPRESS,
        help="test the real-valued score <= 1, not the original's truncated int",
    )
    g = p.add_argument_group("voxel (paper: 20 ms, 8 bins)")
    g.add_argument(
        "--voxel-window-ms",
        default=argparse.SUPPRESS,
        type=float,
        metavar="MS",
        help="voxel window [20]",
    )
    g.add_argument(
        "--voxel-bins", default=argparse.SUPPRESS, type=int, metavar="N", help="temporal bins [8]"
    )
    p.set_defaults(func=run)


def method_params(args: argparse.Namespace) -> dict[str, Any]:
    """The method parameters given on the command line (only those given)."""
    params: dict[str, Any] = {}
    for dest, (methods, name, convert) in _OPTIONS.items():
        value = getattr(args, dest, None)
        if value is None:
            continue
        if args.method not in methods:
            flag = "--" + dest.replace("_", "-")
            if dest == "efr_warmup" and not value:
                flag = "--no-efr-warmup"
            raise ParameterError(f"{flag} applies to --method {' or '.join(methods)}")
        params[name] = convert(value)
    if "window_us" in params and args.method.startswith("pfd"):
        params.setdefault("stage1_window_us", params["window_us"])
    bias_path = getattr(args, "efr_bias", None)
    if bias_path is not None:
        if args.method != "efr":
            raise ParameterError("--efr-bias applies to --method efr")
        params["bias"] = _load_bias(bias_path)
    return params


def _load_bias(path: Path) -> np.ndarray:
    from ..errors import EventFileError

    try:
        bias = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise EventFileError(path, f"cannot read a bias map ({exc})") from None
    if not isinstance(bias, np.ndarray) or bias.ndim != 2:
        raise EventFileError(path, "a bias map must be a 2-D (H, W) array in a .npy file")
    return bias


def run(args: argparse.Namespace) -> int:
    """Build the method, stream the input through it, write the output atomically."""
    from ..deflare import deflare_file

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
    return 0
