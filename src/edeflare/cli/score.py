"""``edeflare score RECORDING --lights L.json -m NAME ...``: flare score without ground truth."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HELP = (
    "Score de-flaring on a real recording without ground truth: flare removed around the "
    "light sources (halo, ghost), light kept, background kept, one combined score."
)

DESCRIPTION = (
    HELP + " Methods given with -m run now (timed); --pred NAME=PATH scores a de-flared file. "
    "Light sources come from an annotation (JSON: circles, polygons or tracks [t_us, x, y, r] "
    "linear in time) or are detected per window. Combined: the harmonic mean of flare removed, "
    "light kept and background kept."
)


def _named_path(text: str) -> tuple[str, Path]:
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise argparse.ArgumentTypeError(f"--pred must look like NAME=PATH, got {text!r}")
    return name, Path(path)


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    from ..methods import list_methods

    p = sub.add_parser("score", help=HELP, description=DESCRIPTION, **kwargs)
    p.add_argument("recording", type=Path, help="the input recording (any readable format)")
    p.add_argument(
        "-m",
        "--method",
        action="append",
        default=[],
        choices=list_methods(),
        metavar="NAME",
        help="a registered method to run and score (repeatable): " + ", ".join(list_methods()),
    )
    p.add_argument(
        "--pred",
        type=_named_path,
        action="append",
        default=[],
        metavar="NAME=PATH",
        help="a de-flared version of the recording (repeatable)",
    )
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--lights", type=Path, metavar="JSON", help="light-source annotation")
    g.add_argument(
        "--detect-lights",
        action="store_true",
        help="detect the brightest compact regions per window instead",
    )
    p.add_argument("--max-sources", type=int, default=1, help="--detect-lights: sources per window")
    p.add_argument(
        "--fixed-regions",
        action="store_true",
        help="--detect-lights: size each light's halo and ghost by the fixed factors alone "
        "(default: measured from the radial event rate around it, the factors as the least "
        "halo: docs/scoring.md)",
    )
    p.add_argument(
        "--save-lights",
        type=Path,
        metavar="JSON",
        help="--detect-lights: write the lights found, with their regions, as an annotation "
        "(--lights JSON, edeflare tune-head --real REC:JSON) to check and edit",
    )
    p.add_argument("--measure-regions", action="store_true", help=argparse.SUPPRESS)  # the default
    p.add_argument(
        "--window-ms",
        type=float,
        default=20.0,
        help="window of the count comparison (and of detection) (ms)",
    )
    p.add_argument("--margin-px", type=float, help="rim between light and halo [annotation's, 2]")
    p.add_argument(
        "--halo-factor", type=float, help="halo outer radius / source radius [annotation's, 6]"
    )
    p.add_argument(
        "--ghost-factor", type=float, help="ghost disc radius / source radius [annotation's, 2]"
    )
    p.add_argument(
        "--phases",
        type=int,
        default=1,
        help="run each method at this many window phases (the recording delayed by "
        "multiples of window/phases) and report the mean and the worst phase: a model "
        "decides per aligned window and can depend on where a recording's windows start",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of methods that draw")
    p.add_argument("--report", type=Path, help="write the Markdown table to this file")
    p.add_argument("--json", type=Path, help="write the scores as JSON to this file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Score every method, print the table, optionally write it and the JSON (atomically)."""
    from ..errors import EdeflareError
    from ..eval.score import score_recording
    from ..io._atomic import atomic_path

    names = [*args.method, *(name for name, _ in args.pred)]
    if len(set(names)) != len(names):
        raise EdeflareError(f"method names must be unique, got {names}")
    if not args.method and not args.pred:
        raise EdeflareError("nothing to score: give -m NAME and/or --pred NAME=PATH")
    window = round(args.window_ms * 1000)
    if window <= 0 or args.max_sources < 1:
        raise EdeflareError("--window-ms and --max-sources must be positive")
    if args.save_lights is not None and not args.detect_lights:
        raise EdeflareError("--save-lights writes detected lights: give --detect-lights")
    overrides = {
        k: getattr(args, k)
        for k in ("margin_px", "halo_factor", "ghost_factor")
        if getattr(args, k) is not None
    }
    report = score_recording(
        args.recording,
        args.method,
        dict(args.pred),
        None if args.detect_lights else args.lights,
        window_us=window,
        max_sources=args.max_sources,
        overrides=overrides,
        rng=args.seed,
        phases=args.phases,
        measure=not args.fixed_regions,
    )
    markdown = report.to_markdown()
    print(markdown, end="")
    outputs = []
    if args.report is not None:
        outputs.append((args.report, markdown))
    if args.json is not None:
        outputs.append((args.json, json.dumps(report.to_dict(), indent=2) + "\n"))
    for path, text in outputs:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
    if args.save_lights is not None:
        from ..lights import save_lights

        args.save_lights.parent.mkdir(parents=True, exist_ok=True)
        save_lights(
            args.save_lights,
            report.lights,
            sensor_size=list(report.sensor_size),
            recording=str(args.recording),
            method="edeflare score --detect-lights",
        )
        print(f"wrote the {len(report.lights.sources)} light(s) found to {args.save_lights}")
    return 0
