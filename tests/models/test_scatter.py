"""Crowded isolated events and scattered-light fields (edeflare.rules.light_free): against
loops over the squares, by hand on small layouts, and in the light-free shift of the
model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from edeflare.errors import ParameterError
from edeflare.events import make_events
from edeflare.lights.cells import covered_us
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.models.mask_kernels import event_support
from edeflare.rules.light_free import (
    FIELD_MAX_RATE,
    FIELD_MIN_EVENTS,
    FIELD_MIN_SHARE,
    SCATTER_CELL,
    SCATTER_REACH,
    SOURCE_SUPPORT,
    crowded_isolated,
    light_free_shifts,
    scatter_field,
    scatter_reach,
)


def _crowded_by_loops(events, size, isolated, z, cell, reach):
    """The definition, one cell and one event at a time."""
    gw, gh = -(-size[0] // cell), -(-size[1] // cell)
    counts = np.zeros((gh, gw))
    for x, y in zip(events["x"][isolated].tolist(), events["y"][isolated].tolist(), strict=True):
        counts[y // cell, x // cell] += 1
    k = reach // cell

    def square(cy, cx):
        part = counts[max(cy - k, 0) : cy + k + 1, max(cx - k, 0) : cx + k + 1]
        return part.sum(), part.size

    density = np.median(
        [n / a for n, a in (square(cy, cx) for cy in range(gh) for cx in range(gw))]
    )
    out = np.zeros(events.size, bool)
    for i in np.flatnonzero(isolated):
        n, a = square(int(events["y"][i]) // cell, int(events["x"][i]) // cell)
        lam = density * a
        out[i] = n - 1 - lam > z * np.sqrt(lam + 1)
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_crowded_isolated_equals_the_definition_by_loops(seed):
    rng = np.random.default_rng(seed)
    size = (203, 131)
    # an even spread plus a cluster, some events not judged
    n_even, n_cluster = 120, 60
    x = np.concatenate([rng.integers(0, size[0], n_even), rng.normal(150, 12, n_cluster)])
    y = np.concatenate([rng.integers(0, size[1], n_even), rng.normal(40, 10, n_cluster)])
    x = np.clip(np.rint(x), 0, size[0] - 1).astype(int)
    y = np.clip(np.rint(y), 0, size[1] - 1).astype(int)
    ev = make_events(np.arange(x.size), x, y, np.ones(x.size))
    judged = rng.random(x.size) < 0.8
    for z, cell, reach in ((3.0, 16, 128), (0.0, 8, 24), (2.0, 5, 0)):
        got = crowded_isolated(ev, size, judged, z=z, cell=cell, reach=reach)
        np.testing.assert_array_equal(got, _crowded_by_loops(ev, size, judged, z, cell, reach))
        assert not got[~judged].any()
    # at the default reach (a sixth of 131: 21 px) most of the cluster crowds
    assert scatter_reach(size) == 21
    assert crowded_isolated(ev, size, judged, z=3.0)[n_even:][judged[n_even:]].mean() > 0.5


def test_an_even_spread_never_crowds_and_a_cluster_in_it_does():
    assert (SCATTER_CELL, SCATTER_REACH, scatter_reach((640, 480))) == (16, 1 / 6, 80)
    size = (640, 480)
    gy, gx = np.mgrid[0:12, 0:16] * 40 + 20  # one isolated event per 40 px
    even = make_events(np.arange(gx.size), gx.ravel(), gy.ravel(), np.ones(gx.size))
    assert not crowded_isolated(even, size, np.ones(even.size, bool), z=3.0).any()
    # a ring of 24 events of radius 30 around (320, 240), 8 px apart: scattered light
    angle = np.arange(24) * 2 * np.pi / 24
    rx, ry = np.rint(320 + 30 * np.cos(angle)), np.rint(240 + 30 * np.sin(angle))
    ring = make_events(np.arange(24), rx.astype(int), ry.astype(int), np.zeros(24))
    both = np.concatenate([even, ring])
    hit = crowded_isolated(both, size, np.ones(both.size, bool), z=3.0)
    assert hit[even.size :].all()
    # of the even events only those whose 11x11-cell square (80 px) holds the ring crowd
    near = (np.abs(gx.ravel() // 16 - 320 // 16) <= 10) & (
        np.abs(gy.ravel() // 16 - 240 // 16) <= 10
    )
    assert not hit[: even.size][~near].any()
    # z: the higher, the fewer; none judged, or one alone, none crowd
    assert crowded_isolated(both, size, np.ones(both.size, bool), z=1e6).sum() == 0
    assert not crowded_isolated(both, size, np.zeros(both.size, bool), z=0.0).any()
    one = np.zeros(both.size, bool)
    one[-1] = True
    assert not crowded_isolated(both, size, one, z=0.0).any()


def test_crowded_isolated_rejects_bad_arguments():
    ev = make_events([0, 1], [1, 2], [1, 2], [1, 1])
    with pytest.raises(ValueError, match="one bool per event"):
        crowded_isolated(ev, (8, 8), np.ones(3, bool), z=3.0)
    for z in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="z must be >= 0"):
            crowded_isolated(ev, (8, 8), np.ones(2, bool), z=z)
    with pytest.raises(ValueError, match="cell >= 1"):
        crowded_isolated(ev, (8, 8), np.ones(2, bool), z=3.0, cell=0)


def test_the_light_free_shift_reaches_the_isolated_events_that_do_not_crowd():
    weights = bundled_weights()
    size = (640, 480)
    # no light: a 3x3 patch (supported), isolated events one per 40 px over the sensor
    # (background activity) and a ring of 24 isolated ones 8 px apart (scattered light)
    px, py = np.mgrid[200:203, 100:103]
    gy, gx = np.mgrid[0:12, 0:16] * 40 + 20
    angle = np.arange(24) * 2 * np.pi / 24
    rx = np.rint(320 + 30 * np.cos(angle)).astype(int)
    ry = np.rint(240 + 30 * np.sin(angle)).astype(int)
    x = np.concatenate([px.ravel(), gx.ravel(), rx])
    y = np.concatenate([py.ravel(), gy.ravel(), ry])
    ev = make_events(np.arange(x.size) * 50, x, y, np.arange(x.size) % 2)
    order = np.argsort(ev["t"], kind="stable")
    assert (order == np.arange(ev.size)).all()
    support = event_support(ev, size)
    assert (support[:9] == 8).all() and (support[9:] < 2).all()
    patch, ring = slice(0, 9), slice(9 + gx.size, None)
    near = (np.abs(gx.ravel() // 16 - 20) <= 7) & (np.abs(gy.ravel() // 16 - 15) <= 7)
    far = np.zeros(ev.size, bool)
    far[9 : 9 + gx.size] = ~near  # even events whose square misses the ring
    plain = ModelDeflarer(weights, light_free_shift=0.0, scatter_shift=0.0)
    base = plain.window_logits([(0, ev)], size)[0]

    def delta(crowding):
        d = ModelDeflarer(
            weights,
            light_free_shift=2.0,
            light_free_support=2,
            light_free_crowding=crowding,
            scatter_shift=0.0,
        )
        return d.window_logits([(0, ev)], size)[0] - base

    off, on = delta(0.0), delta(3.0)
    np.testing.assert_allclose(off[patch], 2.0, atol=1e-9)
    np.testing.assert_allclose(off[9:], 0.0, atol=1e-9)  # crowding 0: no isolated event
    np.testing.assert_allclose(on[patch], 2.0, atol=1e-9)
    np.testing.assert_allclose(on[far], 2.0, atol=1e-9)  # background activity: raised
    np.testing.assert_allclose(on[ring], 0.0, atol=1e-9)  # scattered light: left alone
    for bad in (-1.0, float("inf"), True):
        with pytest.raises(ParameterError, match="light_free_crowding"):
            ModelDeflarer(weights, light_free_crowding=bad)
    assert ModelDeflarer(weights).rules["light_free_crowding"] == 3.0


def _field_by_loops(events, size, crowded, cell, reach, span_us):
    """scatter_field's definition, one event at a time."""
    k = reach // cell
    gw, gh = -(-size[0] // cell), -(-size[1] // cell)
    cy, cx = events["y"].astype(int) // cell, events["x"].astype(int) // cell
    out = np.zeros(events.size, bool)
    for i in range(events.size):
        near = (np.abs(cy - cy[i]) <= k) & (np.abs(cx - cx[i]) <= k)
        mine = (near & crowded).sum()
        cells_y = min(cy[i] + k, gh - 1) - max(cy[i] - k, 0) + 1
        cells_x = min(cx[i] + k, gw - 1) - max(cx[i] - k, 0) + 1
        rate = near.sum() / (cells_y * cells_x * cell**2) / (span_us * 1e-6)
        out[i] = (
            mine >= FIELD_MIN_EVENTS and mine >= FIELD_MIN_SHARE * near.sum()
            and rate <= FIELD_MAX_RATE
        )  # fmt: skip
    return out


def _slow_lamp_window():
    """A light-free 640x480 window: a dense 6x6 lamp, a line of events 2 px apart beside
    it (its bloom), 30 isolated events on a ring of radius 50 around it (its scattered
    light) and 48 isolated events one per 80 px over the sensor (background activity)."""
    ly, lx = np.mgrid[200:206, 300:306]
    bx = np.arange(320, 342, 2)
    angle = np.arange(30) * 2 * np.pi / 30
    rx = np.rint(303 + 50 * np.cos(angle)).astype(int)
    ry = np.rint(203 + 50 * np.sin(angle)).astype(int)
    gy, gx = np.mgrid[0:6, 0:8] * 80 + 40
    x = np.concatenate([lx.ravel(), bx, rx, gx.ravel()])
    y = np.concatenate([ly.ravel(), np.full(bx.size, 230), ry, gy.ravel()])
    parts = {"lamp": slice(0, 36), "bloom": slice(36, 47), "ring": slice(47, 77)}
    parts["even"] = slice(77, 125)
    return make_events(np.arange(x.size) * 100, x, y, np.arange(x.size) % 2), parts


def test_scatter_field_equals_the_definition_by_loops():
    ev, parts = _slow_lamp_window()
    size = (640, 480)
    isolated = event_support(ev, size) < 2
    crowded = crowded_isolated(ev, size, isolated, z=3.0)
    assert crowded[parts["ring"]].all() and not crowded[parts["lamp"]].any()
    for cell, reach, span in ((16, 80, 20_000), (8, 40, 20_000), (16, 0, 20_000), (8, 40, 300)):
        np.testing.assert_array_equal(
            scatter_field(ev, size, crowded, cell=cell, reach=reach, span_us=span),
            _field_by_loops(ev, size, crowded, cell, reach, span),
        )
    field = scatter_field(ev, size, crowded)  # over the events' own 12.4 ms
    assert field[parts["lamp"]].all() and field[parts["ring"]].all()
    assert field[parts["bloom"]].all()
    far = _far_from(ev[parts["even"]], 303, 203)
    assert far.sum() >= 25 and not field[parts["even"]][far].any()
    with pytest.raises(ValueError, match="crowded must hold one bool per event"):
        scatter_field(ev, size, crowded[:-1])
    with pytest.raises(ValueError, match="span_us must be >= 1"):
        scatter_field(ev, size, crowded, span_us=0)


def test_a_scattered_light_field_is_dark():
    # the lamp's square (11x11 cells of 16 px: 30,976 px) holds its 36 events, the
    # bloom's 11, the ring's 30 and 6 of the even spread: 83 events, at most
    # FIELD_MAX_RATE per pixel and second from 83 / (rate * 30976) on (535.9 us at 5);
    # in less time they are a lit texture's, not scattered light
    edge = 83 / (FIELD_MAX_RATE * 1e-6 * 30_976)
    ev, parts = _slow_lamp_window()
    size = (640, 480)
    crowded = crowded_isolated(ev, size, event_support(ev, size) < 2, z=3.0)
    lamp = parts["lamp"]
    assert scatter_field(ev, size, crowded, span_us=math.ceil(edge))[lamp].all()
    assert not scatter_field(ev, size, crowded, span_us=math.floor(edge))[lamp].any()


def _far_from(events, x, y):
    """Events whose 11x11-cell square (80 px at 16 px cells) misses every cell of the
    lamp, bloom and ring (all within 55 px of (x, y))."""
    cx, cy = events["x"].astype(int) // 16, events["y"].astype(int) // 16
    return (np.abs(cx - x // 16) > 9) | (np.abs(cy - y // 16) > 9)


def test_light_free_shifts_raise_the_lamp_and_lower_its_scattered_light():
    ev, parts = _slow_lamp_window()
    size = (640, 480)
    support = event_support(ev, size)
    assert (support[parts["lamp"]] >= SOURCE_SUPPORT).all()
    bloom = support[parts["bloom"]]
    assert bloom.tolist() == [1] + [2] * 9 + [1]  # 2 px apart: the ends have one
    assert (support[parts["ring"]] < 2).all() and (support[parts["even"]] == 0).all()

    def shifts(**kw):
        return light_free_shifts(ev, size, support, shift=4.0, **kw)

    np.testing.assert_array_equal(shifts(), 4.0)  # no gate: every event
    gated = shifts(gate=2)
    np.testing.assert_array_equal(gated, 4.0 * (support >= 2))
    crowding = shifts(gate=2, crowding=3.0)
    np.testing.assert_array_equal(crowding[parts["ring"]], 0.0)
    far = _far_from(ev[parts["even"]], 303, 203)
    np.testing.assert_array_equal(crowding[parts["even"]][far], 4.0)  # background activity
    scatter = shifts(gate=2, crowding=3.0, scatter_shift=4.0)
    np.testing.assert_array_equal(scatter[parts["lamp"]], 8.0)  # the lamp: 4 + 4
    # the bloom, sparse and in the field: no shift; its two ends are isolated and crowd
    np.testing.assert_array_equal(scatter[parts["bloom"]], [-4.0] + [0.0] * 9 + [-4.0])
    np.testing.assert_array_equal(scatter[parts["ring"]], -4.0)  # its scattered light
    np.testing.assert_array_equal(scatter[parts["even"]][far], 4.0)
    # without crowding there is no field: the scatter shift does nothing
    np.testing.assert_array_equal(shifts(gate=2, scatter_shift=4.0), gated)
    # the same events within 100 us: every square near the lamp holds its 36 events and
    # more, over the 15.5 that 5 per pixel and second allow there. A lit texture's
    # crowding is its own: the crowded isolated events rise too, and there is no field
    lit = shifts(gate=2, crowding=3.0, scatter_shift=4.0, span_us=100)
    for part in ("lamp", "bloom", "ring"):
        np.testing.assert_array_equal(lit[parts[part]], 4.0)
    np.testing.assert_array_equal(lit[parts["even"]][far], 4.0)
    with pytest.raises(ValueError, match="support must hold one count per event"):
        light_free_shifts(ev, size, support[:3], shift=4.0, gate=2)
    for bad in ({"crowding": -1.0}, {"crowding": 3.0, "scatter_shift": float("nan")}):
        with pytest.raises(ValueError, match="crowding and scatter_shift must be >= 0"):
            light_free_shifts(ev, size, support, shift=4.0, gate=2, **bad)


def test_the_model_adds_the_light_free_shifts_in_a_window_without_a_light():
    weights = bundled_weights()
    ev, _ = _slow_lamp_window()
    size = (640, 480)
    base = ModelDeflarer(weights, light_free_shift=0.0, scatter_shift=0.0)
    base_logits = base.window_logits([(0, ev)], size)[0]
    d = ModelDeflarer(
        weights, light_free_shift=4.0, light_free_support=2, light_free_crowding=3.0,
        scatter_shift=4.0,
    )  # fmt: skip
    expected = light_free_shifts(
        ev, size, event_support(ev, size), shift=4.0, gate=2, crowding=3.0, scatter_shift=4.0,
        span_us=covered_us(ev, 0, 20_000),
    )  # fmt: skip
    np.testing.assert_allclose(d.window_logits([(0, ev)], size)[0] - base_logits, expected)
    for bad in (-1.0, float("nan"), "4"):
        with pytest.raises(ParameterError, match="scatter_shift"):
            ModelDeflarer(weights, scatter_shift=bad)
    assert ModelDeflarer(weights).rules["scatter_shift"] == 4.0
