"""The bundled default model, night: its card, and what it does to the annotated real recordings."""

from __future__ import annotations

import pytest

from conftest import real_data_dir
from edeflare.deflare import deflare
from edeflare.eval.score import bundled_lights, load_lights, score_events
from edeflare.io import read_events
from edeflare.models.infer import DEFAULT_MODEL, bundled_weights
from edeflare.models.weights import read_card


def test_the_night_card_says_what_it_is_and_night_is_the_default():
    card = read_card(bundled_weights("night"))
    assert DEFAULT_MODEL == "night" and bundled_weights() == bundled_weights("night")
    assert card.preset == "mask.pixel" and card.keep_threshold == 0.5  # the training default
    assert "--loss keep" in card.command and "--freeze-init" in card.command
    assert "--recipe eflare-night" in card.data
    assert card.metrics["score_davis_lamps_combined"] == 0.717
    assert read_card(bundled_weights("eflare")).preset == "unet2d.lite"  # the previous default


@pytest.mark.parametrize(
    ("name", "min_removed", "min_light", "min_combined"),
    [
        ("prophesee_gen3_rotating_light.raw", 0.60, 0.90, 0.72),  # docs: 62.5 %, 92.3 %, 0.745
        ("davis346_flicker_lamps.aedat4", 0.61, 0.89, 0.69),  # docs: 64.1 %, 91.9 %, 0.717
    ],
)
def test_the_default_removes_flare_around_real_lights_and_keeps_them(
    name, min_removed, min_light, min_combined
):
    rec = read_events(real_data_dir() / name)
    lights = load_lights(bundled_lights(name), rec.sensor_size)
    outputs = {
        "default": deflare(rec.events, rec.sensor_size, "model"),
        "eflare": deflare(rec.events, rec.sensor_size, "model", weights="eflare"),
        # the filters users already run (the dv extra, part of the test extra)
        "dv-fastdecay": deflare(rec.events, rec.sensor_size, "dv-fastdecay"),
        "dv-bafilter": deflare(rec.events, rec.sensor_size, "dv-bafilter"),
    }
    default, eflare, *filters = score_events(rec.events, outputs, lights, rec.sensor_size)
    assert default.flare_removed >= min_removed and default.light_kept >= min_light
    assert default.combined >= min_combined
    assert default.combined > 4 * eflare.combined  # the previous default erodes the light
    assert all(default.combined > f.combined for f in filters)
