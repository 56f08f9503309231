"""A stream's keep logits split into the network's and each rule knob's term."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_benchmark
from edeflare.errors import ParameterError
from edeflare.events import concat_events, event_keys, make_events
from edeflare.io import read_events
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.models.mask_kernels import keep_logit_threshold
from edeflare.rules.terms import RuleTerms, shift_knobs

SETTINGS = [
    {},  # every rule off: the network alone
    {"halo_shift": 3.0, "ghost_shift": 3.0, "streak_shift": 8.0, "far_shift": 4.0,
     "light_free_shift": 4.0, "scatter_shift": 4.0},  # the card's
    {"halo_shift": 2.0, "far_shift": 8.0, "light_free_shift": 6.0, "scatter_shift": 8.0},
    {"far_shift": 2.5, "light_free_shift": 3.5},  # the light-free shift without scatter
    {"scatter_shift": 7.0, "streak_shift": 0.5},  # scatter without the light-free shift
]  # fmt: skip


def _kept(events, size, model="night", **knobs):
    """What a model keeps with these shifts (the card's counts and threshold)."""
    d = ModelDeflarer(bundled_weights(model), runtime="torch",
                      **{k: knobs.get(k, 0.0) for k in shift_knobs()})  # fmt: skip
    out = d(events, size)
    return np.isin(event_keys(events, size), event_keys(out, size))


def _scene(size=(96, 72)):
    """A bright 8x8 block firing fast (a light) among scattered events, then 40 ms of
    scattered events alone (windows without a light)."""
    rng = np.random.default_rng(3)
    w, h = size
    n = 3_000
    scatter = make_events(np.sort(rng.integers(0, 80_000, n)), rng.integers(0, w, n),
                          rng.integers(0, h, n), rng.integers(0, 2, n))  # fmt: skip
    yy, xx = np.mgrid[30:38, 40:48]
    k = 40 * xx.size
    block = make_events(np.arange(k) * 40_000 // k, np.tile(xx.ravel(), 40),
                        np.tile(yy.ravel(), 40), np.ones(k, np.int64))  # fmt: skip
    ev = concat_events([scatter, block])
    return ev[np.argsort(ev["t"], kind="stable")], size


def _check(events, size):
    d = ModelDeflarer(bundled_weights("night"), runtime="torch")
    terms = d.rule_terms(events, size)
    assert terms.delays_us == (0, 5_000)  # the model's two views
    cut = keep_logit_threshold(d.keep_threshold)
    for knobs in SETTINGS:
        mine = terms.logits(knobs) > cut
        np.testing.assert_array_equal(mine, _kept(events, size, **knobs), err_msg=str(knobs))


def test_the_terms_keep_what_the_model_keeps_at_any_shifts():
    events, size = _scene()
    _check(events, size)


def test_on_real_recordings_too(real_data):
    for name in ("prophesee_gen3_rotating_light.raw", "davis346_street_cars.aedat4"):
        r = read_events(real_data / name)
        _check(r.events[:200_000], r.sensor_size)


@pytest.mark.slow
def test_on_a_slow_lamps_scattered_light_too(monkeypatch, real_data):
    """The reference window's lamp is too slow for the light test: its windows are
    light-free and hold a scattered-light field, where the light-free shift covers other
    events when the scatter shift is on (about 30 s on 2 cores)."""
    module = load_benchmark(monkeypatch, "reference_window")
    if not module.PICTURE.is_file():
        pytest.skip(f"{module.PICTURE} is not there")
    _check(module.reference_window(4), module.SENSOR)


def test_the_logits_are_the_network_plus_each_knob_times_its_unit():
    base = np.array([[1.0, -2.0], [3.0, 0.0]], np.float32)  # two windowings, two events
    units = {
        ("halo_shift",): {"halo_shift": np.array([[-1.0, 0.0], [-1.0, -1.0]], np.float32)},
        ("light_free_shift",): {"light_free_shift": np.array([[1.0, 1.0], [0, 0]], np.float32)},
        ("light_free_shift", "scatter_shift"): {
            "light_free_shift": np.array([[0.0, 1.0], [0, 0]], np.float32),
            "scatter_shift": np.array([[2.0, -1.0], [0, 0]], np.float32),
        },
    }
    terms = RuleTerms((0, 5_000), base, units)
    # view 0: [1 - 2, -2] + 4 * [1, 1] = [3, 2]; view 1: [3 - 2, 0 - 2] = [1, -2]
    assert terms.logits({"halo_shift": 2.0, "light_free_shift": 4.0}).tolist() == [2.0, 0.0]
    # with a scatter shift the light-free shift covers other events: [1 - 2 + 0 + 2, -2 + 4 - 1]
    both = terms.logits({"halo_shift": 2.0, "light_free_shift": 4.0, "scatter_shift": 1.0},
                        views=[0])  # fmt: skip
    assert both.tolist() == [1.0, 1.0]
    with pytest.raises(ParameterError, match=r"unknown shift knob\(s\) \['glow_shift'\]"):
        terms.logits({"glow_shift": 1.0})


def test_a_model_with_a_keep_head_splits_the_same_way():
    """A keep head's logits take the rules' shifts on top: its terms are exact too."""
    events, size = _scene()
    d = ModelDeflarer(bundled_weights("learned"), runtime="torch")
    terms = d.rule_terms(events, size)
    cut = keep_logit_threshold(d.keep_threshold)
    np.testing.assert_array_equal(terms.logits({}) > cut, _kept(events, size, "learned"))
    knobs = SETTINGS[2]
    mine = terms.logits(knobs) > cut
    theirs = _kept(events, size, "learned", **knobs)
    np.testing.assert_array_equal(mine, theirs)
    assert 0 < theirs.sum() < (terms.logits({}) > cut).sum()  # the shifts remove some
