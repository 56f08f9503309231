"""``edeflare info FILE``: format, sensor size, events, span, rate, ON fraction; or, for
a model's weights, its card."""

from __future__ import annotations

import argparse
from pathlib import Path

from .._progress import progress_bar
from ..errors import EdeflareError
from ._common import GROUP_HELP, SIZE_HELP, sensor_size_arg

HELP = (
    "Describe an event file (format, sensor, events, span, rate, ON fraction), or a "
    "model's weights (.safetensors, .onnx or a bundled model's name: its card)."
)
_WEIGHTS = (".safetensors", ".onnx")


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("info", help=HELP, description=HELP, **kwargs)
    p.add_argument("file", type=Path)
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    p.add_argument("--group", help=GROUP_HELP)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Stream the file once and print its figures (or print a weights file's card)."""
    from ..io import open_events
    from ..models.infer import bundled_weights

    if args.file.suffix.lower() in _WEIGHTS:
        return _card(args.file)
    if not args.file.suffix and not args.file.exists():
        try:  # a bundled model's name (night, eflare, paper)
            return _card(bundled_weights(args.file.name))
        except EdeflareError:
            pass  # not one: the event reader names the missing file

    src = open_events(args.file, args.sensor_size, group=args.group)
    n = n_on = 0
    first = last = None
    with progress_bar(total=src.n_events, unit="ev", unit_scale=True, leave=False) as bar:
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


def _card(path: Path) -> int:
    """Print the model card of a weights file (no tensors loaded)."""
    from ..models.weights import read_card

    card = read_card(path)
    print(f"file        {path}")
    print(f"preset      {card.preset} ({card.bins} bins, {card.window_us / 1000:g} ms windows)")
    if card.preset.startswith("mask."):
        print(f"keep        probability > {card.keep_threshold:g}")
        light_free = f"light_free_shift {card.light_free_shift:g}"
        if card.light_free_support:
            gate = f"support {card.light_free_support}"
            if card.light_free_crowding:
                gate += f", crowding {card.light_free_crowding:g}"
                if card.scatter_shift:
                    gate += f", scatter_shift {card.scatter_shift:g}"
            light_free += f" ({gate})"
        print(
            f"priors      halo_shift {card.halo_shift:g}, ghost_shift {card.ghost_shift:g}, "
            f"streak_shift {card.streak_shift:g}, {light_free}, far_shift {card.far_shift:g}"
        )
    for key, value in card.metrics.items():
        print(f"{key:<11} {value}")
    for name in ("data", "command", "notes"):
        text = getattr(card, name)
        if text:
            print(f"{name:<11} {text}")
    return 0
