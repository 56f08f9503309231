"""The issue's real streaks and ghost ring (digitised), before and after: ``reference_window.png``.

Run from the repository root, with ``../shared/reference/`` present::

    python docs/figures/make_reference_window.py docs/figures/reference_window.png

One 100 ms window of ``benchmarks/reference_window.py``'s proxy (the lights' pixels
firing 4 times a window), cropped to the picture's panel: the input, the default with
an earlier card (the light-free support alone), the default, and dv-processing's
FastDecayNoiseFilter. Each method runs on the whole second; the figure shows its first
window. ON red, OFF blue (``edeflare.viz.event_frame``).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from reference_window import OFFSET, PANEL_COLUMNS, SENSOR, WINDOW_US, reference_window

from edeflare import list_methods
from edeflare.methods import deflare
from edeflare.viz import event_frame, grid, save_image


def main(out: str) -> None:
    ev = reference_window(core=4)
    rows = {
        "input (digitised, 100 ms)": ev,
        "default, light-free support alone (before)": deflare(
            ev, SENSOR, "model", light_free_crowding=0, scatter_shift=0
        ),
        "default (crowding and scattered-light field)": deflare(ev, SENSOR, "model"),
    }
    if "dv-fastdecay" in list_methods():
        rows["dv-fastdecay (defaults)"] = deflare(ev, SENSOR, "dv-fastdecay")
    x0, height = OFFSET[0], 552 + OFFSET[1]
    frames = [
        event_frame(e[e["t"] < WINDOW_US], SENSOR)[:height, x0 : x0 + PANEL_COLUMNS]
        for e in rows.values()
    ]
    save_image(out, grid(frames, captions=list(rows), ncols=2))


if __name__ == "__main__":
    main(sys.argv[1])
