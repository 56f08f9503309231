"""``edeflare benchmark SPLIT``: every method on every test sequence, the table and speed."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import EdeflareError

HELP = "Benchmark methods on a dataset split (folder of sequence files): metrics table and speed."


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("benchmark", help=HELP, description=HELP, **kwargs)
    p.add_argument("split", type=Path, help="folder of sequence files, e.g. DATA/test")
    p.add_argument(
        "--methods",
        nargs="+",
        default=["raw", "voxel", "efr", "pfd-a", "pfd-b", "model"],
        help="registered methods to run ('raw' is the unranked input row)",
    )
    p.add_argument(
        "--model",
        action="append",
        default=[],
        metavar="[NAME=]PATH",
        help="weights for the 'model' row [the bundled model]; NAME=PATH adds a row NAME "
        "(repeatable: compare several trained models in one table)",
    )
    p.add_argument(
        "--decoder", choices=["keep", "paper"], default="keep", help="decoder of the 'model' row"
    )
    p.add_argument("--seed", type=int, default=0, help="seeds methods that draw")
    p.add_argument(
        "--convention",
        choices=["edeflare", "authors"],
        default="edeflare",
        help="whose definitions of the metrics: edeflare's (aligned 20 ms segments) or the "
        "authors' evaluation code behind the paper's tables (each sequence scored whole)",
    )
    p.add_argument(
        "--report",
        type=Path,
        help="write the table to this .md file, with .csv and .json beside it",
    )
    p.add_argument(
        "--html",
        type=Path,
        metavar="DIR",
        help="write an HTML report (index.html, figures, GIFs, reconstructions) into DIR",
    )
    p.add_argument("--samples", type=int, default=4, help="sample windows in the HTML report")
    p.add_argument(
        "--downstream",
        nargs="?",
        const=True,
        default=False,
        metavar="WEIGHTS",
        help="also reconstruct every stream into images (the bundled reconstructor, or these "
        "weights) and score PSNR / SSIM against the files' clean frames (eflare-r-sim files)",
    )
    p.add_argument(
        "--real",
        nargs="+",
        type=Path,
        default=[],
        metavar="FILE",
        help="with --html: also reconstruct these real recordings before and after each "
        "method (qualitative: real recordings have no flare-free image)",
    )
    p.set_defaults(func=run)


def _models(values: list[str]) -> tuple[Path | None, dict[str, Path]]:
    """Split ``--model`` values into the unnamed one (the 'model' row) and ``NAME=PATH`` rows."""
    unnamed: Path | None = None
    named: dict[str, Path] = {}
    for text in values:
        name, sep, path = text.partition("=")
        if sep and name and "/" not in name and not Path(text).exists():
            if name in named:
                raise EdeflareError(f"--model {text}: row {name!r} given twice")
            named[name] = Path(path)
        elif unnamed is not None:
            raise EdeflareError("give one unnamed --model PATH; name the others NAME=PATH")
        else:
            unnamed = Path(text)
    return unnamed, named


def run(args: argparse.Namespace) -> int:
    """Run the benchmark, print the tables, optionally write the report files."""
    from ..eval.benchmark import benchmark
    from ..eval.evaluate import convention_note

    rows: dict[str, str] = {m: m for m in args.methods}
    params: dict[str, dict[str, object]] = {}
    unnamed, named = _models(args.model)
    if unnamed is not None and "model" not in rows:
        rows["model"] = "model"
    if "model" in rows:
        params["model"] = {"decoder": args.decoder}
        if unnamed is not None:
            params["model"]["weights"] = unnamed
    for name, path in named.items():
        if name in rows:
            raise EdeflareError(f"--model {name}={path}: the table already has a row {name!r}")
        rows[name] = "model"
        params[name] = {"decoder": args.decoder, "weights": path}
    collector = None
    if args.real and args.html is None:
        raise EdeflareError("--real shows recordings in the HTML report: give --html DIR too")
    if args.html is not None:
        from ..eval.report import FigureCollector, check_report_dir

        check_report_dir(args.html)
        collector = FigureCollector(args.samples)
    result = benchmark(
        args.split,
        rows,
        params=params,
        seed=args.seed,
        on_output=collector,
        downstream=args.downstream,
        convention=args.convention,
    )
    table = result.table()
    markdown = table.to_markdown() + "\n" + result.speed_markdown()
    if args.downstream is not False:
        if not result.downstream or all(d["windows"] == 0 for d in result.downstream.values()):
            raise EdeflareError(
                f"{args.split}: no sequence holds clean frames to score reconstructions against "
                "(simulate it with a recipe that writes them, e.g. eflare-r-sim)"
            )
        markdown += "\nReconstruction (downstream):\n\n" + result.downstream_markdown()
    caption = convention_note(args.convention)
    if args.convention != "edeflare":  # the default's output stays the tables alone
        print(caption)
    print(markdown, end="")
    if args.report is not None:
        report = args.report.with_suffix(".md")
        details = {"convention": args.convention, "benchmark": result.to_dict()}
        table.save(report, markdown=caption + "\n\n" + markdown, details=details)
        print(f"wrote {report}, {report.with_suffix('.csv')} and {report.with_suffix('.json')}")
    if collector is not None:
        from ..eval.report import write_report
        from ..methods import create_method

        real_methods = {k: create_method(v, **params.get(k, {})) for k, v in rows.items()}
        page = write_report(
            result,
            args.html,
            figures=collector.finish(),
            real=args.real,
            real_methods=real_methods,
        )
        print(f"wrote {page}")
    return 0
