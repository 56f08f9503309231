"""The Gen3 light with half its events (each kept with probability 0.5, seed 0) and its
one-phase score, as ``rate_columns.py`` and relative-rates' ``context_counts.py`` read it."""

from pathlib import Path

import numpy as np

from edeflare.eval.score import score_recording
from edeflare.io import read_events, write_events
from edeflare.lights import bundled_lights

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
FILE = "prophesee_gen3_rotating_light.raw"


def write_half(folder: str | Path) -> Path:
    """``folder/half.h5``: the Gen3 light with each event kept with probability 0.5."""
    r = read_events(REAL / FILE)
    path = Path(folder) / "half.h5"
    keep = np.random.default_rng(0).random(r.events.size) < 0.5
    write_events(path, r.events[keep], r.sensor_size)
    return path


def score_half(path: Path, params: dict) -> list[float]:
    """Flare removed, light kept and combined of the ``model`` method with ``params``."""
    res = score_recording(
        path, ["model"], lights=bundled_lights(FILE), phases=1, method_params={"model": params}
    )
    m = res.rows[0]
    return [round(float(v), 4) for v in (m.flare_removed, m.light_kept, m.combined)]
