"""python experiments/sim-limits/skirt.py real | sim SPLIT OUTDIR: cut a bright light's
"skirt", its pixels that fire little against the light's busiest (a tenth of its pixels)
and lie far from its core, from the default's output. Not adopted.

A simulated light's glare bloom makes its found pixels about twice the ground truth's
disc (``experiments/rsim-gap``). Each pair (ALPHA, BETA) cuts, per aligned 20 ms window
and light of :func:`~edeflare.models.halos.window_lights`, the events in the light's
pixels that fire fewer than ALPHA times the light's 90th-percentile pixel count and lie
more than BETA of its radius from its core (:func:`~edeflare.models.streaks._core`).

``real``: the default (one call, phase 0) on the real recordings, with each cut: flare
removed, light kept and scene kept on the two annotated ones, events kept on the three
without a light. ``sim``: the eight metrics of ``OUTDIR/<seq>.night.npy``
(``experiments/hybrid/outputs.py``) with each cut, over a simulated split.
"""

import sys
from pathlib import Path

import numpy as np

from edeflare.events import event_keys
from edeflare.io import open_events
from edeflare.models.ghosts import covered_us
from edeflare.models.halos import LIGHT_CORE_RATE, _lights, window_lights
from edeflare.models.streaks import _core

WIN_US = 20_000
REAL = "../shared/data/real/"
LIGHTS = "src/edeflare/assets/lights/"
CUTS = [(a, b) for a in (0.2, 0.35, 0.5) for b in (0.5, 1.0, 1.5)]


def skirts(inp: np.ndarray, size: tuple[int, int], start: int) -> dict:
    """Per (ALPHA, BETA): a mask over ``inp`` of the events in its lights' skirts."""
    t = inp["t"]
    out = {cut: np.zeros(inp.size, dtype=bool) for cut in CUTS}
    for s in range(start, int(t[-1]) + 1, WIN_US):
        a, b = np.searchsorted(t, [s, s + WIN_US])
        if a == b:
            continue
        ev = inp[a:b]
        span = covered_us(ev, s, WIN_US)
        lights = window_lights(ev, size, span)
        if not lights.any():
            continue
        _, found, at = _lights(ev, size, span, 8, lights)
        for ys, xs, own, radius in found:
            counts = at.counts[ys, xs]
            if np.median(counts[own]) < LIGHT_CORE_RATE * span / 1000:
                continue  # not a light: dense scene (window_lights)
            cy, cx = _core(own)
            busy = np.percentile(counts[own], 90)
            yy, xx = np.mgrid[0 : own.shape[0], 0 : own.shape[1]]
            far = np.hypot(yy - cy, xx - cx) / radius
            inside = (ev["y"] >= ys.start) & (ev["y"] < ys.stop)
            inside &= (ev["x"] >= xs.start) & (ev["x"] < xs.stop)
            idx = np.flatnonzero(inside)
            iy, ix = ev["y"][idx] - ys.start, ev["x"][idx] - xs.start
            for alpha, beta in CUTS:
                cut = own & (counts < alpha * busy) & (far > beta)
                out[alpha, beta][a + idx[cut[iy, ix]]] = True
    return out


def _line(kept: np.ndarray, regions) -> str:
    """Flare removed, light and scene kept (an annotated recording), or the share kept."""
    if regions is None:
        return f"kept {100 * kept.mean():.1f} %"
    flare = regions.halo | regions.ghost
    return (
        f"flare removed {100 * (1 - kept[flare].mean()):.1f} %, light kept "
        f"{100 * kept[regions.light].mean():.1f} %, scene kept "
        f"{100 * kept[regions.background].mean():.1f} %"
    )


def real() -> None:
    from edeflare.deflare import deflare
    from edeflare.eval.score import classify_events, load_lights

    for name, ann in (
        ("davis346_flicker_lamps.aedat4", "davis346_flicker_lamps.json"),
        ("prophesee_gen3_rotating_light.raw", "prophesee_gen3_rotating_light.json"),
        ("davis346_street_cars.aedat4", None),
        ("davis346_lowlight_cradle.aedat4", None),
        ("prophesee_gen41_street.raw", None),
    ):
        src = open_events(REAL + name)
        inp, size = src.read(), src.sensor_size
        out = deflare(inp, size, "model")
        kept = np.isin(event_keys(inp, size), event_keys(out, size))
        regions = None
        if ann:
            regions = classify_events(inp, load_lights(LIGHTS + ann, size), size)

        print(f"{name} default: {_line(kept, regions)}", flush=True)
        for cut, m in skirts(inp, size, int(inp["t"][0]) // WIN_US * WIN_US).items():
            print(f"{name} cut {cut}: {_line(kept & ~m, regions)} ({m.sum()} marked)", flush=True)


def sim(split: Path, outdir: Path) -> None:
    from edeflare.eval.evaluate import evaluate_events

    rows: dict[str, list] = {}
    for path in sorted(split.glob("*.h5")):
        src = open_events(path, group="input")
        inp, size = src.read(), src.sensor_size
        gt = open_events(path, group="gt").read()
        out = np.load(outdir / f"{path.stem}.night.npy")
        start = min(int(inp["t"][0]), int(gt["t"][0])) // WIN_US * WIN_US
        end = max(int(inp["t"][-1]), int(gt["t"][-1])) + 1
        kept = np.isin(event_keys(inp, size), event_keys(out, size))
        outs = {"night": inp[kept]}
        for cut, m in skirts(inp, size, start).items():
            outs[f"cut {cut}"] = inp[kept & ~m]
        for label, ev in outs.items():
            rows.setdefault(label, []).append(
                evaluate_events(gt, ev, size, start_us=start, end_us=end)
            )
    metrics = list(rows["night"][0].means)
    print("| output | " + " | ".join(metrics) + " |")
    print("|---" * (len(metrics) + 1) + "|")
    for label, ss in rows.items():
        vals = [float(np.nanmean([s.means[m] for s in ss])) for m in metrics]
        print(f"| {label} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")


if __name__ == "__main__":
    if sys.argv[1] == "real":
        real()
    else:
        sim(Path(sys.argv[2]), Path(sys.argv[3]))
