"""Where the flare reaches, measured from a recording: rings of event rate around a light."""

from __future__ import annotations

import math

import numpy as np
import pytest

from edeflare.cli import main
from edeflare.io import write_events
from edeflare.lights import Lights, LightSource, flare_reach, measure_regions
from edeflare.lights.reach import EXCESS, synthetic_flare


def _true_reach(radius: float, reach: float, strength: float) -> float:
    """Where the drawn halo's rate falls to EXCESS of the background's (or its end)."""
    return min(reach, radius * math.sqrt(strength / EXCESS))


@pytest.mark.parametrize("size", [(346, 260), (640, 480), (1280, 720)])
@pytest.mark.parametrize("log_strength", [1.5, 2.5, 3.5, 5.0])
def test_the_reach_is_found_within_15_percent_at_every_size_and_strength(size, log_strength):
    strength = 10.0**log_strength
    radius, reach = 0.02 * size[0], 0.25 * size[0]
    centre = (0.35 * size[0], 0.4 * size[1])
    # a strong source fires so much that a shorter recording holds as many events
    duration = int(100_000 * min(1.0, 10**1.5 / strength) ** 0.5)
    ev = synthetic_flare(
        np.random.default_rng(int(log_strength * 10)), size, centre, radius=radius,
        reach=reach, strength=strength, ghost_radius=2 * radius, duration_us=duration,
    )  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(*centre, radius))
    true = _true_reach(radius, reach, strength)
    assert found.halo_outer_px is not None
    assert abs(found.halo_outer_px - true) <= 0.15 * true, (found.halo_outer_px, true)
    gx, gy = found.ghost_centre
    assert math.hypot(gx - (size[0] - 1 - centre[0]), gy - (size[1] - 1 - centre[1])) <= 10


def test_a_faint_source_shows_no_ghost_and_keeps_the_factor():
    size = (346, 260)
    ev = synthetic_flare(np.random.default_rng(3), size, (100, 90), radius=6, reach=80,
                         strength=50.0)  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(100, 90, 6))
    assert found.ghost_radius_px is None and found.halo_outer_px is not None
    lights = measure_regions(ev, size, Lights((LightSource.circle(100, 90, 6),)))
    (source,) = lights.sources
    assert source.ghost_radius_px is None and source.halo_outer_px == found.halo_outer_px
    assert "measured" in lights.note


def test_a_ghost_is_measured_where_the_light_reflects():
    size = (640, 480)
    ev = synthetic_flare(np.random.default_rng(4), size, (200, 150), radius=10, reach=150,
                         strength=1000.0, ghost_radius=30)  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(200, 150, 10))
    assert found.ghost_centre == (439.0, 329.0)
    assert found.ghost_radius_px is not None and 25 <= found.ghost_radius_px <= 40


def test_score_records_the_regions_it_measured_and_a_dark_recording_gets_a_message(
    tmp_path, capsys
):
    size = (346, 260)
    ev = synthetic_flare(np.random.default_rng(5), size, (120, 100), radius=6, reach=80,
                         strength=300.0)  # fmt: skip
    write_events(tmp_path / "lamp.h5", ev, size)
    report = tmp_path / "s.json"
    args = ["score", str(tmp_path / "lamp.h5"), "-m", "raw", "--detect-lights", "--measure-regions"]
    assert main([*args, "--json", str(report)]) == 0
    import json

    data = json.loads(report.read_text())
    (source,) = data["lights"]["sources"]
    assert 0.85 * 80 <= source["halo_outer_px"] <= 1.15 * 80
    assert "measured" in data["lights"]["note"]
    capsys.readouterr()
    dark = ev[:0]
    write_events(tmp_path / "dark.h5", dark, size)
    assert main(["score", str(tmp_path / "dark.h5"), "-m", "raw", "--detect-lights"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("edeflare: error:") and "dark.h5" in err and "nan" not in err.lower()
