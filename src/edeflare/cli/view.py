"""``edeflare view FILE -o out.png|.gif|.mp4``: event frames of consecutive windows."""

from __future__ import annotations

import argparse
from pathlib import Path

from .._progress import progress_bar
from ..errors import EdeflareError
from ._common import GROUP_HELP, SIZE_HELP, ms_to_us, sensor_size_arg, warn_outside_span

HELP = (
    "Render windows of events (ON red, OFF blue) to a PNG, GIF or MP4. Times are in ms "
    "relative to the recording's start (its first event)."
)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("view", help=HELP, description=HELP, **kwargs)
    p.add_argument("file", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True, help=".png, .jpg, .gif or .mp4")
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    p.add_argument("--group", help=GROUP_HELP)
    p.add_argument(
        "--start-ms",
        type=float,
        help="start of the first window, in ms after the recording's first event "
        "(not absolute time); default: 0, the first event",
    )
    p.add_argument("--window-ms", type=float, default=20.0, help="window length (ms)")
    p.add_argument("--count", type=int, default=1, help="number of consecutive windows")
    p.add_argument("--background", choices=["white", "black"], default="white")
    p.add_argument("--fps", type=float, default=10.0, help="frames per second of GIF/MP4")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Render ``--count`` windows; a PNG tiles them, a GIF/MP4 animates them."""
    from ..io import open_events
    from ..viz import event_frame, grid, save_animation, save_image

    out = Path(args.output)
    if out.suffix.lower() not in (".png", ".jpg", ".jpeg", ".gif", ".mp4"):
        raise EdeflareError(f"{out}: output must be .png, .jpg, .gif or .mp4")
    if args.count < 1:
        raise EdeflareError(f"--count must be at least 1, got {args.count}")
    window = round(args.window_ms * 1000)
    if window <= 0:
        raise EdeflareError(f"--window-ms must be positive, got {args.window_ms}")
    src = open_events(args.file, args.sensor_size, group=args.group)
    size = src.sensor_size
    origin = src.first_time_us()
    if origin is None:
        raise EdeflareError(f"{args.file}: no events to show")
    # Windows start at the first event by default (not at the multiple of the window
    # below it), so the captions count from 0 ms as the help says.
    start = origin + (0 if args.start_ms is None else ms_to_us(args.start_ms))
    end = start + window * args.count
    frames, labels, counts = [], [], []
    with progress_bar(total=args.count, unit="frame", leave=False) as bar:
        for w_start, events in src.windows(window, start_us=start, end_us=end):
            frames.append(event_frame(events, size, background=args.background))
            counts.append(events.size)
            labels.append(f"{(w_start - origin) / 1000:.1f} ms ({events.size:,} ev)")
            bar.update(1)
            if len(frames) >= args.count:
                break
    if not frames:
        raise EdeflareError(f"{args.file}: no events to show")
    if not any(f_events for f_events in counts):
        warn_outside_span(src, origin, start, start + window * len(frames))
    if out.suffix.lower() in (".gif", ".mp4"):
        animated = [grid([f], captions=[c]) for f, c in zip(frames, labels, strict=True)]
        save_animation(out, animated, fps=args.fps)
    else:
        save_image(out, grid(frames, captions=labels, ncols=min(len(frames), 4)))
    span = f"{(start - origin) / 1000:g}-{(start - origin + window * len(frames)) / 1000:g} ms"
    print(f"wrote {len(frames)} window(s) of {args.window_ms:g} ms ({span}) to {out}")
    return 0
