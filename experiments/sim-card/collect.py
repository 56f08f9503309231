"""Each validation event's keep logit under `night`'s network and each rule's unit shift.

For every test-split sequence of a simulated dataset (each part of `eflare-train`), its
input (labels: kept where the clean lens sees it or it is the light's own) and its scene
alone (every event kept), in both of the product's windowings (aligned, and 5 ms later),
this stores for a random draw of events:

- ``base``: `night`'s keep logits with every rule off (2 views x events);
- ``units:ON:K``: what shift knob K adds at value 1 when the rule's knobs ON are on
  (:meth:`edeflare.models.infer.ModelDeflarer.rule_terms`), ``light_free_support`` and
  ``light_free_crowding`` at the card's 2 and 3;
- ``y`` (keep), ``light`` (the light's own), ``group`` (the dataset's part, or the scene
  alone).

A card's decision on an event is then ``unflatten(arrays).logits(knobs) >
keep_logit_threshold(thr)``, as the product makes it: ``fit.py`` searches the knobs
without running the network again.

    python collect.py DATA OUT.npz            # DATA: edeflare simulate --recipe eflare-train
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from edeflare.io.sequence import read_sequence
from edeflare.models.head_training import _component, keep_labels
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.rules.terms import RuleTerms


def flatten(terms: RuleTerms, take: np.ndarray) -> dict[str, np.ndarray]:
    """The drawn events' terms as named arrays (``base``, ``units:ON:KNOB``), both views."""
    out = {"base": terms.base[:, take]}
    for on, per_knob in terms.units.items():
        for name, unit in per_knob.items():
            out[f"units:{'+'.join(on)}:{name}"] = unit[:, take]
    return out


def unflatten(arrays: dict[str, np.ndarray]) -> RuleTerms:
    """:func:`flatten`'s arrays back as :class:`RuleTerms` (the two views)."""
    units: dict[tuple[str, ...], dict[str, np.ndarray]] = {}
    for key, value in arrays.items():
        if key.startswith("units:"):
            _, on, name = key.split(":")
            units.setdefault(tuple(on.split("+")), {})[name] = value
    return RuleTerms((0, 5_000), arrays["base"], units)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--per-stream", type=int, default=60_000, help="events drawn per stream")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    d = ModelDeflarer(bundled_weights("night"), runtime="torch")
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
            for name, v in flatten(d.rule_terms(ev, size), take).items():
                rows.setdefault(name, []).append(v)
            rows.setdefault("y", []).append(keep[take])
            rows.setdefault("light", []).append(own[take])
            rows.setdefault("group", []).append(np.full(take.size, group))
            rows.setdefault("source", []).append(np.full(take.size, n, np.int32))
        print(f"{n + 1}/{len(files)} {path.parent.parent.name}/{path.name}", flush=True)
    np.savez_compressed(str(args.out), **{k: np.concatenate(v, axis=-1) for k, v in rows.items()},
                        files=np.array([str(f) for f in files]))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
