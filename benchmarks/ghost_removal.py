"""Ghost rings and scattered light, simulated as real sensors record them: what each
method removes.

The test set is ``eflare-night-sparse`` at 640x480 (8 sequences, seed 4242; simulated
into ``--data`` first when absent, about 5 minutes on 2 cores): sparse night
backgrounds, ghosts sensed at their own rate wherever they land, keep-only targets.
Each sequence's events to drop (the input's events missing from ``gt``) are split into
those inside a ghost's disc (:func:`edeflare.sim.sensing.in_ghosts`, from the script's
ghosts and the source's centre per 10 ms) and the others (scattered light, hot pixels).
Per method: the share of the ghost events dropped, of the other events to drop dropped,
of the events to keep kept (means over the sequences holding at least 100 events of the
kind; one huge light can hold most of the pooled events) and the harmonic mean of the
three. The reference is dv-processing's ``FastDecayNoiseFilter`` (dv-fastdecay), the
filter users already run, which removes the ghost ring of
``../shared/reference/real_flare_example.png``. The row ``model, card before`` is the
default with the card it had before its threshold and shifts were raised on 2026-11-26
(threshold 0.5, halo and ghost shifts 1, no spike prior, no light-free or far shift; the
study "streaks" of ``docs/studies.md``). Prints the table and writes
``results/ghost_removal.json``.
Run::

    python benchmarks/ghost_removal.py [--model WEIGHTS] [--data DIR]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import h5py
import numpy as np
from _common import report

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES
from edeflare.events import event_keys
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.methods import create_method
from edeflare.sim.flare import GhostSpec
from edeflare.sim.sensing import in_ghosts, source_track

ROWS = {
    "raw": ("raw", {}),
    "model": ("model", {}),
    # the default's card before its threshold and shifts were raised (study "streaks")
    "model, card before": (
        "model",
        {
            "keep_threshold": 0.5,
            "halo_shift": 1.0,
            "ghost_shift": 1.0,
            "streak_shift": 0.0,
            "light_free_shift": 0.0,
            "far_shift": 0.0,
        },
    ),
    "dv-fastdecay": ("dv-fastdecay", {}),
    "dv-bafilter": ("dv-bafilter", {}),
    "dv-knoise": ("dv-knoise", {}),
    "pfd-a": ("pfd-a", {}),
}
"""Row name: (method, parameters)."""
METHODS = tuple(ROWS)
REFERENCE = "dv-fastdecay"
MIN_EVENTS = 100
"""A sequence counts for a kind's mean where it holds at least this many of its events."""


def labelled_events(seq: Path) -> tuple[np.ndarray, tuple[int, int], np.ndarray, np.ndarray]:
    """A sequence's input events, sensor size, and per event whether it is to keep (in
    ``gt``) and whether it lies in a ghost's disc (from the script's ghosts and the
    source's track)."""
    inp, size = read_dsec(seq, "input")
    gt, _ = read_dsec(seq, "gt")
    light, _ = read_dsec(seq, "light")
    with h5py.File(seq) as f:
        ghosts = [GhostSpec(**g) for g in json.loads(f.attrs["script"])["ghosts"]]
    keep = np.isin(event_keys(inp, size), event_keys(gt, size))
    return inp, size, keep, in_ghosts(inp, source_track(light), ghosts, size)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", help="weights for the model row (default: the bundled)")
    parser.add_argument("--data", type=Path, default=Path(__file__).parent / ".data")
    args = parser.parse_args()
    folder = args.data / "eflare-night-sparse-640x480"
    if not (folder / "manifest.json").is_file() or not list_sequences(folder / "test"):
        print(f"simulating eflare-night-sparse into {folder} ...", flush=True)
        recipe = RECIPES["eflare-night-sparse"].replace(
            sequences=8, test_sequences=8, sensor_size=(640, 480), seed=4242
        )
        generate_dataset(recipe, folder, workers=2)
    weights = {"weights": args.model} if args.model else {}
    methods = {
        name: create_method(m, **params, **(weights if m == "model" else {}))
        for name, (m, params) in ROWS.items()
    }
    shares: dict[str, dict[str, list[float]]] = {
        m: {"ghost": [], "other": [], "keep": []} for m in METHODS
    }
    counts = {"ghost": 0, "other": 0, "keep": 0}
    for seq in list_sequences(folder / "test"):
        inp, size, keep, ghost = labelled_events(seq)
        keys = event_keys(inp, size)
        kinds = {"ghost": ~keep & ghost, "other": ~keep & ~ghost, "keep": keep}
        for kind, sel in kinds.items():
            counts[kind] += int(sel.sum())
        for name, method in methods.items():
            kept = np.isin(keys, event_keys(method(inp, size, rng=0), size))
            for kind, sel in kinds.items():
                if sel.sum() >= MIN_EVENTS:
                    hit = kept[sel] if kind == "keep" else ~kept[sel]
                    shares[name][kind].append(float(hit.mean()))
        print(
            f"{seq.name}: {', '.join(f'{k} {int(v.sum())}' for k, v in kinds.items())}", flush=True
        )
    rows = []
    for name in METHODS:
        g, o, k = (float(np.mean(shares[name][kind])) for kind in ("ghost", "other", "keep"))
        hm = 3 / (1 / max(g, 1e-9) + 1 / max(o, 1e-9) + 1 / max(k, 1e-9))
        rows.append({"method": name, "ghost dropped": round(g, 3),
                     "other flare dropped": round(o, 3), "kept": round(k, 3),
                     "harmonic mean": round(hm, 3)})  # fmt: skip
    ref = next(r for r in rows if r["method"] == REFERENCE)["harmonic mean"]
    for r in rows:
        r[f"/ {REFERENCE}"] = round(r["harmonic mean"] / ref, 3) if ref else float("nan")
    print(f"events: {counts}; sequences: {len(list_sequences(folder / 'test'))}")
    report("ghost_removal", rows, list(rows[0]))


if __name__ == "__main__":
    main()
