"""``edeflare evaluate --gt GT --pred NAME=PATH ...``: the paper's metrics table."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import SIZE_HELP, sensor_size_arg

HELP = "Score restored events against ground truth with the paper's eight metrics (20 ms segments)."


def _named_path(text: str) -> tuple[str, Path]:
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise argparse.ArgumentTypeError(f"--pred must look like NAME=PATH, got {text!r}")
    return name, Path(path)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser(
        "evaluate",
        help=HELP,
        description=HELP + " Files in folders are paired by name (stem). Name the unprocessed "
        "input 'raw' to get the unranked Raw Input row.",
        **kwargs,
    )
    p.add_argument("--gt", type=Path, required=True, help="ground-truth file or folder")
    p.add_argument(
        "--pred",
        type=_named_path,
        action="append",
        required=True,
        metavar="NAME=PATH",
        help="restored file or folder of one method (repeat for several methods)",
    )
    p.add_argument(
        "--report",
        type=Path,
        help="write the table to this .md file, with .csv and .json beside it",
    )
    p.add_argument("--window-ms", type=float, default=20.0, help="segment length (ms)")
    p.add_argument("--bins", type=int, default=8, help="time bins of the voxel grids")
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    p.add_argument(
        "--convention",
        choices=["edeflare", "authors"],
        default="edeflare",
        help="whose definitions of the metrics: edeflare's (aligned segments) or the authors' "
        "evaluation code behind the paper's tables (each file whole; 20 ms, 8 bins fixed)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Evaluate every method, print the Markdown table, optionally write the report files."""
    from ..errors import EdeflareError
    from ..eval.evaluate import convention_note, evaluate
    from ..eval.tables import ResultsTable

    names = [name for name, _ in args.pred]
    if len(set(names)) != len(names):
        raise EdeflareError(f"--pred names must be unique, got {names}")
    window = round(args.window_ms * 1000)
    if window <= 0 or args.bins < 1:
        raise EdeflareError("--window-ms and --bins must be positive")
    result = evaluate(
        args.gt,
        dict(args.pred),
        sensor_size=args.sensor_size,
        window_us=window,
        bins=args.bins,
        convention=args.convention,
    )
    table = ResultsTable({m: s.means for m, s in result.methods.items()})
    markdown = table.to_markdown()
    caption = convention_note(args.convention)
    if args.convention != "edeflare":  # the default's output stays the table alone
        print(caption)
    print(markdown, end="")
    counted = "segments" if args.convention == "edeflare" else "chunk pairs"
    for method, summary in result.methods.items():
        undefined = {k: v for k, v in summary.undefined.items() if v}
        note = f", undefined: {undefined}" if undefined else ""
        print(f"{method}: {summary.n_segments} {counted}{note}")
    if args.report is not None:
        report = args.report.with_suffix(".md")
        details = {
            "convention": args.convention,
            "evaluation": result.to_dict(),
            "window_us": window,
            "bins": args.bins,
        }
        table.save(report, markdown=caption + "\n\n" + markdown, details=details)
        print(f"wrote {report}, {report.with_suffix('.csv')} and {report.with_suffix('.json')}")
    return 0
