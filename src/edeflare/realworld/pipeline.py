"""The whole pipeline: two recordings in, paired benchmark windows and a manifest out."""

from __future__ import annotations

import json
import math
import os
import re
import warnings
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import EventFileError, ParameterError
from ..events import SensorSize, center_crop, check_sensor_size, merge_events
from ..io import EventSource, open_events, write_events
from ..io._atomic import atomic_path
from ..io.sequence import file_sha256, write_sequence
from ..lights import Circle, LightSource, Polygon, Shape, detect_light_source, light_mask
from ._common import (
    LOW_CONFIDENCE,
    MANIFEST_FORMAT,
    PairingError,
    _pixel_mask_of,
    _positive_int,
    _progress,
)
from .align import Alignment, estimate_offset
from .geometry import glare_mask
from .noise import NoiseEstimate, draw_noise, estimate_background_rate
from .plot import plot_alignment
from .signature import RecordingScan, scan_recording

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


@dataclass(frozen=True)
class PairConfig:
    """How :func:`pair_recordings` turns two passes into paired windows.

    Parameters
    ----------
    name : str, optional
        Scene name, the prefix of its files (default: the observation's file stem).
    split : str
        Sub-folder of the output (``test``: E-Flare-R is a test set).
    sensor_size : (width, height), optional
        For files that record none.
    bin_us, refine_bin_us : int
        Coarse search bin and signature (fine) bin of the alignment.
    max_offset_us : int
        Half-width of the offset search (see :func:`estimate_offset`).
    expected_offset_us : int, optional
        Centre of the search (default: the recordings' first events aligned).
    min_confidence : float
        Refuse alignments below this confidence (0: never refuse; below
        :data:`LOW_CONFIDENCE` a warning is issued).
    lights : tuple of Circle or Polygon
        Light sources in full-sensor pixel coordinates.
    detect_light : bool
        Add the brightest compact region of the reference (:func:`detect_light_source`).
    glare_radius_px : float
        Width of the glare zone removed from the reference around each source.
    noise_rate_hz : float, optional
        Background noise rate per pixel to inject; None measures it (and its
        ON fraction) on the observation (:func:`estimate_background_rate`);
        a given rate injects 50 % ON events; 0 injects none.
    noise_region : {"cleaned", "all"}
        Where noise is injected: the glare zone that cleaning emptied
        (default; the rest of the reference keeps its own recorded
        background activity, which noise there would double), or every pixel.
    crop : (width, height), optional
        Centre crop (default 640x480, the paper's); None keeps the full sensor.
    window_us : int
        Length of one output sequence (default 100 ms, the paper's); windows
        are aligned to multiples of it on the observation's clock and only
        complete ones within the overlap of both passes are written.
    seed : int
        Seeds the noise: window ``k`` draws from
        ``SeedSequence([seed, crc32(name), k])``.
    stream_files : bool
        Also write each window's input and ground truth as separate DSEC
        files under ``split/input`` and ``split/gt`` (for ``edeflare
        deflare`` and ``edeflare evaluate``).
    """

    name: str | None = None
    split: str = "test"
    sensor_size: SensorSize | None = None
    bin_us: int = 1_000
    refine_bin_us: int = 100
    max_offset_us: int = 1_000_000
    expected_offset_us: int | None = None
    min_confidence: float = 0.0
    lights: tuple[LightSource | Shape, ...] = ()
    detect_light: bool = False
    glare_radius_px: float = 40.0
    noise_rate_hz: float | None = None
    noise_region: str = "cleaned"
    crop: SensorSize | None = (640, 480)
    window_us: int = 100_000
    seed: int = 0
    stream_files: bool = True

    def __post_init__(self) -> None:
        if self.name is not None and not _NAME.fullmatch(self.name):
            raise ParameterError(
                f"name must be letters, digits, '_', '.', '-' (not starting with them), "
                f"got {self.name!r}"
            )
        if not _NAME.fullmatch(self.split):
            raise ParameterError(f"split must be a plain folder name, got {self.split!r}")
        if self.sensor_size is not None:
            object.__setattr__(self, "sensor_size", check_sensor_size(self.sensor_size))
        if self.crop is not None:
            object.__setattr__(self, "crop", check_sensor_size(self.crop))
        for key in ("bin_us", "refine_bin_us", "window_us"):
            _positive_int(key, getattr(self, key))
        if self.bin_us % self.refine_bin_us:
            raise ParameterError(
                f"bin_us {self.bin_us} must be a multiple of refine_bin_us {self.refine_bin_us}"
            )
        if self.max_offset_us < 0:
            raise ParameterError(f"max_offset_us must be >= 0, got {self.max_offset_us}")
        if not 0 <= self.min_confidence <= 1:
            raise ParameterError(f"min_confidence must lie in [0, 1], got {self.min_confidence}")
        shapes = []
        for light in self.lights:
            if isinstance(light, LightSource):
                light = light.shape  # a fixed source's outline (a moving one has none)
            if not isinstance(light, (Circle, Polygon)):
                raise ParameterError(f"lights must be light sources, got {light!r}")
            shapes.append(light)
        object.__setattr__(self, "lights", tuple(shapes))
        if not math.isfinite(self.glare_radius_px) or self.glare_radius_px < 0:
            raise ParameterError(f"glare_radius_px must be >= 0, got {self.glare_radius_px}")
        if self.noise_rate_hz is not None and (
            not math.isfinite(self.noise_rate_hz) or self.noise_rate_hz < 0
        ):
            raise ParameterError(f"noise_rate_hz must be >= 0, got {self.noise_rate_hz}")
        if self.noise_region not in ("cleaned", "all"):
            raise ParameterError(
                f"noise_region must be 'cleaned' or 'all', got {self.noise_region!r}"
            )
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)):
            raise ParameterError(f"seed must be an int, got {self.seed!r}")
        if self.seed < 0:
            raise ParameterError(f"seed must be >= 0, got {self.seed}")


