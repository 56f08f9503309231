"""Each validation event's keep logit under `night`'s network and each rule's unit shift.

For every test-split sequence of a simulated dataset (each part of `eflare-train`), its
input (labels: kept where the clean lens sees it or it is the light's own) and its scene
alone (every event kept), in both of the product's windowings (aligned, and 5 ms later),
this stores for a random draw of events:

- ``base_V``: `night`'s keep logit with every rule off (view V = 0, 1);
- ``unit_V_K``: what rule knob K adds at value 1 (the rules are linear in their shifts:
  ghost, halo, streak, far, light_free, scatter), with ``light_free_support`` and
  ``light_free_crowding`` at the card's 2 and 3;
- ``y`` (keep), ``light`` (the light's own), ``group`` (the dataset's part, or the scene
  alone).

A card's decision on an event is then ``mean_V(base_V + sum_K k_K unit_V_K) > logit(thr)``,
as :class:`edeflare.models.two_view.TwoViewStreamer` makes it: ``fit.py`` searches the
knobs without running the network again.

    python collect.py DATA OUT.npz            # DATA: edeflare simulate --recipe eflare-train
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

from edeflare.io.sequence import read_sequence
from edeflare.lights.cells import covered_us
from edeflare.models.head_training import _component, keep_labels
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.models.mask_kernels import event_features, event_keep_logits, event_records
from edeflare.models.weights import read_card
from edeflare.rules import RULES, WindowContext
from edeflare.rules.light_free import light_free_shifts

KNOBS = ("ghost_shift", "halo_shift", "streak_shift", "far_shift", "light_free_shift",
         "scatter_shift")  # fmt: skip
DELAYS = (0, 5_000)
SUPPORT, CROWDING = 2, 3


def unit_shifts(ctx: WindowContext) -> dict[str, np.ndarray]:
    """What each knob adds to the window's keep logits at value 1."""
    n = ctx.events.size
    out = {k: np.zeros(n, np.float32) for k in KNOBS}
    if ctx.has_lights:
        for name, knob in (("ghost", "ghost_shift"), ("halo", "halo_shift"),
                           ("streak", "streak_shift"), ("far", "far_shift")):  # fmt: skip
            rule = RULES[name]
            params = dataclasses.replace(rule.params(), **{knob: 1.0})
            out[knob][:] = rule.shift(params, ctx)
    else:
        kw = dict(support=ctx.support, gate=SUPPORT, crowding=CROWDING, span_us=ctx.span_us)
        lone = light_free_shifts(ctx.events, ctx.sensor_size, shift=1.0, **kw)
        both = light_free_shifts(ctx.events, ctx.sensor_size, shift=1.0, scatter_shift=1.0, **kw)
        out["light_free_shift"][:] = lone
        out["scatter_shift"][:] = both - lone
    return out


def stream_arrays(d: ModelDeflarer, ev: np.ndarray, size, delay: int) -> dict[str, np.ndarray]:
    """Base logits and unit shifts of every event of a stream, in one windowing."""
    net, w = d.model, d.window_us
    base = np.zeros(ev.size, np.float32)
    units = {k: np.zeros(ev.size, np.float32) for k in KNOBS}
    t = ev["t"].astype(np.int64)
    i = 0
    while i < ev.size:
        start = (int(t[i]) + delay) // w * w - delay
        k = int(np.searchsorted(t, start + w, side="left"))
        part = ev[i:k]
        rec = event_records(part, start, w, net.bins, size)
        cellf = event_features(part, size, start, w, net.bins, net.scale, records=rec)
        low = d._network(cellf[None], size, True)[0][: 2 * net.bins]
        support = np.empty(part.size, np.int64)
        base[i:k] = event_keep_logits(
            low, part, start, w, net.scale, pixel_params=d.pixel_params, sensor_size=size,
            support=support, records=rec,
        )  # fmt: skip
        ctx = WindowContext(part, size, covered_us(part, start, w), support)
        for name, v in unit_shifts(ctx).items():
            units[name][i:k] = v
        i = k
    return {"base": base, **units}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--per-stream", type=int, default=60_000, help="events drawn per stream")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    w = bundled_weights("night")
    card = read_card(w)
    d = ModelDeflarer(w, runtime="torch", batch_windows=1, **{k: 0 for k in card.rules})
    rng = np.random.default_rng(args.seed)
    rows: dict[str, list[np.ndarray]] = {}
    files = sorted(args.data.glob("*/test/*.h5"))
    for n, path in enumerate(files):
        inp, gt, size, _, _ = read_sequence(path)
        y = keep_labels(inp, gt)
        light = _component(path, "light")
        lit = keep_labels(inp, light) if light is not None else np.zeros(inp.size, bool)
        streams = [(inp, y | lit, lit, path.parent.parent.name)]
        scene = _component(path, "background")
        if scene is not None:
            streams.append((scene, np.ones(scene.size, bool), np.zeros(scene.size, bool),
                            "scene without a light"))  # fmt: skip
        for ev, keep, own, group in streams:
            if not ev.size:
                continue
            take = np.sort(rng.choice(ev.size, min(args.per_stream, ev.size), replace=False))
            for view, delay in enumerate(DELAYS):
                for name, v in stream_arrays(d, ev, size, delay).items():
                    rows.setdefault(f"{name}_{view}", []).append(v[take])
            rows.setdefault("y", []).append(keep[take])
            rows.setdefault("light", []).append(own[take])
            rows.setdefault("group", []).append(np.full(take.size, group))
            rows.setdefault("source", []).append(np.full(take.size, n, np.int32))
        print(f"{n + 1}/{len(files)} {path.parent.parent.name}/{path.name}", flush=True)
    np.savez_compressed(str(args.out), **{k: np.concatenate(v) for k, v in rows.items()},
                        files=np.array([str(f) for f in files]))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
