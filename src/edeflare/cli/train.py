"""``edeflare train``: train E-DeflareNet on sequence files (one process or torchrun)."""

from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
import sys
from pathlib import Path

HELP = (
    "Train E-DeflareNet on paired sequences (DATA/train, optional DATA/test; several DATA "
    "folders side by side); resumes."
)


def _crop(text: str) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"crop must look like 128x128 (HxW), got {text!r}"
        ) from None
    return h, w


def _milestones(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"milestones must be epochs separated by commas (e.g. 10,20,30; '' for none), "
            f"got {text!r}"
        ) from None


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser(
        "train",
        help=HELP,
        description=HELP + " Run under `torchrun --nproc_per_node N -m edeflare train ...` for DDP "
        "(NCCL on GPUs, gloo on CPUs). Unset options take the --config preset's values.",
        **kwargs,
    )
    p.add_argument(
        "data",
        type=Path,
        nargs="+",
        help="dataset folder(s) with train/ (and test/) *.h5 sequences, or mix folders "
        "(--recipe eflare-mix: each stands for its parts' folders, in the mix's order); with "
        "several, the training windows are those of every folder's train/ in the order given "
        "(each folder's files sorted by name), and the validation windows those of their test/",
    )
    p.add_argument(
        "--out", type=Path, required=True, help="run folder (resumed if it has a checkpoint)"
    )
    p.add_argument(
        "--config",
        choices=["paper", "cpu"],
        default="cpu",
        help="base configuration: the paper's, or a light one for CPUs",
    )
    p.add_argument("--preset", help="model preset (see edeflare.models.list_models())")
    p.add_argument("--iterations", type=int)
    p.add_argument("--batch-size", type=int, help="windows per process and iteration")
    p.add_argument("--lr", type=float)
    p.add_argument(
        "--loss",
        choices=["mse", "keep"],
        help="mse: of the voxel grids; keep: class-balanced cross-entropy of the per-event keep "
        "decisions (mask presets, on keep-only targets)",
    )
    p.add_argument(
        "--keep-weight",
        type=float,
        help="--loss keep: the share of the loss on the events to keep (0.5: balanced; "
        "higher drops only where surer)",
    )
    p.add_argument(
        "--keep-cells",
        choices=["bin", "window"],
        help="--loss keep: match the target's event counts per voxel bin, or per pixel and "
        "polarity over the whole window (lenient to events the flare shifts in time)",
    )
    p.add_argument(
        "--crop",
        type=_crop,
        metavar="HxW",
        help="random crop size (needed when the sequences have several sensor sizes)",
    )
    p.add_argument(
        "--flip",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="random horizontal and vertical flips of the training windows",
    )
    p.add_argument(
        "--milestones",
        type=_milestones,
        metavar="EPOCHS",
        help="epochs at which the learning rate is multiplied by the preset's gamma, "
        "separated by commas ('' for none)",
    )
    p.add_argument(
        "--time-shift",
        action="store_true",
        default=None,
        help="shift each training window's start by a random whole number of bins, so the "
        "model cannot learn where in its window things happen (a lamp's flicker, a source's "
        "motion start at any phase of a real recording's windows)",
    )
    p.add_argument(
        "--polarity-flip",
        action="store_true",
        default=None,
        help="swap ON and OFF in a random half of the training windows (which polarity a "
        "light's edges and settling pixels fire differs between sensors)",
    )
    p.add_argument("--seed", type=int)
    p.add_argument("--val-every", type=int)
    p.add_argument("--val-windows", type=int, help="validation windows per validation")
    p.add_argument("--checkpoint-every", type=int)
    p.add_argument("--workers", type=int, dest="num_workers", help="data loader processes")
    p.add_argument(
        "--precompute",
        action="store_true",
        default=None,
        help="encode every training window once and keep the grids in memory",
    )
    p.add_argument("--device", help="auto, cpu, cuda, cuda:1 ...")
    p.add_argument(
        "--time-limit",
        type=float,
        dest="time_limit_min",
        metavar="MINUTES",
        help="stop after this many minutes of training, checkpointed: model.safetensors holds "
        "the weights reached, and rerunning the same command resumes (for time-limited jobs)",
    )
    p.add_argument(
        "--init",
        metavar="WEIGHTS",
        help="start from these weights (.safetensors or a bundled model's name, e.g. night): "
        "fine-tuning; layers the preset adds start fresh",
    )
    p.add_argument(
        "--freeze-init",
        action="store_true",
        default=None,
        help="with --init: train only the layers the preset adds (e.g. mask.pixel's "
        "refinement on mask.fast weights)",
    )
    p.set_defaults(func=run, resumes=True)


def run(args: argparse.Namespace) -> int:
    """Build the configuration, then train."""
    from ..data.folders import dataset_files
    from ..train import TRAIN_PRESETS, train

    base = TRAIN_PRESETS[args.config]
    overrides = {
        f.name: getattr(args, f.name)
        for f in dataclasses.fields(base)
        if f.name != "data" and getattr(args, f.name, None) is not None
    }
    data = " ".join(str(folder) for folder in args.data)
    config = dataclasses.replace(base, **overrides, data=data)
    train_paths, val_paths = dataset_files(args.data)
    final = train(
        config,
        train_paths,
        args.out,
        val_paths=val_paths or None,
        command="edeflare " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
    )
    if int(os.environ.get("RANK", "0")) == 0:  # once, not per DDP process
        from ..models.weights import read_card

        done = int(read_card(final).metrics.get("iteration", config.iterations))
        of = "" if done == config.iterations else f" of {config.iterations} (time limit)"
        print(f"trained {config.preset} for {done}{of} iterations: {final}")
    return 0
