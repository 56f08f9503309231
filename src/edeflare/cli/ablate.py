"""``edeflare ablate OUT``: Table 3, the same network trained on each composition variant."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = (
    "Ablation of the training-pair composition (the paper's Table 3): simulate one training "
    "set per variant from the same scenes, train the same preset on each with equal budgets, "
    "and score every model on one test set. Resumes."
)

DESCRIPTION = """\
Ablation of the training-pair composition (the paper's Table 3). Simulates one
training set per composition variant from the same scenes (simple, simple+random,
physical+random, no-light, physical = full PNL-ES), trains the same preset on each
with equal budgets, scores every model on one test set, and writes OUT/table.md,
.csv and .json (raw input row unranked; improvement of Full over the best ablated
variant). Every step resumes where a killed run stopped.
"""

EPILOG = """\
configurations:
  small  64x48 scenes, unet2d.tiny, 30 iterations: about a minute on 2 cores; checks the
         pipeline (CI), too small to rank the variants
  cpu    eflare-mini (120 sequences), unet2d.lite, 2000 iterations per variant, tested on
         eflare-r-sim: a longer run (several hours on 2 cores; run it with nohup)
  paper  E-Flare-2.7K and the paper's training (40k iterations of unet3d.paper): for GPUs

examples:
  edeflare ablate runs/ablation-small --config small
  nohup edeflare ablate runs/ablation --config cpu --workers 2 > ablation.log 2>&1 &
  edeflare ablate runs/ablation-real --config cpu --test captures/test
"""


def _variants(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    kwargs["formatter_class"] = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser("ablate", help=HELP, description=DESCRIPTION, epilog=EPILOG, **kwargs)
    p.add_argument("out", type=Path, help="output folder (resumed if it exists)")
    p.add_argument(
        "--config",
        default="small",
        help="named configuration: small, cpu or paper (default: small)",
    )
    p.add_argument(
        "--test",
        type=Path,
        help="test on this folder of paired sequence files instead of generating the "
        "configuration's test set",
    )
    p.add_argument(
        "--variants",
        type=_variants,
        help="comma-separated subset of simple,simple+random,physical+random,no-light,"
        "physical (physical is required)",
    )
    p.add_argument("--iterations", type=int, help="training iterations per variant")
    p.add_argument("--sequences", type=int, help="training sequences per variant")
    p.add_argument("--workers", type=int, default=1, help="data generation processes")
    p.add_argument("--seed", type=int, default=0, help="seeds the model decoders")
    p.set_defaults(func=run, resumes=True)


def run(args: argparse.Namespace) -> int:
    """Run the ablation and print its table."""
    from ..ablate import ABLATIONS, run_ablation

    ABLATIONS[args.config]  # an unknown name is an error listing the valid ones
    changes: dict[str, object] = {}
    if args.variants is not None:
        changes["variants"] = args.variants
    if args.iterations is not None:
        changes["iterations"] = args.iterations
    if args.sequences is not None:
        changes["sequences"] = args.sequences
    config = ABLATIONS[args.config].replace(**changes)
    result = run_ablation(
        config,
        args.out,
        test_split=args.test,
        workers=args.workers,
        seed=args.seed,
        log=lambda line: print(line, flush=True),
    )
    print(result.table.to_markdown(), end="")
    print(f"wrote {args.out / 'table.md'}, table.csv and table.json")
    return 0
