"""Sparse sensing: survival rates, the glow, the restored source, background activity, recipes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import same_events
from edeflare.data.generate import generate_sequence, write_sequence
from edeflare.data.recipe import RECIPES, FlareConfig, Recipe
from edeflare.errors import ParameterError
from edeflare.events import EVENT_DTYPE, make_events
from edeflare.io.dsec import read_dsec
from edeflare.sim.background import SceneConfig
from edeflare.sim.flare import GhostSpec
from edeflare.sim.sensing import SensingConfig, in_ghosts, sparse_sensing

SIZE = (200, 150)
CX, CY = 100, 75


def _events(t, x, y, p) -> np.ndarray:
    order = np.argsort(t, kind="stable")
    return make_events(np.asarray(t)[order], np.asarray(x)[order], np.asarray(y)[order],
                       np.asarray(p)[order])  # fmt: skip


def _sequence(rng: np.random.Generator, n_flare: int = 40_000):
    """A 9x9 source at the centre (one event per pixel per ms for 20 ms), flare events
    uniform over the sensor, a scene of 500 events; the input lacks the source's core."""
    xs, ys = np.meshgrid(np.arange(CX - 4, CX + 5), np.arange(CY - 4, CY + 5))
    ts = np.repeat(np.arange(20) * 1000, xs.size)
    light = _events(ts, np.tile(xs.ravel(), 20), np.tile(ys.ravel(), 20), np.ones(ts.size, int))
    flare = _events(rng.integers(0, 20_000, n_flare), rng.integers(0, SIZE[0], n_flare),
                    rng.integers(0, SIZE[1], n_flare), rng.integers(0, 2, n_flare))  # fmt: skip
    flare = np.unique(flare)  # one event per (t, x, y, p)
    gt = _events(rng.integers(0, 20_000, 500), rng.integers(0, 40, 500),
                 rng.integers(0, 40, 500), rng.integers(0, 2, 500))  # fmt: skip
    lx, ly = light["x"].astype(int), light["y"].astype(int)
    core = (np.abs(lx - CX) <= 1) & (np.abs(ly - CY) <= 1)  # clipped: a hole
    inp = np.concatenate([gt, flare, light[~core]])
    inp = inp[np.argsort(inp["t"], kind="stable")]
    return {"input": inp, "gt": gt, "flare": flare, "light": light}


def _far(ev: np.ndarray, lo: float, hi: float) -> np.ndarray:
    d = np.hypot(ev["x"].astype(float) - CX, ev["y"].astype(float) - CY)
    return (d > lo) & (d <= hi)


def _member(ev: np.ndarray, of: np.ndarray) -> np.ndarray:
    return np.isin(ev.view(np.void), of.view(np.void)) if ev.size else np.zeros(0, bool)


def test_far_flare_survives_at_the_drawn_rate_and_the_rest_is_kept(rng):
    streams = _sequence(rng)
    cfg = SensingConfig(survival=(0.1, 0.1), falloff=0.0, noise_rate=(0.0, 0.0))
    out = sparse_sensing(streams, SIZE, 0, cfg, rng=1)
    flare = streams["flare"]
    far = flare[_far(flare, 10, np.inf)]
    far = far[~_member(far, streams["gt"])]  # (an event of both is a true event)
    survived = _member(far, out["input"]).mean()
    assert survived == pytest.approx(0.1, abs=0.01)  # about 30,000 far flare events
    assert _member(streams["gt"], out["input"]).all() and _member(streams["gt"], out["gt"]).all()
    assert _member(streams["light"], out["input"]).all()  # the clipped core is back
    assert _member(streams["light"], out["gt"]).all()
    glow = flare[_far(flare, 0, 6.3)]  # within 2 px of the 9x9 source (its corner: 5.66 + ...)
    gx, gy = glow["x"].astype(int), glow["y"].astype(int)
    glow = glow[(np.abs(gx - CX) <= 6) & (np.abs(gy - CY) <= 6)]
    assert _member(glow, out["input"]).all() and _member(glow, out["gt"]).all()
    assert _member(out["gt"], out["input"]).all()  # keep-only: a subset of the input
    assert not _member(far, out["gt"]).any()  # flare to remove is never a target
    np.testing.assert_array_equal(out["gt_full"], streams["gt"])
    assert np.all(np.diff(out["input"]["t"]) >= 0)


