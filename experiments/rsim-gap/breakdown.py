"""python experiments/rsim-gap/breakdown.py SPLIT OUTDIR [METHOD]: where a de-flarer's
gap to the pixel oracle lies, by what the default's priors see around each event.

Reads the saved outputs ``OUTDIR/<seq>.METHOD.npy`` (``experiments/hybrid/outputs.py``;
METHOD ``night`` by default). Each input event falls, in its aligned 20 ms window, in one
region (the first that holds it): ``light-free`` (a window without a light), ``light``
(a light's own pixels), ``spike``, ``halo``, ``ghost`` (the cells where the lights'
ghosts can be), ``far`` (``far_from_lights``) or ``near`` (the rest). Per region it
prints the events the output keeps in flare-only pixels (no ground-truth event in the
pixel and window) and the events it drops in scene pixels, and the eight metrics of two
repairs: the output with its kept flare-only events of that region deleted (``cut``),
and with its dropped scene events of that region restored (``restore``).
"""

import sys
from pathlib import Path

import numpy as np

from edeflare.eval.evaluate import evaluate_events
from edeflare.events import event_keys
from edeflare.io import open_events
from edeflare.models.ghosts import covered_us, ghost_cells
from edeflare.models.halos import far_from_lights, in_halo_prior, light_pixels, window_lights
from edeflare.models.streaks import in_streak_prior

WIN_US = 20_000
REGIONS = ("light-free", "light", "spike", "halo", "ghost", "far", "near")


def regions(inp: np.ndarray, size: tuple[int, int], start: int) -> np.ndarray:
    """Each input event's region index (into REGIONS), window by window."""
    out = np.zeros(inp.size, dtype=np.int8)  # 0: light-free, what a window without a light keeps
    t = inp["t"]
    for s in range(start, int(t[-1]) + 1, WIN_US):
        a, b = np.searchsorted(t, [s, s + WIN_US])
        if a == b:
            continue
        ev = inp[a:b]
        span = covered_us(ev, s, WIN_US)
        lights = window_lights(ev, size, span)
        if not lights.any():
            continue
        labels, _ = light_pixels(ev, size, span)
        own = (labels[ev["y"], ev["x"]] > 0) & lights[ev["y"] // 8, ev["x"] // 8]
        spike = in_streak_prior(ev, size, span, lights=lights)
        halo = in_halo_prior(ev, size, span, lights=lights)
        ghosts = ghost_cells(ev, size, span, lights=lights)
        ghost = ghosts[ev["y"] // 8, ev["x"] // 8]
        far = far_from_lights(ev, size, span, lights=lights, exclude=ghosts)
        r = np.full(ev.size, 6, dtype=np.int8)
        for k, m in ((5, far), (4, ghost), (3, halo), (2, spike), (1, own)):
            r[m] = k
        out[a:b] = r
    return out


def pixel_keys(ev: np.ndarray, w: int, h: int) -> np.ndarray:
    return ((ev["t"].astype(np.int64) // WIN_US) * h + ev["y"]) * w + ev["x"]


if __name__ == "__main__":
    split, outdir = Path(sys.argv[1]), Path(sys.argv[2])
    name = sys.argv[3] if len(sys.argv) > 3 else "night"
    counts = np.zeros((len(REGIONS), 4), dtype=np.int64)  # flare kept/all, scene dropped/all
    rows: dict[str, list] = {}
    for path in sorted(split.glob("*.h5")):
        src = open_events(path, group="input")
        inp, size = src.read(), src.sensor_size
        gt = open_events(path, group="gt").read()
        out = np.load(outdir / f"{path.stem}.{name}.npy")
        w, h = size
        start = min(int(inp["t"][0]), int(gt["t"][0])) // WIN_US * WIN_US
        end = max(int(inp["t"][-1]), int(gt["t"][-1])) + 1
        # the keys count windows from 0; aligned windows start at multiples of WIN_US
        scene = np.isin(pixel_keys(inp, w, h), pixel_keys(gt, w, h))
        kept = np.isin(event_keys(inp, size), event_keys(out, size))
        reg = regions(inp, size, start)
        for k in range(len(REGIONS)):
            m = reg == k
            counts[k] += [
                (m & ~scene & kept).sum(),
                (m & ~scene).sum(),
                (m & scene & ~kept).sum(),
                (m & scene).sum(),
            ]
        outs = {
            "raw": inp,
            name: inp[kept],
            "pixel oracle": inp[scene],
            "cut all": inp[kept & scene],
        }
        for k, label in enumerate(REGIONS):
            m = reg == k
            outs[f"cut {label}"] = inp[kept & ~(m & ~scene)]
            outs[f"restore {label}"] = inp[kept | (m & scene)]
        for label, ev in outs.items():
            rows.setdefault(label, []).append(
                evaluate_events(gt, ev, size, start_us=start, end_us=end)
            )
        print(path.stem, flush=True, file=sys.stderr)
    print("| region | flare-only events kept / in it | scene events dropped / in it |")
    print("|---|---:|---:|")
    for k, label in enumerate(REGIONS):
        fk, fa, sd, sa = counts[k]
        print(f"| {label} | {fk:,} / {fa:,} | {sd:,} / {sa:,} |")
    metrics = list(rows["raw"][0].means)
    print()
    print("| output | " + " | ".join(metrics) + " |")
    print("|---" * (len(metrics) + 1) + "|")
    for label, ss in rows.items():
        vals = [float(np.nanmean([s.means[m] for s in ss])) for m in metrics]
        print(f"| {label} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")
