"""``edeflare convert IN OUT``: any readable format to any writable one, streamed, cropped."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._progress import progress_bar
from ..events import center_crop, crop
from ._common import (
    GROUP_HELP,
    SIZE_HELP,
    crop_spec,
    ms_to_us,
    sensor_size_arg,
    warn_outside_span,
)

if TYPE_CHECKING:
    from tqdm import tqdm

HELP = (
    "Convert between event formats (by suffix), streaming, optionally cropped. Times are in "
    "ms relative to the recording's start (its first event)."
)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("convert", help=HELP, description=HELP, **kwargs)
    p.add_argument("input", type=Path)
    p.add_argument("output", type=Path)
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    p.add_argument("--group", help=GROUP_HELP)
    p.add_argument(
        "--crop",
        type=crop_spec,
        metavar="WxH|X,Y,W,H",
        help="centre crop WxH (e.g. 640x480) or the rectangle X,Y,W,H",
    )
    p.add_argument(
        "--start-ms",
        type=float,
        help="keep events from this time, in ms after the recording's first event (not absolute)",
    )
    p.add_argument(
        "--end-ms",
        type=float,
        help="keep events before this time, in ms after the recording's first event",
    )
    p.add_argument(
        "--evt-version",
        default="evt2",
        choices=["evt2", "evt3"],
        help="encoding of .raw outputs (EVT 3.0 output must span under 16.8 s)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Stream chunks from the input, filter and crop them, write the output atomically."""
    from ..io import open_events, write_event_chunks

    src = open_events(args.input, args.sensor_size, group=args.group)
    size = src.sensor_size
    out_size = size
    if args.crop is not None:
        out_size = args.crop if len(args.crop) == 2 else tuple(args.crop[2:])
    rel_lo, rel_hi = ms_to_us(args.start_ms), ms_to_us(args.end_ms)
    t_lo = t_hi = origin = None  # absolute, once the first event is known

    def chunks(bar: tqdm) -> Iterator[np.ndarray]:
        nonlocal t_lo, t_hi, origin
        for events in src.chunks():
            bar.update(events.size)
            if origin is None:
                origin = int(events["t"][0])
                t_lo = None if rel_lo is None else origin + rel_lo
                t_hi = None if rel_hi is None else origin + rel_hi
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

    with progress_bar(total=src.n_events, unit="ev", unit_scale=True, leave=False) as bar:
        count = write_event_chunks(args.output, chunks(bar), out_size, evt_version=args.evt_version)
    if count == 0 and origin is not None and (rel_lo is not None or rel_hi is not None):
        hi = None if rel_hi is None else origin + rel_hi
        warn_outside_span(src, origin, origin + (rel_lo or 0), hi)
    print(f"wrote {count:,} events ({out_size[0]}x{out_size[1]}) to {args.output}")
    return 0
