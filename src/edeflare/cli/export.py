"""``edeflare export OUT.onnx``: write a model's network as ONNX, for other runtimes."""

from __future__ import annotations

import argparse
from itertools import islice
from pathlib import Path

from ._common import sensor_size_arg

HELP = (
    "Export a model's network as ONNX for one sensor size (the bundled model by default), "
    "for ONNX Runtime, C++ and robot stacks; `deflare --model OUT.onnx` runs it. Needs the "
    "onnx extra (pip install 'edeflare[onnx]')."
)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("export", help=HELP, description=HELP, **kwargs)
    p.add_argument("output", type=Path, help="the .onnx file to write")
    p.add_argument(
        "--model",
        type=Path,
        metavar="PATH",
        help="weights (.safetensors) or the name of a bundled model (night, eflare); default: "
        "the default bundled model (night)",
    )
    p.add_argument(
        "--sensor-size",
        type=sensor_size_arg,
        metavar="WxH",
        help="the sensor the graph is made for (default: the --check recording's)",
    )
    p.add_argument("--opset", type=int, default=17, help="ONNX operator set")
    p.add_argument(
        "--check",
        type=Path,
        metavar="RECORDING",
        help="compare the export with torch on this recording's first windows (the maximum "
        "absolute difference of the network's outputs, and the event decisions)",
    )
    p.add_argument("--check-windows", type=int, default=20, metavar="N", help="windows checked")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Export, then optionally check parity on a recording."""
    from ..errors import EdeflareError
    from ..io import open_events
    from ..models.export import export_onnx, onnx_parity
    from ..models.infer import resolve_weights

    if args.output.suffix.lower() != ".onnx":
        raise EdeflareError(f"{args.output}: the output must be a .onnx file")
    weights = resolve_weights(args.model)
    source = open_events(args.check, args.sensor_size) if args.check is not None else None
    size = args.sensor_size or (source.sensor_size if source is not None else None)
    if size is None:
        raise EdeflareError("give --sensor-size WxH (or --check RECORDING to take its size)")
    card = export_onnx(weights, args.output, size, opset=args.opset)
    print(f"{card.preset}: wrote {args.output} for a {size[0]}x{size[1]} sensor")
    if source is not None:
        windows = islice(source.windows(card.window_us), args.check_windows)
        parity = onnx_parity(weights, args.output, windows, size)
        print(f"parity on {args.check}: {parity}")
    return 0
