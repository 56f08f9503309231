"""The bundled default model, night: its card, and what it does to the annotated real recordings."""

from __future__ import annotations

import pytest

from conftest import real_data_dir
from edeflare.deflare import deflare
from edeflare.eval.score import bundled_lights, load_lights, score_events, score_recording
from edeflare.io import read_events
from edeflare.models.infer import DEFAULT_MODEL, bundled_weights
from edeflare.models.weights import read_card


def test_the_night_card_says_what_it_is_and_night_is_the_default():
    card = read_card(bundled_weights("night"))
    assert DEFAULT_MODEL == "night" and bundled_weights() == bundled_weights("night")
    assert card.preset == "mask.pixel" and card.keep_threshold == 0.5  # the training default
    assert "--loss keep" in card.command and "--init night-9893b7a.safetensors" in card.command
    assert "--recipe eflare-night" in card.data and "gen_day.py" in card.data
    assert card.metrics["score_davis_lamps_combined"] == 0.779
    assert read_card(bundled_weights("eflare")).preset == "unet2d.lite"  # the previous default


@pytest.mark.parametrize(
    ("name", "min_removed", "min_light", "min_combined", "behind_bafilter"),
    [
        # docs (mean of 4 window phases): 90.3 %, 98.1 %, 0.940; dv-bafilter 0.949 (it keeps
        # 99.8 % of the blob)
        ("prophesee_gen3_rotating_light.raw", 0.88, 0.97, 0.93, 0.015),
        # 64.3 %, 99.0 %, 0.726 (worst phase 0.710); dv-fastdecay 0.693 at every phase
        ("davis346_flicker_lamps.aedat4", 0.60, 0.98, 0.71, 0.0),
    ],
)
def test_the_default_removes_flare_around_real_lights_and_keeps_them(
    name, min_removed, min_light, min_combined, behind_bafilter
):
    # every method at 4 window phases: where a recording's windows fall is chance
    report = score_recording(
        real_data_dir() / name,
        ["model", "dv-fastdecay", "dv-bafilter"],
        lights=bundled_lights(name),
        phases=4,
    )
    default, fastdecay, bafilter = report.rows
    assert default.flare_removed >= min_removed and default.light_kept >= min_light
    assert default.combined >= min_combined
    assert default.combined_worst > fastdecay.combined  # at every phase
    # Gen3: second to it (it keeps 99.8 % of the blob), by less than behind_bafilter
    assert default.combined > bafilter.combined - behind_bafilter


def test_the_previous_default_erodes_the_light():
    name = "davis346_flicker_lamps.aedat4"
    rec = read_events(real_data_dir() / name)
    lights = load_lights(bundled_lights(name), rec.sensor_size)
    outputs = {
        "default": deflare(rec.events, rec.sensor_size, "model"),
        "eflare": deflare(rec.events, rec.sensor_size, "model", weights="eflare"),
    }
    default, eflare = score_events(rec.events, outputs, lights, rec.sensor_size)
    assert default.combined > 4 * eflare.combined and eflare.light_kept < 0.6


@pytest.mark.parametrize(
    ("name", "min_kept"),
    [
        ("davis346_street_cars.aedat4", 0.76),  # docs: 77.8 %
        ("davis346_lowlight_cradle.aedat4", 0.88),  # docs: 90.0 %
        ("prophesee_gen41_street.raw", 0.36),  # docs: 38.5 %, dense daytime texture
    ],
)
def test_the_default_leaves_most_of_a_scene_without_lights(name, min_kept):
    rec = read_events(real_data_dir() / name)
    kept = deflare(rec.events, rec.sensor_size, "model").size / rec.events.size
    assert kept >= min_kept
    if name.startswith("prophesee_gen41"):  # more than the density filter users run
        assert kept > deflare(rec.events, rec.sensor_size, "dv-fastdecay").size / rec.events.size
