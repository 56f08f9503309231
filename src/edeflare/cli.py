"""The ``edeflare`` command line: a thin layer that parses options and calls the library.

User errors print one line (``edeflare: error: ...``) to stderr and exit 1;
nothing is half-written.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from . import __version__
from .errors import EdeflareError, EventsError
from .events import SensorSize, center_crop, crop, parse_sensor_size

__all__ = ["main"]


def _size(text: str) -> SensorSize:
    try:
        return parse_sensor_size(text)
    except EventsError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _crop_spec(text: str) -> tuple[int, int, int, int] | SensorSize:
    """``WxH`` (centre crop) or ``X,Y,W,H``."""
    if "," in text:
        try:
            x0, y0, w, h = (int(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"crop must be WxH or X,Y,W,H, got {text!r}") from None
        return x0, y0, w, h
    return _size(text)


def _ms_to_us(ms: float | None) -> int | None:
    return None if ms is None else round(ms * 1000)


# -- info ------------------------------------------------------------------------------
def _cmd_info(args: argparse.Namespace) -> int:
    from .io import open_events

    src = open_events(args.file, args.sensor_size)
    n = n_on = 0
    first = last = None
    with tqdm(total=src.n_events, unit="ev", unit_scale=True, disable=None, leave=False) as bar:
        for chunk in src.chunks():
            n += chunk.size
            n_on += int(chunk["p"].sum())
            if first is None:
                first = int(chunk["t"][0])
            last = int(chunk["t"][-1])
            bar.update(chunk.size)
    width, height = src.sensor_size
    print(f"file        {src.path}")
    print(f"format      {src.format}")
    print(f"sensor      {width}x{height} ({src.sensor_size_source})")
    print(f"events      {n:,}")
    if n:
        span = last - first  # type: ignore[operator]
        print(f"first t     {first} µs")
        print(f"last t      {last} µs")
        print(f"span        {span / 1000:.3f} ms")
        rate = n / (span / 1e6) if span else float("inf")
        print(f"rate        {rate / 1e6:.3f} Mev/s")
        print(f"ON fraction {n_on / n:.4f}")
    return 0


# -- convert ---------------------------------------------------------------------------
def _cmd_convert(args: argparse.Namespace) -> int:
    from .io import open_events, write_event_chunks

    src = open_events(args.input, args.sensor_size)
    size = src.sensor_size
    out_size = size
    if args.crop is not None:
        out_size = args.crop if len(args.crop) == 2 else tuple(args.crop[2:])  # type: ignore[assignment]
    t_lo, t_hi = _ms_to_us(args.start_ms), _ms_to_us(args.end_ms)

    def chunks(bar: tqdm) -> Iterator[np.ndarray]:
        for events in src.chunks():
            bar.update(events.size)
            if t_lo is not None or t_hi is not None:
                t = events["t"]
                keep = np.ones(t.size, dtype=bool)
                if t_lo is not None:
                    keep &= t >= t_lo
                if t_hi is not None:
                    keep &= t < t_hi
                events = events[keep]
            if args.crop is not None:
                if len(args.crop) == 2:
                    events, _ = center_crop(events, size, args.crop)
                else:
                    events, _ = crop(events, size, *args.crop)
            yield events

    with tqdm(total=src.n_events, unit="ev", unit_scale=True, disable=None, leave=False) as bar:
        count = write_event_chunks(args.output, chunks(bar), out_size, evt_version=args.evt_version)
    print(f"wrote {count:,} events ({out_size[0]}x{out_size[1]}) to {args.output}")
    return 0


# -- view ------------------------------------------------------------------------------
def _cmd_view(args: argparse.Namespace) -> int:
    from .io import open_events
    from .viz import event_frame, grid, save_animation, save_image

    out = Path(args.output)
    if out.suffix.lower() not in (".png", ".jpg", ".jpeg", ".gif", ".mp4"):
        raise EdeflareError(f"{out}: output must be .png, .jpg, .gif or .mp4")
    src = open_events(args.file, args.sensor_size)
    size = src.sensor_size
    window = round(args.window_ms * 1000)
    if window <= 0:
        raise EdeflareError(f"--window-ms must be positive, got {args.window_ms}")
    start = _ms_to_us(args.start_ms)
    end = None if start is None else start + window * args.count
    frames, labels = [], []
    with tqdm(total=args.count, unit="frame", disable=None, leave=False) as bar:
        for w_start, events in src.windows(window, start_us=start, end_us=end):
            frames.append(event_frame(events, size, background=args.background))
            labels.append(f"{w_start / 1000:.1f} ms ({events.size:,} ev)")
            bar.update(1)
            if len(frames) >= args.count:
                break
    if not frames:
        raise EdeflareError(f"{args.file}: no events to show")
    if out.suffix.lower() in (".gif", ".mp4"):
        save_animation(
            out,
            [grid([f], captions=[c]) for f, c in zip(frames, labels, strict=True)],
            fps=args.fps,
        )
    else:
        save_image(out, grid(frames, captions=labels, ncols=min(len(frames), 4)))
    print(f"wrote {len(frames)} window(s) of {args.window_ms:g} ms to {out}")
    return 0


# -- demo ------------------------------------------------------------------------------
def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    paths = run_demo(args.out, rng=args.seed)
    print(f"demo written to {args.out}/:")
    for name, path in paths.items():
        print(f"  {name:<11} {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``edeflare`` command."""
    parser = argparse.ArgumentParser(
        prog="edeflare",
        description="Remove lens flare from event-camera data (E-Deflare).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"edeflare {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, help_: str) -> argparse.ArgumentParser:
        return sub.add_parser(
            name,
            help=help_,
            description=help_,
            formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        )

    size_help = "sensor size WxH, for files that record none (else max+1, with a warning)"

    p = add("info", "Describe an event file: format, sensor, events, span, rate, ON fraction.")
    p.add_argument("file", type=Path)
    p.add_argument("--sensor-size", type=_size, metavar="WxH", help=size_help)
    p.set_defaults(func=_cmd_info)

    p = add("convert", "Convert between event formats (by suffix), streaming, optionally cropped.")
    p.add_argument("input", type=Path)
    p.add_argument("output", type=Path)
    p.add_argument("--sensor-size", type=_size, metavar="WxH", help=size_help)
    p.add_argument(
        "--crop",
        type=_crop_spec,
        metavar="WxH|X,Y,W,H",
        help="centre crop WxH (e.g. 640x480) or the rectangle X,Y,W,H",
    )
    p.add_argument("--start-ms", type=float, help="keep events from this absolute time (ms)")
    p.add_argument("--end-ms", type=float, help="keep events before this absolute time (ms)")
    p.add_argument(
        "--evt-version",
        default="evt3",
        choices=["evt3", "evt2", "evt2.1"],
        help="encoding of .raw outputs",
    )
    p.set_defaults(func=_cmd_convert)

    p = add("view", "Render windows of events (ON red, OFF blue) to a PNG, GIF or MP4.")
    p.add_argument("file", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True, help=".png, .jpg, .gif or .mp4")
    p.add_argument("--sensor-size", type=_size, metavar="WxH", help=size_help)
    p.add_argument(
        "--start-ms",
        type=float,
        help="absolute start of the first window (ms); default: aligned to the first event",
    )
    p.add_argument("--window-ms", type=float, default=20.0, help="window length (ms)")
    p.add_argument("--count", type=int, default=1, help="number of consecutive windows")
    p.add_argument("--background", choices=["white", "black"], default="white")
    p.add_argument("--fps", type=float, default=10.0, help="frames per second of GIF/MP4")
    p.set_defaults(func=_cmd_view)

    p = add("demo", "Run the embedded demo on a synthetic flare scene; writes pictures and files.")
    p.add_argument("--out", type=Path, default=Path("demo"), help="output folder")
    p.add_argument("--seed", type=int, default=0, help="seed of the synthetic scene")
    p.set_defaults(func=_cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``edeflare`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except EdeflareError as exc:
        print(f"edeflare: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("edeflare: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
