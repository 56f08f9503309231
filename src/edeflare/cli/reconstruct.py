"""``edeflare reconstruct IN OUT.mp4``: events to a gray video with the bundled reconstructor."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import GROUP_HELP, SIZE_HELP, sensor_size_arg

HELP = (
    "Reconstruct intensity images from events (a small recurrent network trained on the "
    "simulator, one image per 20 ms window) and write them as a gray .mp4 or .gif: compare "
    "a recording before and after de-flaring."
)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("reconstruct", help=HELP, description=HELP, **kwargs)
    p.add_argument("input", type=Path, help="event file (any readable format)")
    p.add_argument("output", type=Path, help="video to write (.mp4 or .gif)")
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    p.add_argument("--group", help=GROUP_HELP)
    p.add_argument("--weights", type=Path, help="reconstructor weights [the bundled firenet]")
    p.add_argument("--fps", type=float, help="frames per second of the video [real time: 50]")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Reconstruct and write the video."""
    from ..recon.infer import reconstruct_file

    n = reconstruct_file(
        args.input,
        args.output,
        sensor_size=args.sensor_size,
        group=args.group,
        weights=args.weights,
        fps=args.fps,
    )
    print(f"wrote {args.output} ({n} frames)")
    return 0
