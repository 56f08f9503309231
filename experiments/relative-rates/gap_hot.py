"""gap.py's comparison with the simulated events to remove split by what they are: the
scattered light (events of the sequence's stored ``flare`` stream) and the hot pixels
(the sensing stage's step 6: events to remove that no flare event matches). gap.py pooled
the two as "flare". What is kept is split into the light's own events (matched to its
``light`` stream) and the rest; the scattered light also within 6 radii of the light, as
far as the annotation's halo reaches; ``events`` counts each group. Features as a head of
`learned`'s form reads them (the bundled `learned`: its network logit and 21 features; the
six rate-relative ones derived from them as `relative_features` does); no head's decision
enters. Measures only.

Run: python experiments/relative-rates/gap_hot.py OUT.json FAERY_DATA SEQUENCE_FOLDER...
(SEQUENCE_FOLDER: e.g. STEADY/steady-640/test; every sequence of each, one windowing)
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _own_rows import write_medians  # noqa: E402
from night_recording import HERE as BENCH  # noqa: E402
from night_recording import faery_file  # noqa: E402

from edeflare.io import read_events  # noqa: E402
from edeflare.io.sequence import list_sequences, read_sequence  # noqa: E402
from edeflare.lights import load_lights  # noqa: E402
from edeflare.models.event_features import relative_features  # noqa: E402
from edeflare.models.head_training import _component, keep_labels  # noqa: E402
from edeflare.models.head_tuning import recording_inputs, region_labels  # noqa: E402
from edeflare.models.infer import ModelDeflarer, resolve_weights  # noqa: E402

REPORTED = ("net_logit", "balance_pixel", "balance_8", "support", "rate_window",
            "rel_pixel", "rel_32", "rel_128", "rel_support", "crowded", "field")  # fmt: skip
RELATIVE = ("rel_pixel", "rel_8", "rel_32", "rel_128", "rel_support", "rel_since")

dst, faery, folders = Path(sys.argv[1]), Path(sys.argv[2]), [Path(a) for a in sys.argv[3:]]
d = ModelDeflarer(resolve_weights("learned"), runtime="torch", batch_windows=8)
names = list(d.model.head.feature_names)


def features(events: np.ndarray, size: tuple[int, int]) -> dict[str, np.ndarray]:
    """Every event's named features (one windowing), the relative ones derived."""
    columns = recording_inputs(d, events, size, [0])[0][:, : len(names)]
    out = {n: columns[:, i] for i, n in enumerate(names)}
    out.update(relative_features(out, RELATIVE, window_us=d.window_us))
    out["on"] = (events["p"] > 0).astype(np.float64)
    return out


def within_halo(inp: np.ndarray, light: np.ndarray | None, factor: float = 6.0) -> np.ndarray:
    """Which events lie within ``factor`` radii of the light's centre in their window, as
    the annotation's halo reaches (the light's events' mean position and the radius of a
    disc of its distinct pixels, per window of the network's length)."""
    near = np.zeros(inp.size, bool)
    if light is None or not light.size:
        return near
    w_in, w_li = inp["t"] // d.window_us, light["t"] // d.window_us
    for w in np.unique(w_li):
        li = light[w_li == w]
        cx, cy = li["x"].mean(), li["y"].mean()
        radius = np.sqrt(np.unique(li["y"].astype(np.int64) * 65536 + li["x"]).size / np.pi)
        m = w_in == w
        dist = np.hypot(inp["x"][m] - cx, inp["y"][m] - cy)
        near[np.flatnonzero(m)] = dist <= factor * radius
    return near


def medians(cols: dict[str, np.ndarray], m: np.ndarray) -> dict[str, float]:
    row = {k: float(np.median(cols[k][m])) for k in REPORTED}
    row["on_share"] = float(np.mean(cols["on"][m]))
    row["events"] = int(m.sum())
    return {k: round(v, 3) for k, v in row.items()}


out: dict[str, dict[str, float]] = {}
recording = read_events(faery_file(faery / "evt3.raw"))
events, size = recording.events, recording.sensor_size
code = region_labels(events, size, load_lights(BENCH / "night_recording_lights.json", size))
cols = features(events, size)
for label, c in (("flare", 2), ("light", 1)):
    out[f"night recording: {label}"] = medians(cols, code == c)
    print(label, out[f"night recording: {label}"], flush=True)

for folder in folders:
    parts: dict[str, list[np.ndarray]] = {}
    groups: dict[str, list[np.ndarray]] = {
        "scattered flare": [], "scattered flare within 6 radii": [], "hot pixels": [],
        "light": [], "kept, not the light": [],
    }  # fmt: skip
    for path in list_sequences(folder):
        inp, gt, size, _, _ = read_sequence(path)
        keep = keep_labels(inp, gt)
        light = _component(path, "light")
        of_light = keep_labels(inp, light) if light is not None else np.zeros(inp.size, bool)
        keep |= of_light
        flare = _component(path, "flare")
        of_flare = keep_labels(inp, flare) if flare is not None else np.zeros(inp.size, bool)
        c = features(inp, size)
        free = c["light_free"] > 0.5
        for k, v in c.items():
            parts.setdefault(k, []).append(v)
        groups["scattered flare"].append(~keep & of_flare & free)
        near = within_halo(inp, light)
        groups["scattered flare within 6 radii"].append(~keep & of_flare & free & near)
        groups["hot pixels"].append(~keep & ~of_flare & free)
        groups["light"].append(of_light & free)
        groups["kept, not the light"].append(keep & ~of_light & free)
    cols = {k: np.concatenate(v) for k, v in parts.items()}
    name = f"{folder.parent.name}/{folder.name}"
    for label, masks in groups.items():
        m = np.concatenate(masks)
        if m.any():
            out[f"{name}, no light found: {label}"] = medians(cols, m)
            print(name, label, out[f"{name}, no light found: {label}"], flush=True)

write_medians(dst, out, "median of")
