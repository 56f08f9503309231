"""``edeflare tune-head``: fit a trained keep head further to annotated real recordings."""

from __future__ import annotations

import argparse
import math
import shlex
import sys
from pathlib import Path

from ._common import sensor_size_arg
from .train_head import add_thin_option, add_workers_option

HELP = (
    "Fit a trained keep head's perceptrons further on simulated pairs and annotated real "
    "recordings (their lights' regions as labels: the light kept, its halo and ghost "
    "removed, the scene kept; a recording without a light, every event kept)."
)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser(
        "tune-head",
        help=HELP,
        description=HELP + " Writes RUN/model.safetensors (the same layout, the card with the "
        "threshold) and RUN/tune.json; the rows drawn are kept in RUN, so a rerun goes on "
        "from them.",
        **kwargs,
    )
    p.add_argument("weights", help="a model with a keep head (a .safetensors file or a name)")
    p.add_argument(
        "data",
        type=Path,
        nargs="+",
        help="dataset or mix folders (with train/ and test/) of the simulated pairs",
    )
    p.add_argument(
        "--real",
        action="append",
        default=[],
        metavar="REC[:LIGHTS.json]",
        help="a real recording, with its lights' annotation (edeflare score --lights) or "
        "without one for a recording without a light (repeat for more)",
    )
    p.add_argument("--out", type=Path, required=True, help="run folder")
    p.add_argument(
        "--real-weight",
        type=float,
        default=1.0,
        metavar="A",
        help="the real rows' total loss weight, times the simulated rows'",
    )
    p.add_argument(
        "--balance-classes",
        action="store_true",
        help="give the real rows' keep and flare classes half of their weight each (as the "
        "simulated rows' are); without it, each recording and region weighs alike",
    )
    p.add_argument(
        "--hold-simulated",
        action="store_true",
        help="on the simulated rows, learn the head's own keep probabilities before the fit "
        "instead of their labels (keep what it did on simulation)",
    )
    p.add_argument(
        "--per-region", type=int, default=50_000, help="rows drawn per region and recording"
    )
    p.add_argument(
        "--keep-threshold",
        type=float,
        metavar="P",
        help="the card's keep threshold (default: chosen on the data's test splits)",
    )
    p.add_argument(
        "--validate-last",
        type=float,
        default=0.0,
        metavar="F",
        help="leave the last share F of each recording's span out of the fit and score it "
        "after, beside the head before the fit (tune.json's validation)",
    )
    add_thin_option(p)
    p.add_argument("--epochs", type=int, default=3)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--sensor-size", type=sensor_size_arg, help="WxH, for recordings whose files do not say"
    )
    add_workers_option(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def real_argument(text: str) -> tuple[Path, Path | None]:
    """``REC`` or ``REC:LIGHTS.json`` (split at the last colon before a ``.json``).

    Examples
    --------
    >>> real_argument("night.raw:night.json")
    (PosixPath('night.raw'), PosixPath('night.json'))
    >>> real_argument("street.aedat4")
    (PosixPath('street.aedat4'), None)
    """
    rec, sep, lights = text.rpartition(":")
    if sep and lights.lower().endswith(".json") and rec:
        return Path(rec), Path(lights)
    return Path(text), None


def run(args: argparse.Namespace) -> int:
    """Read the recordings and their annotations, fit, write the run."""
    from ..errors import ParameterError
    from ..io import read_events
    from ..lights import load_lights
    from ..models.head_tuning import TuningConfig, tune_head
    from ..models.infer import resolve_weights

    if not args.real:
        raise ParameterError("give at least one --real recording")
    if args.workers < 1:
        raise ParameterError("--workers must be at least 1")
    config = TuningConfig(
        real_weight=args.real_weight,
        balance_classes=args.balance_classes,
        hold_simulated=args.hold_simulated,
        per_region=args.per_region,
        validate_last=args.validate_last,
        epochs=args.epochs,
        lr=args.lr,
        seed=args.seed,
        thin=args.thin,
    )
    size = args.sensor_size
    recordings = []
    for text in args.real:
        path, lights_path = real_argument(text)
        r = read_events(path, sensor_size=size)
        lights = None if lights_path is None else load_lights(lights_path, r.sensor_size)
        recordings.append((path.stem, r.events, r.sensor_size, lights))
    command = "edeflare " + shlex.join(sys.argv[1:]) if sys.argv[1:] else "edeflare tune-head"
    summary = tune_head(
        resolve_weights(args.weights),
        args.data,
        recordings,
        args.out,
        config,
        keep_threshold=args.keep_threshold,
        command=command,
        progress=not args.no_progress,
        workers=args.workers,
    )
    print(
        f"keep threshold {summary['keep_threshold']:.2f} ({summary['threshold_chosen_on']}; "
        f"on the test splits {summary['simulated_threshold']:.2f}); "
        f"{len(recordings)} real recordings"
    )
    for name, v in summary["validation"].items():
        before, tuned = _scores_text(v["before"]), _scores_text(v["tuned"])
        share = f"{100 * args.validate_last:g} %"
        print(f"{name}, its last {share} ({v['events']:,} events, not fitted): "
              f"{before} before, {tuned} tuned")  # fmt: skip
    print(f"wrote {args.out / 'model.safetensors'} and {args.out / 'tune.json'}")
    return 0


def _scores_text(scores: dict[str, float]) -> str:
    """``flare removed / light kept / scene kept, combined`` (the defined ones), or the share
    kept of a recording without a light.

    Examples
    --------
    >>> nan = float("nan")
    >>> _scores_text({"flare removed": 0.5, "light kept": 1.0, "scene kept": nan,
    ...               "combined": 0.667})
    'removed 50.0 %, light 100.0 %: 0.667'
    >>> _scores_text({"flare removed": nan, "light kept": nan, "scene kept": nan, "combined": 0.9})
    'kept 90.0 %'
    """
    names = {"flare removed": "removed", "light kept": "light", "scene kept": "scene"}
    parts = [f"{short} {100 * scores[k]:.1f} %" for k, short in names.items()
             if not math.isnan(scores[k])]  # fmt: skip
    if not parts:
        return f"kept {100 * scores['combined']:.1f} %"
    return ", ".join(parts) + f": {scores['combined']:.3f}"
