"""``edeflare info FILE``: format, sensor size, events, span, rate, ON fraction; or, for
a model's weights, its card."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .._progress import progress_bar
from ..errors import EdeflareError
from ._common import GROUP_HELP, SIZE_HELP, sensor_size_arg

HELP = (
    "Describe an event file (format, sensor, events, span, rate, ON fraction; with --lights, "
    "in how many windows the models' light test finds a light), or a model's weights "
    "(.safetensors, .onnx or a bundled model's name: its card)."
)
_WEIGHTS = (".safetensors", ".onnx")


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("info", help=HELP, description=HELP, **kwargs)
    p.add_argument("file", type=Path)
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    p.add_argument("--group", help=GROUP_HELP)
    p.add_argument(
        "--lights",
        action="store_true",
        help="also run the light test that the mask models' priors and light features read, "
        "window by window: in how many windows it finds a light, and how fast each window's "
        "brightest compact region fires against the rate it asks of a light",
    )
    p.add_argument(
        "--window-ms", type=float, default=20.0, help="--lights: the windows (ms; the models': 20)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Stream the file once and print its figures (or print a weights file's card)."""
    from ..events import iter_chunk_windows
    from ..io import open_events
    from ..lights import light_test_summary
    from ..models.infer import bundled_weights

    if args.file.suffix.lower() in _WEIGHTS:
        return _card(args.file)
    if not args.file.suffix and not args.file.exists():
        try:  # a bundled model's name (night, eflare, paper, firenet)
            return _card(bundled_weights(args.file.name))
        except EdeflareError:
            pass  # not one: the event reader names the missing file

    src = open_events(args.file, args.sensor_size, group=args.group)
    window_us = round(args.window_ms * 1000)
    if args.lights and window_us <= 0:
        raise EdeflareError(f"--window-ms must be positive, got {args.window_ms}")
    n = n_on = 0
    first = last = None
    lights = None
    with progress_bar(total=src.n_events, unit="ev", unit_scale=True, leave=False) as bar:

        def counted() -> Iterator[np.ndarray]:
            nonlocal n, n_on, first, last
            for chunk in src.chunks():
                n += chunk.size
                n_on += int(chunk["p"].sum())
                if first is None and chunk.size:
                    first = int(chunk["t"][0])
                if chunk.size:
                    last = int(chunk["t"][-1])
                bar.update(chunk.size)
                yield chunk

        if args.lights:
            lights = light_test_summary(
                iter_chunk_windows(counted(), window_us), src.sensor_size, window_us
            )
        else:
            for _ in counted():
                pass
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
    if lights is not None:
        print("\n".join(lights.lines(window_us)))
    return 0


def _card(path: Path) -> int:
    """Print the model card of a weights file (no tensors loaded)."""
    from ..models.weights import read_card, read_metadata
    from ..rules import RULES

    if path.suffix.lower() == ".safetensors":
        meta = read_metadata(path)
        if "edeflare_recon_card" in meta and "edeflare_card" not in meta:
            return _recon_card(path, meta["edeflare_recon_card"])
    card = read_card(path)
    print(f"file        {path}")
    print(f"preset      {card.preset} ({card.bins} bins, {card.window_us / 1000:g} ms windows)")
    if card.preset.startswith("mask."):
        print(f"keep        probability > {card.keep_threshold:g}")
        rules = card.rule_set()
        for rule in RULES.values():
            params = rules.params[rule.name]
            if rule.active(params):
                knobs = ", ".join(f"{k} {v:g}" for k, v in vars(params).items() if v)
                print(f"{'rule ' + rule.name:<11} {knobs}")
        if card.head:
            widths = ", ".join(map(str, card.head["hidden"])) or "none"
            print(f"head        learned: {len(card.head['features'])} features, hidden {widths}")
            print(f"features    {', '.join(card.head['features'])}")
            context = card.head.get("context")
            if context:
                levels = ", ".join(map(str, context["widths"]))
                relative = context.get("relative_counts")
                print(f"context     {context['channels']} maps of {context['inputs']} cell "
                      f"channels, U-Net widths {levels}"
                      + (f"; {relative} count channels relative to the window's mean"
                         if relative else ""))  # fmt: skip
            if card.head.get("members"):
                print(f"members     {card.head['members']} heads, their mean keep logit")
        if card.unlit_model:
            print(f"unlit       {card.unlit_model} judges the windows where no light is found")
    for key, value in card.metrics.items():
        print(f"{key:<11} {value}")
    for name in ("data", "command", "notes"):
        text = getattr(card, name)
        if text:
            print(f"{name:<11} {text}")
    return 0


def _recon_card(path: Path, text: str) -> int:
    """Print a reconstructor's card (``edeflare reconstruct``'s weights)."""
    import json

    from ..recon.weights import ReconCard

    card = ReconCard.from_dict(json.loads(text))
    print(f"file        {path}")
    print(
        f"model       reconstructor ({card.bins} bins, {card.features} features, "
        f"{card.window_us / 1000:g} ms windows)"
    )
    print(f"{'iterations':<11} {card.iterations}")
    for key, value in card.metrics.items():
        print(f"{key:<11} {value}")
    for name in ("data", "command"):
        text = getattr(card, name)
        if text:
            print(f"{name:<11} {text}")
    return 0
