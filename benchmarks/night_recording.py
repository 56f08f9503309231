"""The real 1280x720 night recording behind ``reference_window.py``, scored whole.

``reference_window.py`` digitises one 100 ms panel of a Prophesee 1280x720 night
recording (a bright light with radial scattering streaks and a ghost ring, three small
lights, stars; 10.8 s, 1,218,618 events). The recording itself is a test file of
faery's source distribution (``faery-0.7.1/tests/data/evt3.raw``, EVT 3.0; the same
events as its ``gen4.dat``), which is not in ``../shared``: fetch it once (about 60 MB)::

    curl -LO https://files.pythonhosted.org/packages/27/a5/\
9d5ea080aaec73f2e4641c81ea90d4c7780a655c2a48af09d997e545ed4a/faery-0.7.1.tar.gz
    tar xzf faery-0.7.1.tar.gz faery-0.7.1/tests/data

The script checks its sha256, annotates it (:func:`annotate`, no choice made by eye:
the sizes are ``reference_window_lights.json``'s, made on the panel before any method
ran on this recording), and scores every method with ``edeflare score``'s regions at
four window phases, as ``flare_targets.py`` does the annotated recordings:

- **light**: the night light's disc (18 px: where dv-processing's FastDecay stops keeping
  events in the panel's right half) and the three small lights' (5 px);
- **flare**: the night light's halo out to ``halo_outer_px`` (320 px: the streaks' ends)
  and its ghost disc (140 px) at the light's reflection through the sensor's centre;
- **background** (stars, noise): reported, not scored (``score_background`` false, as
  the panel's annotation).

The camera drifts (about 50 px over the recording), so every source is a **track**:
the upper-right small light (the steadiest blob: found in every 100 ms window) is
followed window by window and the others keep their offsets from it (the medians over
the windows where :func:`~edeflare.lights.detect_light_source` finds them).

With ``--scenes faery-0.7.1/tests/data`` it also measures the share of events each method
keeps of faery's two real recordings without a light (:data:`SCENES`; goal: >= 95 %).

Run::

    python benchmarks/night_recording.py --recording faery-0.7.1/tests/data/evt3.raw \
        [--scenes faery-0.7.1/tests/data] [--model WEIGHTS ...] \
        [--figure docs/figures/night_recording_regions.png]

writes ``results/night_recording.json`` (``night_recording_scenes.json``) and
``night_recording_lights.json`` (the annotation, with its checks) beside this script.
No setting of ``learned`` or ``general`` was chosen on these recordings. ``night``'s
light-free rules (the crowding test, the scattered-light field, their shifts) were made
on ``reference_window.py``'s panel, a window of this recording: for ``night`` it is not
held out (``flare_targets.py``'s leave-one-out holds the two out together). faery's two
scenes without a light chose nothing.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
from _common import add_model_option, model_label, report

from edeflare import read_events
from edeflare.eval.score import classify_events, score_recording
from edeflare.io.sequence import file_sha256
from edeflare.lights import Lights, LightSource, detect_light_source

FAERY_SHA256 = {
    "evt3.raw": "8eca19cd8f0580ae939490484a023d858192a4c102b6649d8f5e19a62cb77ad3",
    "evt2.raw": "e84afbecdc07d2910ae846a4ae0ee246f5b9c97a53816c637d4f85c023d7c234",
    "dvs.es": "98f9ca09e1b77ccc02bbe130a2c295ca531a29eb4d3f597d9917ddce0f26d333",
}
"""faery 0.7.1's test files read here: the night recording, and its other real recordings,
neither with a light (:data:`SCENES`)."""
SCENES = ("evt2.raw", "dvs.es")
"""Plants and a string before a Prophesee Gen3 (640x480, 96 ms, 521,252 events) and an
object moving before a DVS (320x240, 1 s, 473,225 events; ``atis.es`` holds the same)."""
HERE = Path(__file__).resolve().parent
PANEL = HERE / "reference_window_lights.json"
WINDOW_US = 100_000
ANCHOR_START = (558.0, 232.0)
"""Where the upper-right small light is in the first windows (``detect_light_source``'s
circle of the 250-350 ms window); the anchor is followed from there."""
ANCHOR_SEARCH_PX = 20.0
METHODS = ("raw", "voxel", "efr", "pfd-a", "pfd-b", "dv-fastdecay", "dv-bafilter", "dv-knoise")
MODELS = ("night", "general", "learned")


def _centre(x: np.ndarray, y: np.ndarray, cx: float, cy: float, reach: float) -> tuple:
    """The mean of the events within ``reach`` of ``(cx, cy)``, three times (None: too few)."""
    for r in (reach, reach / 2, reach / 2):
        near = np.hypot(x - cx, y - cy) <= r
        if near.sum() < 10:
            return None
        cx, cy = float(x[near].mean()), float(y[near].mean())
    return cx, cy


def annotate(events: np.ndarray, size: tuple[int, int]) -> tuple[Lights, dict]:
    """The recording's lights as tracks anchored on the upper-right small light."""
    panel = json.loads(PANEL.read_text())
    spec = panel["sources"]
    t = events["t"]
    x, y = events["x"].astype(np.float64), events["y"].astype(np.float64)
    starts = range(int(t[0]), int(t[-1]) + 1, WINDOW_US)
    anchor, cx, cy = [], *ANCHOR_START
    detected: list[tuple[int, list]] = []
    for w0 in starts:
        sl = slice(*np.searchsorted(t, [w0, w0 + WINDOW_US]))
        found = _centre(x[sl], y[sl], cx, cy, ANCHOR_SEARCH_PX)
        if found is not None:
            cx, cy = found
            anchor.append([w0 + WINDOW_US / 2, cx, cy])
        detected.append((len(anchor) - 1, detect_light_source(events[sl], size, max_sources=4)))
    track = np.array(anchor)
    # each other source's offset from the anchor: the median over the windows where a
    # detected circle lies within 12 px of the panel's offset
    panel_anchor = np.array(spec[1]["circle"][:2])
    offsets, found_in = [], []
    for s in spec:
        expect = np.array(s["circle"][:2]) - panel_anchor
        seen = []
        for k, circles in detected:
            if k < 0:
                continue
            for c in circles:
                off = np.array([c.cx, c.cy]) - track[k, 1:]
                if np.hypot(*(off - expect)) <= 12.0:
                    seen.append(off)
                    break
        offsets.append(np.median(seen, axis=0) if seen else expect)
        found_in.append(len(seen))
    offsets[1] = np.zeros(2)  # the anchor itself
    sources = []
    for s, off in zip(spec, offsets, strict=True):
        r = float(s["circle"][2])
        rows = [[round(float(tt)), round(float(ax + off[0]), 1), round(float(ay + off[1]), 1), r]
                for tt, ax, ay in track]  # fmt: skip
        extra = {k: s[k] for k in ("halo_outer_px", "ghost_radius_px", "ghost") if k in s}
        sources.append(LightSource.track(rows, name=s["name"], **extra))
    lights = Lights(
        tuple(sources),
        margin_px=panel["margin_px"],
        halo_factor=panel["halo_factor"],
        ghost_factor=panel["ghost_factor"],
        note="the night light, three small lights and stars; tracks anchored on the "
        "upper-right small light; sizes from reference_window_lights.json; background "
        "(stars, noise) reported, not scored",
        score_background=False,
    )
    regions = classify_events(events, lights, size)
    checks = {
        "event_share": {
            r: round(float(regions.mask(r).sum()) / events.size, 4)
            for r in ("light", "rim", "halo", "ghost", "background")
        },
        "anchor_windows": f"{len(track)} of {len(starts)}",
        "anchor_drift_px": [round(float(v), 1) for v in track[-1, 1:] - track[0, 1:]],
        "offsets_px": [[round(float(v), 1) for v in o] for o in offsets],
        "offset_windows": found_in,
    }
    return lights, checks


