"""``edeflare simulate OUT``: generate a paired dataset (parallel, sharded, resumable).

Also the test sets ``eflare-r-sim`` / ``eflare-r-sim-mini`` (the paper's real-capture
model, simulated), ``eflare-forward`` / ``eflare-forward-hd`` (the full forward model)
and ``dsec-flare`` (windows of a local DSEC copy, ``--dsec-root``), and mixes
(``eflare-mix``: each part a dataset of its own in ``OUT/<part>/``).
"""

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
        "use --shard i/n for array jobs. The test-set recipes put every sequence in OUT/test: "
        "eflare-r-sim(-mini) simulates lit sources (point light, square lamp, strobe) behind "
        "a star or random-pattern filter and the clean lens, one sensor draw per pair; "
        "dsec-flare cuts the paper's DSEC-Flare windows from your DSEC copy "
        "(--dsec-root; nothing is downloaded) into files with an input group only "
        "(no ground truth: for edeflare deflare / view, not for benchmark); eflare-forward(-hd) "
        "simulates dense flare and its flare-free twin through the full forward model. A mix "
        "(eflare-mix) writes each part as a dataset of its own in OUT/<part>/ and "
        "OUT/manifest.json listing them; edeflare train OUT trains on every part; --shard "
        "splits the sequences of all parts.",
        **kwargs,
    )
    p.add_argument("out", type=Path, help="dataset folder")
    p.add_argument(
        "--recipe",
        default="eflare-mini",
        help="eflare-2.7k (the paper's: 544 x 100 ms at 640x480), eflare-mini (120 at 346x260), "
        "eflare-night (180 at 346x260, calibrated on real night recordings), eflare-night-sparse "
        "(the same with sparse backgrounds and ghosts sensed at their own rate), "
        "eflare-day-street (72 at 346x260: eflare-night's lights and flare over a street lit as "
        "by day); eflare-mix (a mix: 128 sequences in five parts, each its own dataset in "
        "OUT/<part>/: night-346 and day-346 (eflare-night, eflare-day-street), dense-640 and "
        "dense-1280 (dense flare of strong sources through the full forward model at 640x480 "
        "and 1280x720), sparse-1280 (eflare-night at 1280x720); 11-15 minutes with "
        "--workers 2 on 2 cores); eflare-gaps (a mix to train beside it: dense-640 with the "
        "scene alone stored, sparse-346 of eflare-night-sparse; 60 sequences); eflare-day (a "
        "mix of day streets at 640x480 and 1280x720 under weak and strong sources, still and "
        "seen from a driving car, the scene alone stored; 72 sequences); eflare-train (a mix "
        "of eflare-mix's and eflare-day's parts and fast-640, large fast lights over night "
        "streets at 640x480; 218 sequences); eflare-lit (a mix of lamps lighting the scene "
        "around them, flickering: the forward model at 346x260 and 640x480; 40 sequences); "
        "eflare-near (a mix of large textured objects swinging fast close to the camera, no "
        "light, before night and day streets under sparse and dense flare, the scene alone "
        "stored; 49 sequences); "
        "test sets: "
        "eflare-r-sim (30 at 640x480), eflare-r-sim-mini (20 at 346x260), "
        "eflare-forward (12 at 640x480) and eflare-forward-hd (4 at 1280x720: dense flare "
        "through the full forward model, with ground truth), "
        "dsec-flare (15 DSEC windows of 100 ms at 640x480, needs --dsec-root)",
    )
    p.add_argument(
        "--sequences",
        type=int,
        help="number of sequences (a test set's stay all in test unless --test-sequences)",
    )
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
    g = p.add_argument_group("dsec-flare")
    g.add_argument(
        "--dsec-root",
        type=Path,
        metavar="PATH",
        help="local DSEC folder holding <seq>/events/left/events.h5 (or train|test/<seq>/...)",
    )
    g.add_argument(
        "--dsec-window",
        action="append",
        metavar="SEQ[:SECONDS[:COUNT]]",
        help="COUNT (3) windows of 100 ms centred on SECONDS (default: mid-recording) of a "
        "sequence; repeat it; replaces the default windows (3 around 7.6 s of "
        "zurich_city_03_a and 26 s of zurich_city_09_c, 3 mid-recording of zurich_city_10_b, "
        "zurich_city_12_a, zurich_city_09_d)",
    )
    g.add_argument("--rectify", action="store_true", help="move events by DSEC's rectify_map.h5")
    p.add_argument("--workers", type=int, default=1, help="worker processes")
    p.add_argument(
        "--shard", default="0/1", metavar="I/N", help="make sequences with index %% N == I"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run, resumes=True)


