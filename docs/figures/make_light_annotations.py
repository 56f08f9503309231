"""Light-source annotations of the real recordings, their checks and overlay figures.

Run from the repository root, with ``../shared/data/real/`` present::

    python docs/figures/make_light_annotations.py --data ../shared/data/real \
        --json-dir src/edeflare/assets/lights --figures docs/figures

Fits the annotations (see ``src/edeflare/assets/lights/README.md``), writes them as
JSON, prints the checks (also stored in each JSON under ``"checks"``) and draws one
overlay figure per recording: event frames (ON red, OFF blue) with the light disc
(green), the halo's outer circle (orange) and the ghost disc (violet) at the window's
middle time.

- ``prophesee_gen3_rotating_light.raw``: a blob moving on a circle. Per 1 ms window
  the dense core's centre (median, then three times the mean of the events within
  35 px of it); a track through the centres at the windows' middle times, extended
  linearly to the recording's first and last event; one radius for the whole track.
  Its response time (``response_us``): each pixel the blob's disc covers fires a train
  (an OFF burst as the blob arrives, an ON burst as it leaves) whose last events come
  after the disc has left the pixel, as the photoreceptor settles; ``response_us`` is
  the 95th percentile over those pixels of the last event's delay after the disc left
  (``edeflare.lights.light_response``; the raster ``lights_gen3_pixel_trains.png``
  shows the trains).
- ``davis346_flicker_lamps.aedat4``: two fixed ceiling lamps, found on the whole
  recording's event density by ``edeflare.lights.detect_light_source``.

Radius (both): the event density per pixel ring of 1 px around the centre (for the
moving blob, around its position at each event's time) falls below 5 % of the core's
(the mean of the rings within 4 px); the radius is the first ring edge below it.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from edeflare import read_events
from edeflare.eval.score import classify_events
from edeflare.lights import Lights, LightSource, detect_light_source, light_response
from edeflare.viz import event_frame, grid, save_image

# When each annotation was last changed (Gen3: the response time added).
DATES = {
    "prophesee_gen3_rotating_light.raw": "2026-11-25",
    "davis346_flicker_lamps.aedat4": "2026-11-23",
}
COMMAND = (
    "python docs/figures/make_light_annotations.py --data ../shared/data/real "
    "--json-dir src/edeflare/assets/lights --figures docs/figures"
)


def radius_from_profile(d: np.ndarray, core_px: float = 4.0, level: float = 0.05) -> float:
    """First ring edge (1 px rings) where the per-pixel density drops below ``level`` x core."""
    edges = np.arange(0.0, 80.0, 1.0)
    counts, _ = np.histogram(d, bins=edges)
    area = np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    density = counts / area
    core = density[edges[:-1] < core_px].mean()
    below = np.nonzero((density < level * core) & (edges[:-1] >= core_px))[0]
    return float(edges[below[0]]) if below.size else float(edges[-1])


def gen3_track(events: np.ndarray, window_us: int = 1_000) -> tuple[np.ndarray, dict]:
    """Per-window core centres of the moving blob: rows ``[t_mid, cx, cy]``."""
    t = events["t"]
    x = events["x"].astype(np.float64)
    y = events["y"].astype(np.float64)
    start = int(t[0])
    rows = []
    for w0 in range(start, int(t[-1]) + 1, window_us):
        m = (t >= w0) & (t < w0 + window_us)
        if m.sum() < 100:
            continue
        cx, cy = np.median(x[m]), np.median(y[m])
        for _ in range(3):
            near = m & (np.hypot(x - cx, y - cy) <= 35)
            cx, cy = x[near].mean(), y[near].mean()
        rows.append([w0 + window_us / 2, cx, cy])
    track = np.array(rows)
    # Extend linearly to the first and last event so nothing is held.
    first = track[0] + (track[0] - track[1]) * (track[0, 0] - t[0]) / (track[1, 0] - track[0, 0])
    last = track[-1] + (track[-1] - track[-2]) * (t[-1] - track[-1, 0]) / (
        track[-1, 0] - track[-2, 0]
    )
    first[0], last[0] = t[0], t[-1]
    track = np.vstack([first, track, last])
    # The circle the blob runs on (least squares), for the record.
    a = np.c_[2 * track[:, 1], 2 * track[:, 2], np.ones(len(track))]
    b = track[:, 1] ** 2 + track[:, 2] ** 2
    (ccx, ccy, c), *_ = np.linalg.lstsq(a, b, rcond=None)
    orbit_r = float(np.sqrt(c + ccx**2 + ccy**2))
    resid = np.hypot(track[:, 1] - ccx, track[:, 2] - ccy) - orbit_r
    info = {
        "orbit_centre": [round(float(ccx), 1), round(float(ccy), 1)],
        "orbit_radius_px": round(orbit_r, 1),
        "orbit_residual_rms_px": round(float(np.sqrt(np.mean(resid**2))), 2),
        "window_us": window_us,
    }
    return track, info


def train_raster(
    trains: list[np.ndarray], response_us: float, span_us: tuple[int, int] = (-6_000, 8_000)
) -> np.ndarray:
    """The pixels' trains as a raster: one row per pixel, time relative to the disc's exit.

    ON red, OFF blue; black line: the exit; green line: ``response_us`` after it.
    """
    lo, hi = span_us
    w, row = 700, 8
    img = Image.new("RGB", (w, row * len(trains) + 24), "white")
    draw = ImageDraw.Draw(img)
    col = lambda v: int((v - lo) / (hi - lo) * (w - 1))  # noqa: E731
    for v, colour in ((0, (0, 0, 0)), (response_us, (0, 160, 0))):
        draw.line([col(v), 0, col(v), row * len(trains)], fill=colour, width=2)
    for i, tr in enumerate(trains):
        for rel, p in tr:
            if lo <= rel < hi:
                x, y = col(rel), i * row + row // 2
                draw.rectangle([x - 1, y - 2, x + 1, y + 2], fill=(220, 0, 0) if p else (0, 0, 220))
    for v in range(lo, hi + 1, 2_000):
        draw.text((col(v) + 2, row * len(trains) + 6), f"{v / 1000:+g} ms", fill=(0, 0, 0))
    return np.asarray(img)


def checks(events: np.ndarray, size: tuple[int, int], lights: Lights, n_src: int) -> dict:
    """Region shares, dense-core containment and stability over 5 ms windows."""
    regions = classify_events(events, lights, size)
    n = events.size
    share = {r: round(float(regions.mask(r).sum()) / n, 4) for r in
             ("light", "rim", "halo", "ghost", "background")}  # fmt: skip
    bg = events[regions.background]
    _, per_pixel = np.unique(bg["y"].astype(np.int64) * size[0] + bg["x"], return_counts=True)
    t = events["t"]
    inside, total, offsets, fractions = 0, 0, [], []
    for w0 in range(int(t[0]), int(t[-1]) + 1, 5_000):
        sl = slice(*np.searchsorted(t, [w0, w0 + 5_000]))
        ev = events[sl]
        if ev.size < 100:
            continue
        circles = detect_light_source(ev, size, max_sources=n_src)
        core = np.zeros(ev.size, dtype=bool)
        for c in circles:
            core |= np.hypot(ev["x"] - c.cx, ev["y"] - c.cy) <= c.r
            mid = np.array([w0 + 2_500])
            best = min(
                float(np.hypot(*(np.array(s.at(mid)[:2]).ravel() - [c.cx, c.cy])))
                for s in lights.sources
            )
            offsets.append(best)
        k = int((core & regions.light[sl]).sum())
        inside += k
        total += int(core.sum())
        fractions.append(k / max(1, int(core.sum())))
    return {
        "event_share": share,
        "dense_core_in_light": round(inside / total, 4),
        "dense_core_in_light_min_window": round(min(fractions), 4),
        "dense_core": "events inside detect_light_source's circle(s) of each 5 ms window",
        "detected_centre_offset_px_median": round(float(np.median(offsets)), 2),
        "detected_centre_offset_px_max": round(float(np.max(offsets)), 2),
        "windows": len(fractions),
        "background_events": int(bg.size),
        "background_pixels": int(per_pixel.size),
        "background_share_of_10_busiest_pixels": round(
            float(np.sort(per_pixel)[-10:].sum()) / max(1, bg.size), 4
        ),
    }


def overlay(events, size, lights, t0, window_us, scale) -> np.ndarray:
    """One event frame with the regions drawn at the window's middle time."""
    t = events["t"]
    ev = events[np.searchsorted(t, t0) : np.searchsorted(t, t0 + window_us)]
    img = Image.fromarray(event_frame(ev, size)).resize(
        (size[0] * scale, size[1] * scale), Image.NEAREST
    )
    draw = ImageDraw.Draw(img)
    mid = np.array([t0 + window_us // 2])
    w, h = size
    for s in lights.sources:
        cx, cy, r = (float(v[0]) for v in s.at(mid))
        outer = lights.halo_factor * r if s.halo_outer_px is None else s.halo_outer_px
        circles = [(cx, cy, r, (0, 160, 0)), (cx, cy, outer, (240, 140, 0))]
        if s.response_us:  # the disc response_us ago: the comet's tail
            px, py, pr = (float(v[0]) for v in s.at(mid - s.response_us))
            circles.append((px, py, pr, (0, 90, 0)))
        if s.ghost:
            gr = lights.ghost_factor * r if s.ghost_radius_px is None else s.ghost_radius_px
            circles.append((w - 1 - cx, h - 1 - cy, gr, (150, 0, 200)))
        for x, y, rr, colour in circles:
            x, y, rr = (x + 0.5) * scale, (y + 0.5) * scale, rr * scale
            draw.ellipse([x - rr, y - rr, x + rr, y + rr], outline=colour, width=2)
    return np.asarray(img)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data/real"))
    parser.add_argument("--json-dir", type=Path, default=Path("src/edeflare/assets/lights"))
    parser.add_argument("--figures", type=Path, default=Path("docs/figures"))
    args = parser.parse_args(argv)

    # --- Gen3 rotating light: a track.
    name = "prophesee_gen3_rotating_light.raw"
    events, size = read_events(args.data / name)
    track, info = gen3_track(events)
    cx = np.interp(events["t"], track[:, 0], track[:, 1])
    cy = np.interp(events["t"], track[:, 0], track[:, 2])
    r = radius_from_profile(np.hypot(events["x"] - cx, events["y"] - cy))
    rows = [[round(float(a)), round(float(b), 1), round(float(c), 1), r] for a, b, c in track]
    with_r = np.c_[track[:, :3], np.full(len(track), r)]
    response = light_response(events, LightSource.track(with_r.tolist()), trains=40)
    response_us = response.response_us
    info = {**info, **response.record()}
    save_image(
        args.figures / "lights_gen3_pixel_trains.png",
        train_raster(list(response.trains), response_us),
    )
    gen3 = Lights(
        (
            LightSource.track(
                rows, name="rotating blob", ghost_radius_px=r, response_us=response_us
            ),
        ),
        note="blob moving on a circle in the dark; ghost disc as large as the blob (its "
        "reflection passes within 90 px of the blob); background: hot pixels only, not scored",
        score_background=False,
    )
    # --- DAVIS346 ceiling lamps: fixed circles.
    name2 = "davis346_flicker_lamps.aedat4"
    events2, size2 = read_events(args.data / name2)
    found = sorted(detect_light_source(events2, size2, max_sources=2), key=lambda c: c.cx)
    lamps = []
    for i, c in enumerate(found):
        d = np.hypot(events2["x"] - c.cx, events2["y"] - c.cy)
        rr = radius_from_profile(d[d < 80])
        lamps.append(
            LightSource.circle(
                round(c.cx, 1), round(c.cy, 1), rr, name=f"ceiling lamp {i + 1}", ghost=False
            )
        )
    davis = Lights(
        tuple(lamps),
        note="two ceiling lamps flickering at 100 Hz; no ghost region: their reflections "
        "through the centre land on the lit table, where no ghost is seen",
    )

    args.json_dir.mkdir(parents=True, exist_ok=True)
    for rec, (ev, sz), lights, n_src, extra, windows, scale in (
        (name, (events, size), gen3, 1, info, (0, 12_000, 25_000, 37_000), 1),
        (name2, (events2, size2), davis, 2, {}, (0, 40_000, 80_000, 120_000), 2),
    ):
        found_checks = checks(ev, sz, lights, n_src)
        print(rec, json.dumps(found_checks))
        doc = {
            "recording": rec,
            "sensor_size": list(sz),
            "date": DATES[rec],
            "method": COMMAND,
            "checks": {**found_checks, **extra},
            **lights.to_dict(),
        }
        out = args.json_dir / (Path(rec).stem + ".json")
        text = json.dumps(doc, indent=1)
        # One line per innermost list (track rows, centres, sizes).
        text = re.sub(
            r"\[\s+([^\[\]{}]*?)\s+\]", lambda m: "[" + re.sub(r"\s+", " ", m[1]) + "]", text
        )
        out.write_text(text + "\n", encoding="utf-8")
        t0 = int(ev["t"][0])
        win = 1_000 if n_src == 1 else 10_000
        frames = [overlay(ev, sz, lights, t0 + w, win, scale) for w in windows]
        captions = [f"[{w / 1000:g}, {(w + win) / 1000:g}) ms" for w in windows]
        figure = grid(frames, ncols=len(frames), captions=captions)
        save_image(args.figures / f"lights_{Path(rec).stem}.png", figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
