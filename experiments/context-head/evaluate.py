"""Score fitted heads (one windowing) on eflare-forward and the real recordings, beside
`general` and `night` with one windowing.

    python experiments/context-head/evaluate.py RUN [RUN ...] --out results.json
    python experiments/context-head/evaluate.py RUN [RUN ...] --ensemble --out results.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch
from common import LN3, ContextHead, night_deflarer, window_inputs
from safetensors.torch import load_file

from edeflare.eval.benchmark import benchmark
from edeflare.eval.score import score_recording
from edeflare.io import read_events
from edeflare.io.sequence import list_sequences
from edeflare.lights import bundled_lights
from edeflare.methods import Method, create_method
from edeflare.methods.windows import WindowStreamer
from edeflare.models.infer import bundled_weights

REPO = Path(__file__).resolve().parents[2]
REAL = REPO.parent / "shared" / "data" / "real"  # ../shared beside the checkout
LIGHTS = ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4")
NO_LIGHT = (
    "davis346_street_cars.aedat4",
    "davis346_lowlight_cradle.aedat4",
    "prophesee_gen41_street.raw",
)
FORWARD = REPO / "benchmarks" / ".data" / "eflare-forward" / "test"  # flare_targets.py makes it


class CtxMethod(Method):
    def __init__(self, run: Path) -> None:
        super().__init__()
        s = json.loads((run / "summary.json").read_text())
        a = s["args"]
        st = load_file(run / "head.safetensors")
        self.model = ContextHead(
            int(st["mean"].numel()),
            int(a["k"]),
            tuple(map(int, a["hidden"].split(","))),
            tuple(map(int, a["widths"].split(","))),
            in_ch=int(st["cmean"].shape[0]),
        )
        self.model.load_state_dict(st)
        self.model.gate_light_free = a.get("gate") == "True"
        self.model.eval()
        self.thr = float(s["threshold"])
        self.d = night_deflarer()

    def probability(self, start: int, ev: np.ndarray, size) -> np.ndarray:
        lights = self.model.cmean.shape[0] == 34  # a light-map channel
        c, f, cell = window_inputs(self.d, ev, start, size, lights)
        with torch.no_grad():
            x = torch.from_numpy(f)
            rows = None
            if self.model.k:
                win = torch.zeros(ev.size, dtype=torch.long)
                rows = self.model.rows(torch.from_numpy(c)[None], win, torch.from_numpy(cell))
            v = self.model(x, rows).numpy()
        return 1 / (1 + np.exp(-(v + LN3)))

    def keep(self, start: int, ev: np.ndarray, size) -> np.ndarray:
        return self.probability(start, ev, size) > self.thr

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        def transform(batch, span):
            return [ev[self.keep(s, ev, sensor_size)] for s, ev in batch]

        return WindowStreamer(self.d.window_us, transform)


def score_real(methods: dict[str, Method], out: dict) -> None:
    """Score ``methods`` on the real recordings into ``out["real"]`` and ``out["no_light"]``."""
    from edeflare.methods.base import METHODS

    for name, m in methods.items():
        key = f"study-{name}"
        if key not in METHODS:
            METHODS.register(key, lambda m=m: m)
    for rec in LIGHTS:
        r = score_recording(
            REAL / rec, [f"study-{n}" for n in methods], lights=bundled_lights(rec), phases=4
        )
        for row in r.rows:
            out["real"].setdefault(rec, {})[row.method] = {
                "flare removed": row.flare_removed,
                "light kept": row.light_kept,
                "background kept": row.background_kept,
                "combined": row.combined,
            }
            print(
                f"{rec[:20]} {row.method:22s} flare {row.flare_removed:.3f} light "
                f"{row.light_kept:.3f} bg {row.background_kept:.3f} comb {row.combined:.3f}",
                flush=True,
            )
    for rec in NO_LIGHT:
        r = read_events(REAL / rec)
        for name, m in methods.items():
            kept = m(r.events, r.sensor_size).size / r.events.size
            out["no_light"].setdefault(rec, {})[name] = kept
            print(f"{rec[:20]} {name:22s} kept {kept:.3f}", flush=True)


class EnsembleMethod(CtxMethod):
    """Several fitted heads: the mean of their keep probabilities against their mean threshold."""

    def __init__(self, runs: list[Path]) -> None:
        Method.__init__(self)
        self.members = [CtxMethod(r) for r in runs]
        self.d = self.members[0].d
        self.thr = float(np.mean([m.thr for m in self.members]))

    def keep(self, start: int, ev: np.ndarray, size) -> np.ndarray:
        p = np.mean([m.probability(start, ev, size) for m in self.members], axis=0)
        return p > self.thr


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--no-reference", action="store_true", help="leave out general/night")
    ap.add_argument("--ensemble", action="store_true", help="score the runs' mean as one head")
    a = ap.parse_args()
    if a.ensemble:
        methods = {"ensemble": EnsembleMethod(a.runs)}
    else:
        methods = {r.name: CtxMethod(r) for r in a.runs}
    if not a.no_reference:
        methods["general-1view"] = create_method(
            "model", weights=str(bundled_weights("general")), phase_shift_us=0
        )
        methods["night-1view"] = create_method("model", phase_shift_us=0)
    out = {"forward": {}, "real": {}, "no_light": {}}
    t0 = time.time()
    files = list_sequences(FORWARD)
    res = benchmark(files, {"raw": create_method("raw"), **methods}, progress=False)
    for m, s in res.evaluation.methods.items():
        out["forward"][m] = s.means
    raw = out["forward"]["raw"]["chamfer"]
    for m, v in out["forward"].items():
        below = 1 - v["chamfer"] / raw
        print(
            f"forward {m:16s} chamfer {v['chamfer']:.3f} ({below:+.1%} below raw)"
            f" mse {v['mse']:.3f} r_f1 {v['r_f1']:.3f} tp_f1 {v['tp_f1']:.3f}",
            flush=True,
        )
    print(f"{time.time() - t0:.0f}s", flush=True)
    score_real(methods, out)
    a.out.write_text(json.dumps(out, indent=1, default=float))
    print(f"done {time.time() - t0:.0f}s")


if __name__ == "__main__":
    main()
