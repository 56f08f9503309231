"""``edeflare train-head``: learn a mask model's per-event keep head on simulated pairs."""

from __future__ import annotations

import argparse
import math
import shlex
import sys
from pathlib import Path

HELP = (
    "Train a learned keep head (the rules' evidence and more, weighed from data) over a mask "
    "model's network on paired sequences; its threshold is chosen on their test splits."
)


def _widths(text: str) -> tuple[int, ...]:
    try:
        widths = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        widths = (0,)
    if any(w < 1 for w in widths):
        raise argparse.ArgumentTypeError(
            f"widths must be positive integers separated by commas (e.g. 32,16; '' for none), "
            f"got {text!r}"
        )
    return widths


def add_thin_option(p: argparse.ArgumentParser) -> None:
    """The ``--thin MIN`` rate augmentation of ``train-head`` and ``tune-head``."""
    p.add_argument(
        "--thin",
        type=float,
        default=1.0,
        metavar="MIN",
        help="rate augmentation: thin a random half of the training windows, each keeping "
        "a share of its events drawn log-uniformly in [MIN, 1] (1: none)",
    )


def add_workers_option(p: argparse.ArgumentParser) -> None:
    """The ``--workers N`` of ``train-head`` and ``tune-head``: processes drawing the rows."""
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help="processes drawing the training rows from the data (the same rows at any number)",
    )


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser(
        "train-head",
        help=HELP,
        description=HELP + " Writes RUN/model.safetensors (the network, the head, a card "
        "with the threshold and no rule shifts) and RUN/head.json (the threshold table); "
        "the features drawn from the data are kept in RUN, so a rerun goes on from them.",
        **kwargs,
    )
    p.add_argument(
        "data",
        type=Path,
        nargs="+",
        help="dataset folders (with train/ and test/) or mix folders "
        "(edeflare simulate --recipe eflare-mix)",
    )
    p.add_argument("--out", type=Path, required=True, help="run folder")
    p.add_argument(
        "--weights",
        default="night",
        help="the mask model whose network the head reads (a .safetensors file or a bundled "
        "model's name)",
    )
    p.add_argument(
        "--features",
        help="the features, comma-separated; 'default' stands for the default set, e.g. "
        "default,since_same,sync_64 (default: edeflare.models.event_features.DEFAULT_FEATURES, "
        "every feature but the two flicker features; docs/training.md lists them)",
    )
    p.add_argument("--hidden", type=_widths, default=(32, 16), help="hidden widths, e.g. 32,16")
    p.add_argument(
        "--per-window", type=int, default=2000, help="training events drawn per window and class"
    )
    p.add_argument(
        "--flare-free-windows",
        action="store_true",
        help="also learn from each pair's ground truth alone, every event kept (a flare-free "
        "recording of the same scene)",
    )
    p.add_argument(
        "--context",
        type=int,
        default=0,
        metavar="K",
        help="learn K maps of the whole window with the head: a cell U-Net on the network's "
        "inputs and keep logits, read at each event's cell (0: none)",
    )
    p.add_argument(
        "--context-widths",
        type=_widths,
        default=(16, 32, 64, 64),
        help="level widths of the context's U-Net",
    )
    p.add_argument(
        "--relative-context",
        action="store_true",
        help="the context reads each cell's event counts relative to its window's mean count "
        "(the same at any event rate; needs --context)",
    )
    p.add_argument(
        "--light-weight",
        type=float,
        default=1.0,
        metavar="W",
        help="weigh the light's own events (matched to each pair's light stream) W times their "
        "class in the loss",
    )
    p.add_argument(
        "--scene-weight",
        type=float,
        default=1.0,
        metavar="W",
        help="weigh the events of each pair's scene alone (a recording without a light) W "
        "times their class in the loss",
    )
    p.add_argument(
        "--windows",
        choices=("all", "lit", "unlit"),
        default="all",
        help="fit the head (and choose its threshold) only on the windows where the light test "
        "finds a light (lit) or finds none (unlit): an expert of a pair, whose card names the "
        "unlit one (edeflare bundle --card unlit_model=...); needs the light_free feature",
    )
    add_thin_option(p)
    p.add_argument("--epochs", type=int, default=8)
    p.add_argument("--lr", type=float, default=3e-3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--members",
        type=int,
        default=1,
        metavar="N",
        help="fit N heads from seeds SEED, SEED+1, ... on the same events and keep their mean "
        "logit (an ensemble: steadier on real recordings than any one seed)",
    )
    p.add_argument(
        "--teacher",
        metavar="WEIGHTS",
        help="learn the keep probabilities of a trained head over the same network (e.g. an "
        "ensemble's RUN/model.safetensors) instead of the labels: one head that decides like it",
    )
    add_workers_option(p)
    p.add_argument(
        "--device",
        default="auto",
        help="where the heads are fitted: auto (CUDA where available), cpu, cuda, cuda:1 ...",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Collect the features, fit the head, choose its threshold, write the run."""
    from ..errors import ParameterError
    from ..models.event_features import DEFAULT_FEATURES, check_feature_names
    from ..models.head_training import HeadTrainingConfig, train_head
    from ..models.infer import resolve_weights

    for name in ("per_window", "epochs", "members", "workers"):
        if getattr(args, name) < 1:
            raise ParameterError(f"--{name.replace('_', '-')} must be at least 1")
    if args.context < 0:
        raise ParameterError(f"--context must be 0 or more, got {args.context}")
    if not args.context_widths:
        raise ParameterError("--context-widths needs at least one width")
    if args.relative_context and not args.context:
        raise ParameterError("--relative-context needs a context (--context K)")
    for name in ("lr", "light_weight", "scene_weight"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"--{name.replace('_', '-')} must be positive, got {value}")
    features = DEFAULT_FEATURES
    if args.features is not None:  # "default" stands for the default set
        names = [f.strip() for f in args.features.split(",") if f.strip()]
        expanded = [n for f in names for n in (DEFAULT_FEATURES if f == "default" else (f,))]
        features = check_feature_names(expanded, "--features")
    config = HeadTrainingConfig(
        features=features,
        hidden=tuple(args.hidden),
        per_window=args.per_window,
        flare_free_windows=args.flare_free_windows,
        context=args.context,
        context_widths=tuple(args.context_widths),
        relative_context=args.relative_context,
        epochs=args.epochs,
        lr=args.lr,
        seed=args.seed,
        members=args.members,
        light_weight=args.light_weight,
        scene_weight=args.scene_weight,
        thin=args.thin,
        windows=args.windows,
    )
    command = "edeflare " + shlex.join(sys.argv[1:]) if sys.argv[1:] else "edeflare train-head"
    summary = train_head(
        args.data,
        resolve_weights(args.weights),
        args.out,
        config,
        command=command,
        teacher=None if args.teacher is None else resolve_weights(args.teacher),
        progress=not args.no_progress,
        workers=args.workers,
        device=args.device,
    )
    best = max(summary["threshold_table"], key=lambda r: r["score"])
    print(
        f"keep threshold {summary['keep_threshold']:.2f} (score {best['score']:.3f} on "
        f"{summary['chosen_on']}); {summary['train_events']:,} training events"
    )
    print(f"wrote {args.out / 'model.safetensors'} and {args.out / 'head.json'}")
    return 0
