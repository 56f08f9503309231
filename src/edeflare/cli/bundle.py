"""``edeflare bundle WEIGHTS OUT``: a trained run's weights with the card that says how
they were made and how to use them (the tensors copied unchanged)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ..errors import ParameterError

HELP = (
    "Copy a run's weights (e.g. RUN/model.safetensors) to a new file with model card fields "
    "set: the data's description, the keep threshold and priors, the scores measured."
)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser(
        "bundle",
        help=HELP,
        description=HELP + " The tensors are copied unchanged (or as float16 with --half); "
        "OUT is written atomically. Works for de-flaring models and reconstructors; "
        "`edeflare info OUT` shows the result.",
        **kwargs,
    )
    p.add_argument(
        "weights", help="weights file (.safetensors) or a bundled model's name (night, ...)"
    )
    p.add_argument("out", type=Path, help="the .safetensors file to write (may be WEIGHTS)")
    p.add_argument(
        "--card",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a card field (repeatable): text fields (command, data, notes) as written, "
        "the others read as JSON (keep_threshold=0.4, seed=0, metrics='{...}'); unknown "
        "fields and wrong types are errors",
    )
    p.add_argument(
        "--metrics",
        metavar="JSON",
        help="a JSON object, or a .json file holding one, merged into the card's metrics",
    )
    p.add_argument(
        "--half", action="store_true", help="store the tensors as float16 (half the size)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Set the card's fields, write OUT, print the new card."""
    from ..models.bundle import bundle_weights
    from ..models.infer import resolve_weights

    metrics = _metrics(args.metrics) if args.metrics is not None else None
    card = bundle_weights(
        resolve_weights(args.weights),
        args.out,
        assignments=args.card,
        metrics=metrics,
        half=args.half,
    )
    print(f"wrote {args.out}")
    print(json.dumps(card, indent=1))
    return 0


def _metrics(text: str) -> dict[str, Any]:
    """The ``--metrics`` object: JSON text, or a JSON file's content."""
    path = Path(text)
    source = text
    if not text.lstrip().startswith("{") and path.is_file():
        text, source = path.read_text(encoding="utf-8"), str(path)
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParameterError(f"--metrics: {source!r} is not JSON ({exc})") from None
    if not isinstance(value, dict):
        raise ParameterError(f"--metrics must be a JSON object, got {value!r}")
    return value