def test_survival_falls_with_distance_beyond_two_radii(rng):
    streams = _sequence(rng, n_flare=200_000)
    cfg = SensingConfig(survival=(0.5, 0.5), falloff=2.0, noise_rate=(0.0, 0.0))
    out = sparse_sensing(streams, SIZE, 0, cfg, rng=2)
    r = np.sqrt(81 / np.pi)  # the disc of the 9x9 source's pixels
    flare = streams["flare"]
    for lo, hi in ((3 * r, 3.5 * r), (8 * r, 9 * r)):
        ring = flare[_far(flare, lo, hi)]
        d = np.hypot(ring["x"].astype(float) - CX, ring["y"].astype(float) - CY)
        expected = np.mean(0.5 * np.minimum(1, (2 * r / d) ** 2))
        assert _member(ring, out["input"]).mean() == pytest.approx(expected, rel=0.15)


def test_background_activity_joins_input_and_target_at_its_rate(rng):
    streams = _sequence(rng, n_flare=10)
    cfg = SensingConfig(survival=(1.0, 1.0), noise_rate=(5.0, 5.0))
    out = sparse_sensing(streams, SIZE, 0, cfg, rng=3, t_end_us=100_000)
    new = out["input"][~_member(out["input"], streams["input"])]
    new = new[~_member(new, streams["light"])]  # the added background activity
    assert new.size == pytest.approx(5.0 * SIZE[0] * SIZE[1] * 0.1, rel=0.05)
    assert _member(new, out["gt"]).all()  # all of it to keep
    assert out["input"]["t"].max() < 100_000


def test_same_seed_same_output_and_bad_configs_are_refused(rng):
    streams = _sequence(rng, n_flare=1000)
    a = sparse_sensing(streams, SIZE, 0, SensingConfig(), rng=(4, 5))
    b = sparse_sensing(streams, SIZE, 0, SensingConfig(), rng=(4, 5))
    assert all(np.array_equal(a[k], b[k]) for k in a)
    for bad in ({"survival": (0.0, 0.1)}, {"noise_rate": (0.0, 3.0)}, {"near_px": -1},
                {"falloff": float("nan")}, {"step_us": 0}):  # fmt: skip
        with pytest.raises(ParameterError):
            SensingConfig(**bad)
    with pytest.raises(ParameterError, match="unknown sensing key"):
        SensingConfig.from_dict({"survivl": 0.1})
    with pytest.raises(ParameterError, match=r"needs the streams \['flare'\]"):
        sparse_sensing({k: v for k, v in streams.items() if k != "flare"}, SIZE, 0,
                       SensingConfig(), rng=0)  # fmt: skip


def test_a_sensing_recipe_writes_a_keep_only_target_and_the_full_one(tmp_path):
    recipe = Recipe(name="tiny-night", sequences=1, test_sequences=0, sensor_size=(64, 48),
                    duration_us=20_000, scene=SceneConfig(fps=1000.0),
                    config=FlareConfig(sensing=SensingConfig(enabled=True)))  # fmt: skip
    assert Recipe.from_dict(recipe.to_dict()) == recipe
    data = generate_sequence(recipe, 0)
    inp, gt = data.streams["input"], data.streams["gt"]
    assert gt.size <= inp.size and _member(gt, inp).all()
    write_sequence(tmp_path / "s.h5", data, recipe)
    np.testing.assert_array_equal(read_dsec(tmp_path / "s.h5", "gt_full")[0],
                                  data.streams["gt_full"])  # fmt: skip
    assert RECIPES["eflare-night"].config.sensing.enabled
    assert "sensing" not in RECIPES["eflare-mini"].to_dict()  # old digests unchanged
    assert EVENT_DTYPE == inp.dtype


