"""The flare of a real night recording with streaks and a ghost ring, digitised from its picture.

Issue 13's example of real flare, a Prophesee 1280x720 night recording of a bright
light (radial scattering streaks and a ghost ring), is not in ``../shared/data/real``;
only one 100 ms window of it is, as the left panel of
``../shared/reference/real_flare_example.png`` (its right panel: what dv-processing's
FastDecayNoiseFilter kept of it). This script turns that panel back into events and
scores every method on them with ``edeflare score``'s regions
(``reference_window_lights.json``, annotated on the picture).

What the picture keeps, and what :func:`reference_window` assumes for the rest:

- **Positions**, one sensor pixel per picture pixel (its dots are single pixels, and
  the streaks' 250 px reach is the report's "halos up to about 250 px in radius at
  1280x720"). The crop's origin is not drawn: the panel is placed where the ghost ring
  is the light's reflection through the sensor's centre (:data:`OFFSET`).
- **Polarity** (blue ON, red OFF, purple one of each).
- **Timestamps are lost.** Each event gets a time uniform in the 100 ms (seeded); the
  window is repeated ``REPEAT`` times with new times (1 s of a still scene).
- **Multiplicity is lost:** a pixel that fired ten times is drawn as one that fired
  once. The recording's rate (1.2 M events in 10.8 s, 11,100 per 100 ms, against the
  panel's 5,431 drawn) is not enough to say where the rest fell, so each case lets the
  lights' own pixels fire ``core`` times per window: 1 (as drawn), 4 and 8. At 4, the
  filters reproduce what was reported on the recording itself: FastDecay keeps
  86 % of the light (reported: 85 %) and the previous default (``eflare``) removes
  70 % of it (reported: 65 %). The study "reference-window" of ``docs/studies.md``
  has the checks.

So this is a proxy: the flare's places and polarities are real, its timing is not. It is
where the bundled default is tested on streaks and a ghost ring like the reported ones.

Rows per case: the raw input, the baselines, the three dv-processing filters (where
installed), the bundled default, the default with its light-free support alone (no
crowding test, no scattered-light field: an earlier card) and
without it (the card before that); with ``--eflare`` also the previous default
``eflare`` (slow at this size: 3 minutes a case on 2 cores). The reference is
``dv-fastdecay``, the filter the report compared with: ``vs fastdecay`` is each row's
combined score over its.

Run: ``python benchmarks/reference_window.py [--eflare] [--model WEIGHTS]``; writes
``results/reference_window.json`` (about a minute).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from _common import add_model_option, report
from PIL import Image

from edeflare import list_methods
from edeflare.eval.score import classify_events, score_events
from edeflare.events import EVENT_DTYPE, make_events, sort_events
from edeflare.io import write_events
from edeflare.lights import load_lights
from edeflare.methods import deflare

PICTURE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "real_flare_example.png"
LIGHTS = Path(__file__).with_name("reference_window_lights.json")
SENSOR = (1280, 720)
SOURCE = "night_recording"
"""The recording the panel is a window of (``night_recording.py``): a leave-one-out holds
the two out together, since a setting chosen on one has seen the other."""
PANEL_COLUMNS = 740  # the input panel; the next starts 744 columns on
TITLE_ROWS = 30
COLOURS = {(30, 70, 220): (1,), (220, 30, 30): (0,), (125, 50, 125): (1, 0)}  # ON, OFF, both
OFFSET = (53, -32)
"""Sensor pixel = picture pixel + OFFSET. The light's core (picture (410.3, 321.6)) and
the centre of the ghost's outer arc (a circle fitted to its left edge: (763, 494)) put
the optical centre at picture (587, 408): the sensor's centre at an offset of
(53, -48). The panel's top drawn row (32) must stay on the sensor: y is clamped to -32."""
WINDOW_US = 100_000
REPEAT = 10
CORES = (1, 4, 8)