def run(args: argparse.Namespace) -> int:
    """Build the recipe from the options, generate, print a summary."""
    from ..data.dsec_flare import parse_window
    from ..data.generate import RECIPES, Mix, generate_dataset
    from ..data.kinds import get_kind
    from ..errors import ParameterError

    base = RECIPES[args.recipe]  # an unknown name is an error listing the valid ones
    if isinstance(base, Mix):
        return _run_mix(base, args)
    kind = get_kind(base.kind)
    given = {  # the kind-specific options (data.kinds.KIND_OPTIONS) given
        "--test-sequences": args.test_sequences is not None,
        "--sequences": args.sequences is not None,
        "--variant": args.variant is not None,
        "--weights": args.weights is not None,
        "--flare7k": args.flare7k is not None,
        "--no-components": args.no_components,
        "--background": bool(args.background),
        "--dsec-root": args.dsec_root is not None,
        "--dsec-window": bool(args.dsec_window),
        "--rectify": args.rectify,
    }
    bad = [name for name, yes in given.items() if yes and name not in kind.cli_options]
    if bad:
        raise ParameterError(
            f"option(s) {', '.join(bad)} do not apply to --recipe {args.recipe} (test sets "
            "put every sequence in test/; dsec-flare's windows set the number of sequences)"
        )
    changes: dict[str, object] = {}
    for key in ("sequences", "test_sequences", "sensor_size", "variant", "weights", "seed"):
        if getattr(args, key) is not None:
            changes[key] = getattr(args, key)
    if "sequences" in changes and "test_sequences" not in changes:
        if base.test_sequences == base.sequences:  # a test set stays all test
            changes["test_sequences"] = changes["sequences"]
    if args.duration_ms is not None:
        changes["duration_us"] = round(args.duration_ms * 1000)
    if args.background:
        changes["background"] = "recorded"
        changes["background_files"] = tuple(str(p) for p in args.background)
    if args.flare7k is not None:
        changes["flare7k"] = str(args.flare7k)
    if args.no_components:
        changes["components"] = False
    if "--dsec-root" in kind.cli_options:  # the DSEC windows' config
        dsec = base.config
        if args.dsec_root is not None:
            dsec = dataclasses.replace(dsec, root=str(args.dsec_root))
        if args.dsec_window:
            dsec = dataclasses.replace(dsec, windows=tuple(map(parse_window, args.dsec_window)))
        changes["config"] = dataclasses.replace(dsec, rectify=args.rectify)
    recipe = base.replace(**changes)
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


_RECIPE_OPTIONS = {
    "sequences": "--sequences",
    "test_sequences": "--test-sequences",
    "duration_ms": "--duration-ms",
    "sensor_size": "--sensor-size",
    "background": "--background",
    "variant": "--variant",
    "weights": "--weights",
    "seed": "--seed",
    "flare7k": "--flare7k",
    "no_components": "--no-components",
    "dsec_root": "--dsec-root",
    "dsec_window": "--dsec-window",
    "rectify": "--rectify",
}


def _run_mix(mix: object, args: argparse.Namespace) -> int:
    """Generate a mix: its parts' recipes as they are (only --workers and --shard apply)."""
    from ..data.generate import generate_dataset
    from ..errors import ParameterError

    given = [
        flag
        for key, flag in _RECIPE_OPTIONS.items()
        if getattr(args, key) is not None and getattr(args, key) is not False
    ]
    if given:
        raise ParameterError(
            f"option(s) {', '.join(given)} do not apply to the mix {args.recipe} (its parts are "
            "recipes of their own; simulate one with its own --recipe to change it)"
        )
    report = generate_dataset(
        mix, args.out, workers=args.workers, shard=args.shard, progress=not args.no_progress
    )
    m = report.manifest
    state = "complete" if m["complete"] else f"{m['done']}/{m['sequences']} sequences so far"
    parts = ", ".join(p["folder"] for p in m["parts"])
    print(
        f"{m['name']}: {report.generated} sequences made, {report.skipped} already there "
        f"({report.wall_seconds:.1f} s); mix {state} (parts {parts}); manifest "
        f"{report.manifest_path}"
    )
    return 0