@dataclass(frozen=True)
class PairReport:
    """What :func:`pair_recordings` did.

    Attributes
    ----------
    name : str
        Scene name.
    alignment : Alignment
    lights : tuple of Circle or Polygon
        Light sources used (given and detected), full-sensor coordinates.
    noise_rate_hz : float
        Noise injected per pixel and second.
    noise : NoiseEstimate or None
        The measurement, when the rate was measured.
    files : list of Path
        Sequence files written.
    manifest_path, plot_path : Path
    entry : dict
        The scene's manifest entry.
    """

    name: str
    alignment: Alignment
    lights: tuple[Shape, ...]
    noise_rate_hz: float
    noise: NoiseEstimate | None
    files: list[Path]
    manifest_path: Path
    plot_path: Path
    entry: dict[str, Any] = field(repr=False)


def _read_manifest(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        raise EventFileError(
            path, "is not a readable manifest; write the pairs to another folder"
        ) from None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        fmt = data.get("format") if isinstance(data, dict) else None
        raise EventFileError(
            path,
            f"belongs to another kind of dataset (format {fmt!r}, not {MANIFEST_FORMAT!r}); "
            "write the pairs to another folder",
        )
    if not isinstance(data.get("scenes"), dict):
        raise EventFileError(path, "has no 'scenes'; write the pairs to another folder")
    return data


def _file_info(source: EventSource, scan: RecordingScan) -> dict[str, Any]:
    return {
        "file": source.path.name,
        "path": str(source.path.resolve()),
        "format": source.format,
        "bytes": source.path.stat().st_size,
        "events": scan.n_events,
        "sensor_size": list(scan.sensor_size),
        "t_first_us": scan.t_first_us,
        "t_last_us": scan.t_last_us,
    }


def _remove_stale(folders: Sequence[Path], name: str, keep: set[str]) -> None:
    """Delete the scene's ``NAME_dddd.h5`` files this run did not write, and killed runs' temps."""
    pattern = re.compile(rf"{re.escape(name)}_\d{{4,}}\.h5")
    partial = re.compile(rf"\.{re.escape(name)}_\d{{4,}}\.h5\..*\.partial\.h5")
    for folder in folders:
        if not folder.is_dir():
            continue
        for path in folder.iterdir():
            if (pattern.fullmatch(path.name) and path.name not in keep) or partial.fullmatch(
                path.name
            ):
                path.unlink()


def pair_recordings(
    observation: str | os.PathLike[str],
    reference: str | os.PathLike[str],
    out: str | os.PathLike[str],
    config: PairConfig = PairConfig(),
    *,
    progress: bool = True,
) -> PairReport:
    """Turn an observation pass and a reference pass into paired benchmark windows.

    Two streaming passes over each file: the first measures the polarity
    signature, the per-pixel counts and the span (:func:`scan_recording`);
    then the offset is estimated (:func:`estimate_offset`), the light sources
    are taken from ``config.lights`` and/or detected on the reference, the
    background rate is measured on the observation (away from the sources and
    their glare); the second pass reads both files window by window (the
    reference shifted onto the observation's clock), cleans the reference
    (:func:`clean_reference`), centre-crops both, injects noise
    (:func:`inject_noise`) and writes one sequence file per window. Memory
    holds one window of each pass, the signatures and four count maps.

    The manifest is written last and updated per scene, so a folder can
    collect many scenes (run one after the other, not concurrently); a run
    killed midway leaves complete files but no manifest entry, and rerunning
    the same command finishes cleanly (files of the scene that the new run
    does not write are deleted).

    Parameters
    ----------
    observation, reference : path-like
        The pass with the filter (input) and without (ground truth source).
    out : path-like
        Dataset folder (see the module docstring for its layout).
    config : PairConfig
    progress : bool
        Progress bars on stderr.

    Returns
    -------
    PairReport

    Raises
    ------
    EventFileError
        Unreadable or empty recordings, a foreign manifest in ``out``.
    PairingError
        Mismatched sensor sizes, an alignment below ``min_confidence``, no
        complete window in the overlap of the aligned passes.
    ParameterError
        A crop larger than the sensor, lights entirely off the sensor.
    """
    cfg = config
    obs_path, ref_path, out = Path(observation), Path(reference), Path(out)
    obs_src = open_events(obs_path, cfg.sensor_size)
    ref_src = open_events(ref_path, cfg.sensor_size)
    size = obs_src.sensor_size
    if ref_src.sensor_size != size:
        raise PairingError(
            f"{obs_path}: sensor {size[0]}x{size[1]} differs from the reference's "
            f"{ref_src.sensor_size[0]}x{ref_src.sensor_size[1]} ({ref_path}); the two passes "
            "must come from the same camera (use --sensor-size for files that record none)"
        )
    crop = cfg.crop or size
    if crop[0] > size[0] or crop[1] > size[1]:
        raise ParameterError(
            f"crop {crop[0]}x{crop[1]} does not fit the {size[0]}x{size[1]} sensor of "
            f"{obs_path}; choose a smaller crop or none"
        )
    x0, y0 = (size[0] - crop[0]) // 2, (size[1] - crop[1]) // 2
    for light in cfg.lights:
        if not light_mask([light], size).any():
            raise ParameterError(f"light {light} covers no pixel of the {size[0]}x{size[1]} sensor")
    name = cfg.name or obs_path.stem
    if not _NAME.fullmatch(name):
        raise ParameterError(
            f"scene name {name!r} (from {obs_path.name}) is not a plain file name; pass a name"
        )
    manifest_path = out / "manifest.json"
    manifest = _read_manifest(manifest_path)  # refuse a foreign folder before any work
    if manifest is not None:
        others = {k: v for k, v in manifest["scenes"].items() if k != name}
        if others and manifest.get("sensor_size") != list(crop):
            raise PairingError(
                f"{out} holds pairs of {manifest.get('sensor_size')} (width, height); this scene "
                f"would be {crop[0]}x{crop[1]}: use the same crop or another folder"
            )

    obs_scan = scan_recording(obs_src, cfg.refine_bin_us, progress=progress)
    ref_scan = scan_recording(ref_src, cfg.refine_bin_us, progress=progress)
    for path, scan in ((obs_path, obs_scan), (ref_path, ref_scan)):
        if scan.n_events == 0:
            raise EventFileError(path, "holds no events")
    lights = list(cfg.lights)
    detected: list[Circle] = []
    if cfg.detect_light:
        try:
            detected = detect_light_source(ref_scan.counts)
        except ParameterError as exc:
            raise PairingError(f"{ref_path}: cannot detect a light source: {exc}") from None
        lights.extend(detected)

    try:
        alignment = estimate_offset(
            obs_scan.signature,
            ref_scan.signature,
            max_offset_us=cfg.max_offset_us,
            expected_offset_us=cfg.expected_offset_us,
            bin_us=cfg.bin_us,
        )
    except PairingError as exc:
        raise PairingError(f"{obs_path} and {ref_path}: {exc}") from None
    if alignment.confidence < cfg.min_confidence:
        raise PairingError(
            f"{obs_path} and {ref_path}: alignment confidence {alignment.confidence:.3f} is "
            f"below {cfg.min_confidence} ({alignment.describe()}); narrow max_offset around a "
            "known expected offset, or use a non-periodic strobe"
        )
    if alignment.confidence < LOW_CONFIDENCE:
        warnings.warn(
            f"{name}: low alignment confidence {alignment.confidence:.3f} "
            f"({alignment.describe()}); check {out / 'alignment' / (name + '.png')}",
            stacklevel=2,
        )
    shift = round(alignment.offset_us)
    window = cfg.window_us
    overlap_start = max(obs_scan.t_first_us, ref_scan.t_first_us - shift)
    overlap_end = min(obs_scan.t_last_us, ref_scan.t_last_us - shift) + 1
    first = -(-overlap_start // window) * window
    n_windows = max(0, (overlap_end - first) // window)
    if n_windows == 0:
        raise PairingError(
            f"{obs_path} and {ref_path}: after alignment (offset {shift / 1000:.3f} ms) the "
            f"passes overlap for {max(0, overlap_end - overlap_start) / 1000:.1f} ms, which holds "
            f"no complete {window / 1000:g} ms window"
        )

    sources = light_mask(lights, size)
    glare = glare_mask(lights, size, cfg.glare_radius_px)
    noise_est: NoiseEstimate | None = None
    if cfg.noise_rate_hz is None:
        try:
            noise_est = estimate_background_rate(
                obs_scan.counts,
                obs_scan.duration_us,
                on_counts=obs_scan.on_counts,
                exclude=sources | glare,
            )
        except ParameterError as exc:
            raise PairingError(f"{obs_path}: {exc}") from None
        rate, on_fraction = noise_est.rate_hz, noise_est.on_fraction
    else:
        rate, on_fraction = float(cfg.noise_rate_hz), 0.5
    crop_rows = slice(y0, y0 + crop[1])
    crop_cols = slice(x0, x0 + crop[0])
    region = (
        glare[crop_rows, crop_cols]
        if cfg.noise_region == "cleaned"
        else np.ones((crop[1], crop[0]), dtype=bool)
    )

    plot_path = out / "alignment" / f"{name}.png"
    plot_alignment(
        obs_scan.signature,
        ref_scan.signature,
        alignment,
        plot_path,
        expected_offset_us=cfg.expected_offset_us,
    )

    split_dir = out / cfg.split
    from .._version import __version__

    base_attrs = {
        "scene": name,
        "observation": obs_path.name,
        "reference": ref_path.name,
        "offset_us": float(alignment.offset_us),
        "alignment_confidence": float(alignment.confidence),
        "noise_rate_hz": float(rate),
        "crop": json.dumps([x0, y0, crop[0], crop[1]]),
        "source": "edeflare pair",
        "edeflare_version": __version__,
    }
    name_key = zlib.crc32(name.encode("utf-8"))
    files: list[Path] = []
    entries: list[dict[str, Any]] = []
    totals = {"input": 0, "gt": 0, "removed": 0, "noise": 0}
    obs_windows = obs_src.windows(window, start_us=first, end_us=first + n_windows * window)
    ref_windows = ref_src.windows(
        window, start_us=first + shift, end_us=first + shift + n_windows * window
    )
    with _progress(n_windows, f"pair {name}", progress, unit="window") as bar:
        for k, ((start, obs_w), (_, ref_w)) in enumerate(
            zip(obs_windows, ref_windows, strict=True)
        ):
            ref_w = ref_w.copy()
            ref_w["t"] -= shift
            cleaned = ref_w[~_pixel_mask_of(ref_w, glare)] if lights else ref_w
            inp, _ = center_crop(obs_w, size, crop)
            gt, _ = center_crop(cleaned, size, crop)
            rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, name_key, k]))
            noise = draw_noise(
                crop, rate, start, start + window, mask=region, on_fraction=on_fraction, rng=rng
            )
            gt = merge_events(gt, noise)
            file_name = f"{name}_{k:04d}.h5"
            path = split_dir / file_name
            attrs = {
                **base_attrs,
                "t_start_us": np.int64(start),
                "t_end_us": np.int64(start + window),
                "index": np.int64(k),
                "seed": json.dumps([cfg.seed, name_key, k]),
            }
            streams: dict[str, str] = {}
            if cfg.stream_files:
                for group, events in (("input", inp), ("gt", gt)):
                    write_events(split_dir / group / file_name, events, crop)
                    streams[group] = f"{cfg.split}/{group}/{file_name}"
            write_sequence(path, {"input": inp, "gt": gt}, crop, attrs)
            removed = ref_w.size - cleaned.size
            counts = {"input": inp.size, "gt": gt.size, "removed": removed, "noise": noise.size}
            for key, value in counts.items():
                totals[key] += int(value)
            entry = {
                "file": f"{cfg.split}/{file_name}",
                "scene": name,
                "split": cfg.split,
                "index": k,
                "t_start_us": int(start),
                "t_end_us": int(start + window),
                "events": {key: int(v) for key, v in counts.items()},
                "bytes": path.stat().st_size,
                "sha256": file_sha256(path),
            }
            if streams:
                entry["streams"] = streams
            entries.append(entry)
            files.append(path)
            bar.update(1)

    written = {p.name for p in files}
    folders = [split_dir, split_dir / "input", split_dir / "gt"]
    if manifest is not None and name in manifest["scenes"]:
        old_split = manifest["scenes"][name].get("split")
        if isinstance(old_split, str) and old_split != cfg.split:
            old = out / old_split
            _remove_stale([old, old / "input", old / "gt"], name, set())
    _remove_stale(folders, name, written)

    scene = {
        "split": cfg.split,
        "observation": _file_info(obs_src, obs_scan),
        "reference": _file_info(ref_src, ref_scan),
        "alignment": alignment.to_dict(),
        "overlap_us": [int(overlap_start), int(overlap_end)],
        "lights": [s.to_dict() for s in lights],
        "lights_detected": [s.to_dict() for s in detected],
        "lights_in_crop": [s.shifted(-x0, -y0).to_dict() for s in lights],
        "glare_radius_px": float(cfg.glare_radius_px),
        "noise": {
            "rate_hz": float(rate),
            "on_fraction": float(on_fraction),
            "measured": noise_est.to_dict() if noise_est is not None else None,
            "region": cfg.noise_region,
            "region_pixels": int(region.sum()),
        },
        "crop": {"x0": x0, "y0": y0, "width": crop[0], "height": crop[1]},
        "sensor_size": list(size),
        "window_us": window,
        "windows": n_windows,
        "seed": cfg.seed,
        "seed_rule": "numpy.random.SeedSequence([seed, crc32(scene), window index])",
        "events": totals,
        "plot": plot_path.relative_to(out).as_posix(),
        "files": entries,
    }
    scenes = dict(manifest["scenes"]) if manifest is not None else {}
    scenes[name] = scene
    payload = {
        "format": MANIFEST_FORMAT,
        "edeflare_version": __version__,
        "kind": "real paired captures (edeflare pair)",
        "sensor_size": list(crop),
        "scenes": {k: scenes[k] for k in sorted(scenes)},
        "files": [f for k in sorted(scenes) for f in scenes[k]["files"]],
    }
    with atomic_path(manifest_path) as tmp:
        tmp.write_text(json.dumps(payload, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return PairReport(
        name,
        alignment,
        tuple(lights),
        float(rate),
        noise_est,
        files,
        manifest_path,
        plot_path,
        scene,
    )