def test_hot_pixels_join_the_input_not_the_target_and_are_off_by_default(rng):
    streams = _sequence(rng, n_flare=100)
    base = SensingConfig(survival=(1.0, 1.0), noise_rate=(0.0, 0.0))
    plain = sparse_sensing(streams, SIZE, 0, base, rng=4, t_end_us=100_000)
    cfg = SensingConfig(survival=(1.0, 1.0), noise_rate=(0.0, 0.0), hot_pixels=(3, 3),
                        hot_rate=(20_000.0, 20_000.0))  # fmt: skip
    out = sparse_sensing(streams, SIZE, 0, cfg, rng=4, t_end_us=100_000)
    extra = out["input"][~_member(out["input"], plain["input"])]
    pix = extra["y"].astype(np.int64) * SIZE[0] + extra["x"]
    counts = np.bincount(np.unique(pix, return_inverse=True)[1])
    assert counts.size == 3  # three pixels
    assert np.all(np.abs(counts - 2000) < 5 * np.sqrt(2000))  # 20 k/s for 100 ms, Poisson
    for p in np.unique(pix):  # each almost all one polarity
        share = extra["p"][pix == p].mean()
        assert share > 0.9 or share < 0.1
    assert not _member(extra, out["gt"]).any()  # to remove: not in the target
    assert same_events(out["gt"], plain["gt"])
    assert "hot_pixels" not in base.to_dict() and cfg.to_dict()["hot_pixels"] == [3, 3]
    with pytest.raises(ParameterError, match="hot_pixels must satisfy"):
        SensingConfig(hot_pixels=(4, 2))


def test_ghost_events_survive_at_their_own_rate_wherever_they_lie(rng):
    """A 9x9 source at (40, 40) of the 200x150 sensor; its ghost k = -1 (radius 10)
    mirrors it through the centre (99.5, 74.5) to (159, 109), 135 px away, where
    scattered light's survival ``q (2 r / d) ** 2`` is below 1e-3 of ``q``."""
    xs, ys = np.meshgrid(np.arange(36, 45), np.arange(36, 45))
    ts = np.repeat(np.arange(20) * 1000, xs.size)
    light = _events(ts, np.tile(xs.ravel(), 20), np.tile(ys.ravel(), 20), np.ones(ts.size, int))
    n = 60_000
    flare = np.unique(_events(rng.integers(0, 20_000, n), rng.integers(0, SIZE[0], n),
                              rng.integers(0, SIZE[1], n), rng.integers(0, 2, n)))  # fmt: skip
    inp = np.concatenate([flare, light])
    streams = {"input": inp[np.argsort(inp["t"], kind="stable")], "gt": light[:0],
               "flare": flare, "light": light}  # fmt: skip
    ghost = GhostSpec(k=-1.0, radius_px=10.0, level=5.0, softness=0.1, fringe=0.0)
    d_ghost = np.hypot(flare["x"] - 159.0, flare["y"] - 109.0)
    inside, outside = flare[d_ghost <= 10.0], flare[(d_ghost > 13.0) & _far(flare, 100, np.inf)]
    assert inside.size > 400 and outside.size > 5000
    base = SensingConfig(survival=(0.5, 0.5), noise_rate=(0.0, 0.0))
    cfg = dataclasses.replace(base, ghost_survival=(0.3, 0.3))
    for config, expected in ((base, 0.0), (cfg, 0.3)):
        out = sparse_sensing(streams, SIZE, 0, config, rng=2, ghosts=[ghost])
        share = _member(inside, out["input"]).mean()
        assert abs(share - expected) < 0.06, (config.ghost_survival, share)
        assert _member(outside, out["input"]).mean() < 0.03  # scattered light, far: thinned
        assert not _member(inside, out["gt"]).any()  # ghost events are flare: to remove
    # without the ghosts given, or off (the default, absent from the recipe's dict)
    same = sparse_sensing(streams, SIZE, 0, cfg, rng=2)
    assert _member(inside, same["input"]).mean() < 0.01
    assert "ghost_survival" not in base.to_dict() and cfg.to_dict()["ghost_survival"] == [0.3, 0.3]
    with pytest.raises(ParameterError, match="ghost_survival must be"):
        SensingConfig(ghost_survival=(0.0, 0.2))


def test_in_ghosts_follows_the_moving_source_through_the_centre():
    ghost = GhostSpec(k=-2.0, radius_px=3.0, level=1.0, softness=0.01, fringe=0.0)
    # the source moves from (60, 40) to (80, 40) over 10 ms on a 101x81 sensor (centre
    # (50, 40)): its ghost from (30, 40) to (-10, 40), at (10, 40) halfway
    track = (np.array([0.0, 10_000.0]), np.array([60.0, 80.0]), np.array([40.0, 40.0]))
    ev = make_events([0, 5_000, 5_000, 10_000], [30, 10, 30, 0], [40, 40, 40, 40], [1, 1, 1, 1])
    assert in_ghosts(ev, track, [ghost], (101, 81)).tolist() == [True, True, False, False]
    assert not in_ghosts(ev, track, [], (101, 81)).any()