def faery_file(path: Path, name: str = "evt3.raw") -> Path:
    """``path``, checked to be faery 0.7.1's test file ``name`` (by its sha256)."""
    if not path.is_file():
        raise SystemExit(f"{path}: no such file (see night_recording.py's docstring)")
    if file_sha256(path) != FAERY_SHA256[name]:
        raise SystemExit(f"{path}: not faery 0.7.1's {name} (sha256 differs)")
    return path


def overlay_figure(events: np.ndarray, size: tuple[int, int], lights: Lights, path: Path) -> None:
    """Four 100 ms windows with the regions drawn (light green, halo orange, ghost violet)."""
    from PIL import Image, ImageDraw

    from edeflare.viz import event_frame, grid, save_image

    t = events["t"]
    frames, captions = [], []
    w, h = size
    for start_ms in (0, 1_000, 5_000, 10_000):
        t0 = int(t[0]) + start_ms * 1_000
        ev = events[np.searchsorted(t, t0) : np.searchsorted(t, t0 + WINDOW_US)]
        img = Image.fromarray(event_frame(ev, size))
        draw = ImageDraw.Draw(img)
        mid = np.array([t0 + WINDOW_US // 2])
        for s in lights.sources:
            cx, cy, r = (float(v[0]) for v in s.at(mid))
            circles = [(cx, cy, r, (0, 160, 0))]
            if s.halo_outer_px is not None:
                circles.append((cx, cy, s.halo_outer_px, (240, 140, 0)))
            if s.ghost:
                gr = lights.ghost_factor * r if s.ghost_radius_px is None else s.ghost_radius_px
                circles.append((w - 1 - cx, h - 1 - cy, gr, (150, 0, 200)))
            for x, y, rr, colour in circles:
                draw.ellipse([x - rr, y - rr, x + rr, y + rr], outline=colour, width=3)
        frames.append(np.asarray(img.resize((w // 2, h // 2), Image.BILINEAR)))
        captions.append(f"[{start_ms / 1000:g}, {start_ms / 1000 + 0.1:g}) s")
    save_image(path, grid(frames, ncols=2, captions=captions))


def scenes_kept(folder: Path, models: list[str]) -> list[dict]:
    """The share of each scene's events each method keeps (one windowing, as ``edeflare
    deflare`` prints it): what a de-flarer should leave alone (goal: >= 95 %)."""
    from edeflare import deflare

    scenes = {name: read_events(faery_file(folder / name, name)) for name in SCENES}
    rows = []
    methods = [(m, m, {}) for m in ("dv-fastdecay", "pfd-a")]
    methods += [(w, "model", {"weights": w}) for w in (*MODELS, *models)]
    for label, method, params in methods:
        row = {"method": model_label(label)}
        for name, (events, size) in scenes.items():
            out = deflare(events, size, method, rng=0, **params)
            row[name] = round(100 * out.size / events.size, 1)
        rows.append(row)
        print(row, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--recording", type=Path, required=True, help="faery's evt3.raw")
    add_model_option(parser)
    parser.add_argument(
        "--scenes",
        type=Path,
        help="faery's tests/data folder: also the share of events each method keeps of its "
        "recordings without a light (evt2.raw, dvs.es)",
    )
    parser.add_argument("--phases", type=int, default=4, help="window phases (as flare_targets)")
    parser.add_argument("--figure", type=Path, help="also draw the regions to this PNG")
    parser.add_argument("--annotate-only", action="store_true", help="annotate, score nothing")
    parser.add_argument(
        "--skip-night", action="store_true", help="with --scenes: score only the scenes"
    )
    args = parser.parse_args()
    if args.scenes is not None and args.skip_night:
        report("night_recording_scenes", scenes_kept(args.scenes, args.model), ["method", *SCENES])
        return
    faery_file(args.recording)
    events, size = read_events(args.recording)
    lights, checks = annotate(events, size)
    doc = {
        "recording": "faery-0.7.1/tests/data/evt3.raw",
        "sensor_size": list(size),
        "method": "python benchmarks/night_recording.py --recording evt3.raw --annotate-only",
        "checks": checks,
        **lights.to_dict(),
    }
    text = json.dumps(doc, indent=1)  # one line per innermost list (track rows, offsets)
    text = re.sub(r"\[\s+([^\[\]{}]*?)\s+\]", lambda m: "[" + re.sub(r"\s+", " ", m[1]) + "]", text)
    (HERE / "night_recording_lights.json").write_text(text + "\n")
    print(json.dumps(checks))
    if args.figure:
        overlay_figure(events, size, lights, args.figure)
    if args.annotate_only:
        return
    rows = []
    for i, weights in enumerate([*MODELS, *args.model]):
        methods = [*METHODS, "model"] if i == 0 else ["model"]
        result = score_recording(
            args.recording,
            methods,
            lights=lights,
            method_params={"model": {"weights": weights}},
            phases=args.phases,
        )
        for s in result.rows:
            rows.append({
                "method": model_label(weights) if s.method == "model" else s.method,
                "halo removed": round(100 * s.halo_removed, 1),
                "ghost removed": round(100 * s.ghost_removed, 1),
                "flare removed": round(100 * s.flare_removed, 1),
                "light kept": round(100 * s.light_kept, 1),
                "background kept": round(100 * s.background_kept, 1),
                "combined": round(s.combined, 3),
                "worst phase": round(s.combined_worst, 3),
            })  # fmt: skip
        print(rows[-1], flush=True)
    report("night_recording", rows, list(rows[0]))
    if args.scenes is not None:
        report("night_recording_scenes", scenes_kept(args.scenes, args.model), ["method", *SCENES])


if __name__ == "__main__":
    main()
