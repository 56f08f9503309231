"""The bundled night model: its card, and what it does to the annotated real recordings."""

from __future__ import annotations

import pytest

from conftest import real_data_dir
from edeflare.deflare import deflare
from edeflare.eval.score import bundled_lights, load_lights, score_events
from edeflare.io import read_events
from edeflare.models.infer import bundled_weights
from edeflare.models.weights import read_card


def test_the_night_card_says_what_it_is():
    card = read_card(bundled_weights("night"))
    assert card.preset == "mask.fast" and card.keep_threshold == 0.7
    assert "--loss keep" in card.command and "thin.py" in card.data
    assert card.metrics["score_davis_lamps_combined"] == 0.739


@pytest.mark.parametrize(
    ("name", "min_removed", "min_light", "min_combined"),
    [
        ("prophesee_gen3_rotating_light.raw", 0.40, 0.86, 0.55),  # docs: 42.8 %, 88.9 %, 0.578
        ("davis346_flicker_lamps.aedat4", 0.68, 0.89, 0.71),  # docs: 71.9 %, 91.5 %, 0.739
    ],
)
def test_night_removes_flare_around_real_lights_and_keeps_them(
    name, min_removed, min_light, min_combined
):
    rec = read_events(real_data_dir() / name)
    out = deflare(rec.events, rec.sensor_size, "model", weights="night")
    lights = load_lights(bundled_lights(name), rec.sensor_size)
    night, default = score_events(
        rec.events,
        {"night": out, "default": deflare(rec.events, rec.sensor_size, "model")},
        lights,
        rec.sensor_size,
    )
    assert night.flare_removed >= min_removed and night.light_kept >= min_light
    assert night.combined >= min_combined
    assert night.combined > 4 * default.combined  # the default erodes the light, keeps flare
