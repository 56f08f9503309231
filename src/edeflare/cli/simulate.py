"""``edeflare simulate OUT``: generate a paired dataset (parallel, sharded, resumable)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from ._common import sensor_size_arg

HELP = "Generate a paired flare / flare-free dataset with the simulator (resumes if rerun)."


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser(
        "simulate",
        help=HELP,
        description=HELP + " Writes OUT/train/*.h5, OUT/test/*.h5 and OUT/manifest.json. "
        "Options left unset take the recipe's values. Rerun the same command to resume; "
        "use --shard i/n for array jobs.",
        **kwargs,
    )
    p.add_argument("out", type=Path, help="dataset folder")
    p.add_argument(
        "--recipe",
        default="eflare-mini",
        help="eflare-2.7k (the paper's: 544 x 100 ms at 640x480) or eflare-mini (120 at 346x260)",
    )
    p.add_argument("--sequences", type=int, help="number of sequences")
    p.add_argument("--test-sequences", type=int, help="sequences in the test split (the last ones)")
    p.add_argument("--duration-ms", type=float, help="length of a sequence (ms)")
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help="sensor size")
    p.add_argument(
        "--background",
        nargs="+",
        metavar="FILE",
        help="recorded event files (any readable format) to cut backgrounds from; "
        "default: synthetic night streets",
    )
    p.add_argument(
        "--variant",
        choices=["physical", "simple", "simple+random", "physical+random", "no-light", "forward"],
        help="composition: PNL-ES (physical), the ablations, or the full forward model",
    )
    p.add_argument(
        "--weights",
        choices=["intensity", "accumulation", "counts"],
        help="PNL-ES intensities: rendered videos (+ scene / accumulation estimate for the "
        "background), accumulation estimate for the background, or whole-window counts",
    )
    p.add_argument("--seed", type=int, help="dataset seed")
    p.add_argument("--flare7k", type=Path, help="a Flare7K++ folder to take flare images from")
    p.add_argument(
        "--no-components",
        action="store_true",
        help="store only input and gt (not the pure flare, light and background streams)",
    )
    p.add_argument("--workers", type=int, default=1, help="worker processes")
    p.add_argument(
        "--shard", default="0/1", metavar="I/N", help="make sequences with index %% N == I"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build the recipe from the options, generate, print a summary."""
    from ..data.generate import RECIPES, generate_dataset
    from ..errors import ParameterError

    if args.recipe not in RECIPES:
        raise ParameterError(f"unknown recipe {args.recipe!r}; choose one of {sorted(RECIPES)}")
    changes: dict[str, object] = {}
    for key in ("sequences", "test_sequences", "sensor_size", "variant", "weights", "seed"):
        if getattr(args, key) is not None:
            changes[key] = getattr(args, key)
    if args.duration_ms is not None:
        changes["duration_us"] = round(args.duration_ms * 1000)
    if args.background:
        changes["background"] = "recorded"
        changes["background_files"] = tuple(str(p) for p in args.background)
    if args.flare7k is not None:
        changes["flare7k"] = str(args.flare7k)
    if args.no_components:
        changes["components"] = False
    recipe = dataclasses.replace(RECIPES[args.recipe], **changes)
    report = generate_dataset(
        recipe, args.out, workers=args.workers, shard=args.shard, progress=not args.no_progress
    )
    m = report.manifest
    state = "complete" if m["complete"] else f"{len(m['files'])}/{m['sequences']} sequences so far"
    print(
        f"{recipe.name}: {report.generated} sequences made, {report.skipped} already there "
        f"({report.wall_seconds:.1f} s); dataset {state}; manifest {report.manifest_path}"
    )
    return 0