def drawn_events(picture: Path = PICTURE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, y, p)`` on the sensor of every event the panel draws (purple: two)."""
    rgb = np.asarray(Image.open(picture).convert("RGB"))[TITLE_ROWS:, :PANEL_COLUMNS]
    xs, ys, ps = [], [], []
    for colour, polarities in COLOURS.items():
        y, x = np.nonzero((rgb == colour).all(axis=-1))
        for p in polarities:
            xs.append(x + OFFSET[0])
            ys.append(y + TITLE_ROWS + OFFSET[1])
            ps.append(np.full(x.size, p))
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(ps)


def reference_window(core: int = 4, seed: int = 0, picture: Path = PICTURE) -> np.ndarray:
    """The panel as ``REPEAT`` windows of 100 ms, the lights' pixels firing ``core`` times.

    Examples
    --------
    >>> ev = reference_window(core=1)  # doctest: +SKIP
    >>> ev.size                        # doctest: +SKIP
    54310
    """
    x, y, p = drawn_events(picture)
    if core > 1:
        drawn = make_events(np.zeros(x.size, np.int64), x, y, p)
        lit = classify_events(drawn, load_lights(LIGHTS, SENSOR), SENSOR).labels == "light"
        times = np.where(lit, core, 1)
        x, y, p = np.repeat(x, times), np.repeat(y, times), np.repeat(p, times)
    rng = np.random.default_rng(seed)
    ev = np.empty(REPEAT * x.size, EVENT_DTYPE)
    ev["t"] = np.repeat(np.arange(REPEAT) * WINDOW_US, x.size) + rng.integers(0, WINDOW_US, ev.size)
    ev["x"], ev["y"], ev["p"] = np.tile(x, REPEAT), np.tile(y, REPEAT), np.tile(p, REPEAT)
    return sort_events(ev)


def methods(eflare: bool = False, models: Sequence[str] = ()) -> dict[str, tuple[str, dict]]:
    """Row label -> (method, parameters); ``models``: more weights (names or files)."""
    rows = {"raw": ("raw", {}), "efr": ("efr", {}), "pfd-a": ("pfd-a", {}), "pfd-b": ("pfd-b", {})}
    for name in ("dv-fastdecay", "dv-bafilter", "dv-knoise"):
        if name in list_methods():
            rows[name] = (name, {})
    rows["default"] = ("model", {})
    rows["default, light-free support alone"] = (
        "model",
        {"light_free_crowding": 0, "scatter_shift": 0},
    )
    rows["default, no light-free support"] = ("model", {"light_free_support": 0})
    if eflare:
        rows["eflare (previous default)"] = ("model", {"weights": "eflare"})
    for weights in models:
        rows[f"model {Path(weights).stem}"] = ("model", {"weights": weights})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cores", type=int, nargs="+", default=list(CORES))
    parser.add_argument(
        "--eflare",
        action="store_true",
        help="also the previous default eflare (3 minutes a case on 2 cores)",
    )
    parser.add_argument(
        "--write",
        type=Path,
        metavar="OUT",
        help="only write the window (core 4, the one the targets score) to OUT (any event "
        "format), e.g. for edeflare tune-head --real OUT:benchmarks/reference_window_lights.json",
    )
    add_model_option(parser)
    args = parser.parse_args()
    if not PICTURE.is_file():
        raise SystemExit(f"{PICTURE} is missing: the reference picture is needed")
    if args.write is not None:
        write_events(args.write, reference_window(4), SENSOR)
        print(f"wrote {args.write}")
        return
    lights = load_lights(LIGHTS, SENSOR)
    rows = []
    for core in args.cores:
        ev = reference_window(core)
        rows_of = methods(args.eflare, args.model)
        outputs = {label: deflare(ev, SENSOR, name, rng=0, **params)
                   for label, (name, params) in rows_of.items()}  # fmt: skip
        scores = score_events(ev, outputs, lights, SENSOR)
        ref = {s.method: s.combined for s in scores}.get("dv-fastdecay", float("nan"))
        for s in scores:
            rows.append({
                "core": core, "method": s.method,
                "halo removed": round(100 * s.halo_removed, 1),
                "ghost removed": round(100 * s.ghost_removed, 1),
                "flare removed": round(100 * s.flare_removed, 1),
                "light kept": round(100 * s.light_kept, 1),
                "combined": round(s.combined, 3),
                "vs fastdecay": round(s.combined / ref, 3) if ref > 0 else None,
            })  # fmt: skip
    report("reference_window", rows, list(rows[0]))


if __name__ == "__main__":
    main()
