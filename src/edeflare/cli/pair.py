"""``edeflare pair OBSERVATION REFERENCE OUT``: a paired benchmark from two real captures."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import SIZE_HELP, ms_to_us, sensor_size_arg

HELP = (
    "Pair a real capture with a flare filter (observation) and without (reference): "
    "strobe alignment, glare cleaning, noise, crop, 100 ms windows."
)


def _crop_arg(text: str) -> tuple[int, int] | None:
    if text.lower() == "none":
        return None
    return sensor_size_arg(text)


def _noise_arg(text: str) -> float | None:
    if text.lower() == "auto":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"noise rate must be 'auto' or a rate in Hz per pixel, got {text!r}"
        ) from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"noise rate must be >= 0, got {text!r}")
    return value


def add_parser(sub: argparse._SubParsersAction, **kwargs: object) -> None:
    """Register the command."""
    p = sub.add_parser(
        "pair",
        help=HELP,
        description=HELP + " Writes OUT/SPLIT/NAME_0000.h5 ... (groups input and gt, as "
        "simulated datasets), OUT/SPLIT/input and OUT/SPLIT/gt (the same windows as single "
        "streams), OUT/alignment/NAME.png and OUT/manifest.json (written last; one folder can "
        "collect many scenes). Then: edeflare benchmark OUT/test.",
        **kwargs,
    )
    p.add_argument("observation", type=Path, help="the pass with the filter (any readable format)")
    p.add_argument("reference", type=Path, help="the pass without the filter")
    p.add_argument("out", type=Path, help="dataset folder")
    p.add_argument("--name", help="scene name, the prefix of its files [observation file stem]")
    p.add_argument("--split", default="test", help="sub-folder of the windows")
    g = p.add_argument_group("alignment (strobe polarity signature)")
    g.add_argument(
        "--max-offset-ms",
        type=float,
        default=1000.0,
        help="search the offset within this much of the expected one; with a periodic strobe "
        "keep it under half the period or the match is ambiguous",
    )
    g.add_argument(
        "--expected-offset-ms",
        type=float,
        help="centre of the search: t_reference - t_observation [first events aligned]",
    )
    g.add_argument("--bin-ms", type=float, default=1.0, help="coarse search bin (ms)")
    g.add_argument(
        "--refine-bin-ms", type=float, default=0.1, help="fine bin of the refinement (ms)"
    )
    g.add_argument(
        "--min-confidence",
        type=float,
        default=0.0,
        help="refuse alignments below this confidence (0..1); below 0.1 a warning is printed",
    )
    g = p.add_argument_group("reference cleaning")
    g.add_argument(
        "--light",
        action="append",
        default=[],
        metavar="SPEC",
        help="a light source in sensor pixels: circle:CX,CY,R, polygon:X1,Y1,X2,Y2,..., "
        "or a .json file of them (repeat for several)",
    )
    g.add_argument(
        "--detect-light",
        action="store_true",
        help="also find the light as the brightest compact region of the reference",
    )
    g.add_argument(
        "--glare-radius",
        type=float,
        default=40.0,
        metavar="PX",
        help="remove reference events within this distance of a light (outside it)",
    )
    g = p.add_argument_group("noise, crop and slicing")
    g.add_argument(
        "--noise-rate",
        type=_noise_arg,
        default="auto",
        metavar="auto|HZ",
        help="background noise added to the ground truth, per pixel and second; auto: "
        "measured in quiet regions of the observation",
    )
    g.add_argument(
        "--noise-region",
        choices=["cleaned", "all"],
        default="cleaned",
        help="where noise is added: the cleaned glare zone, or every pixel",
    )
    g.add_argument(
        "--crop",
        type=_crop_arg,
        default="640x480",
        metavar="WxH|none",
        help="centre crop (none: the whole sensor)",
    )
    g.add_argument("--window-ms", type=float, default=100.0, help="length of one sequence (ms)")
    g.add_argument("--seed", type=int, default=0, help="seed of the injected noise")
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH", help=SIZE_HELP)
    g.add_argument(
        "--no-stream-files",
        action="store_true",
        help="write only the paired sequence files (not OUT/SPLIT/input and OUT/SPLIT/gt)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build the configuration, pair the recordings, print a summary."""
    from ..lights import parse_lights
    from ..realworld import PairConfig, pair_recordings

    config = PairConfig(
        name=args.name,
        split=args.split,
        sensor_size=args.sensor_size,
        bin_us=ms_to_us(args.bin_ms),
        refine_bin_us=ms_to_us(args.refine_bin_ms),
        max_offset_us=ms_to_us(args.max_offset_ms),
        expected_offset_us=ms_to_us(args.expected_offset_ms),
        min_confidence=args.min_confidence,
        lights=tuple(parse_lights(args.light)),
        detect_light=args.detect_light,
        glare_radius_px=args.glare_radius,
        noise_rate_hz=args.noise_rate,
        noise_region=args.noise_region,
        crop=args.crop,
        window_us=ms_to_us(args.window_ms),
        seed=args.seed,
        stream_files=not args.no_stream_files,
    )
    report = pair_recordings(
        args.observation, args.reference, args.out, config, progress=not args.no_progress
    )
    a = report.alignment
    scene = report.entry
    print(
        f"{report.name}: offset {a.offset_us / 1000:.3f} ms (t_reference - t_observation), "
        f"confidence {a.confidence:.3f} (peak {a.correlation:.3f}, second {a.second_peak:.3f})"
    )
    lights = ", ".join(str(s) for s in report.lights) or "none"
    noise = scene["noise"]
    source = "measured" if noise["measured"] else "given"
    print(
        f"lights: {lights}; glare zone removed {scene['events']['removed']:,} reference events; "
        f"noise {report.noise_rate_hz:.4g} Hz/pixel ({source}) added "
        f"{scene['events']['noise']:,} events on {noise['region_pixels']:,} pixels"
    )
    crop = scene["crop"]
    print(
        f"wrote {len(report.files)} windows of {scene['window_us'] / 1000:g} ms at "
        f"{crop['width']}x{crop['height']} to {args.out / config.split}; "
        f"plot {report.plot_path}; manifest {report.manifest_path}"
    )
    return 0
