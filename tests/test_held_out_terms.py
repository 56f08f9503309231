"""The benchmarks' scoring from rule terms reproduces the product's scores."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from edeflare.eval.score import score_recording
from edeflare.io import read_events
from edeflare.lights import bundled_lights, load_lights
from edeflare.models.infer import ModelDeflarer, bundled_weights

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
LAMPS = "davis346_flicker_lamps.aedat4"


@pytest.fixture
def terms_recording(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    from _held_out import TermsRecording

    yield TermsRecording
    sys.modules.pop("_held_out", None)


def test_scores_from_terms_are_score_recordings_at_four_phases(real_data, terms_recording):
    """At the card's knobs and at others, every term of the mean over four phases."""
    r = read_events(real_data / LAMPS)
    lights = load_lights(bundled_lights(LAMPS), r.sensor_size)
    d = ModelDeflarer(bundled_weights("night"), runtime="torch")
    item = terms_recording("lamps", d, r.events, r.sensor_size, lights, phases=4)
    assert item.terms.delays_us == (0, 5_000, 10_000, 15_000)
    assert item.views == [(0, 1), (1, 2), (2, 3), (3, 0)]
    card = _card(d)
    assert card["halo_shift"] == 3.0 and card["scatter_shift"] == 4.0
    for knobs, threshold in [({}, 0.4), ({"halo_shift": 0.0, "far_shift": 8.0}, 0.6)]:
        params = {"keep_threshold": threshold, **knobs}
        result = score_recording(real_data / LAMPS, ["model"], lights=lights,
                                 method_params={"model": params}, phases=4)  # fmt: skip
        want = result.rows[0]
        got = item.measure({**card, **knobs}, [0.3, threshold])[1]
        expected = [want.flare_removed, want.light_kept, want.background_kept, want.combined]
        assert got.tolist() == pytest.approx(expected, abs=1e-9), (knobs, threshold)
    # a lower threshold keeps more: less flare removed, more light kept
    low, high = item.measure(card, [0.2, 0.8])
    assert low[0] < high[0] and low[1] >= high[1]


def test_without_an_annotation_the_score_is_the_share_kept(real_data, terms_recording):
    r = read_events(real_data / "davis346_street_cars.aedat4")
    events = r.events[:30_000]
    d = ModelDeflarer(bundled_weights("night"), runtime="torch")
    item = terms_recording("street", d, events, r.sensor_size, phases=2)
    assert item.terms.delays_us == (0, 5_000, 10_000, 15_000)  # phases 0 and 10 ms
    assert item.views == [(0, 1), (2, 3)]
    got = item.measure(_card(d), [0.4])[0]
    assert got[:3].tolist() == [pytest.approx(float("nan"), nan_ok=True)] * 3
    kept = [score_recording_kept(d, events, r.sensor_size, delay) for delay in (0, 10_000)]
    assert got[3] == pytest.approx(sum(kept) / 2, abs=1e-12)


def score_recording_kept(d, events, size, delay):
    """The share of a recording the model keeps when delayed by ``delay`` microseconds."""
    shifted = events.copy()
    shifted["t"] += delay
    return d(shifted, size).size / events.size


def _card(d):
    """The model's rule shifts, by knob."""
    from edeflare.rules.terms import shift_knobs

    return {k: float(d.rules[k]) for k in shift_knobs()}
