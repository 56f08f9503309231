"""``edeflare demo``: the embedded default a new user runs first."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = (
    "Simulate a flare scene, de-flare it with the bundled model and the baselines; "
    "write pictures and the metrics table."
)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser("demo", help=HELP, description=HELP, **kwargs)
    p.add_argument("--out", type=Path, default=Path("demo"), help="output folder")
    p.add_argument("--seed", type=int, default=0, help="which scene (sequence index) to simulate")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the demo and print where everything is."""
    from ..demo import run_demo

    paths = run_demo(args.out, rng=args.seed)
    print(f"demo written to {args.out}/:")
    for name, path in paths.items():
        print(f"  {name:<11} {path}")
    return 0
