"""Paired voxel windows: alignment, exact grids, seeded crops and flips."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import random_events
from edeflare.data.pairs import PairedWindows, sequence_windows
from edeflare.errors import EventFileError
from edeflare.io.dsec import write_dsec_groups
from edeflare.io.sequence import list_sequences
from edeflare.voxel import encode


def _sequence(path, rng, size=(16, 12), t0=1_000_000, span=60_000, attrs=None):
    inp = random_events(rng, 400, size, t0=t0, span_us=span)
    gt = inp[rng.random(inp.size) < 0.5]
    write_dsec_groups(path, {"input": inp, "gt": gt}, size, attrs)
    return inp, gt


def test_windows_are_aligned_and_grids_exact(tmp_path, rng):
    inp, gt = _sequence(tmp_path / "a.h5", rng, t0=1_005_000)
    ds = PairedWindows([tmp_path / "a.h5"])
    starts = [w.start_us for w in ds.windows]
    assert starts[0] == 1_000_000 and np.all(np.diff(starts) == 20_000)
    assert starts[-1] <= int(inp["t"][-1]) < starts[-1] + 20_000
    x, y = ds[1]
    sel = (inp["t"] >= 1_020_000) & (inp["t"] < 1_040_000)
    np.testing.assert_array_equal(x[0], encode(inp[sel], (16, 12), 1_020_000, 20_000))
    sel = (gt["t"] >= 1_020_000) & (gt["t"] < 1_040_000)
    np.testing.assert_array_equal(y[0], encode(gt[sel], (16, 12), 1_020_000, 20_000))


def test_span_attributes_define_the_windows(tmp_path, rng):
    span = {"t_start_us": 0, "t_end_us": 100_000}
    _sequence(tmp_path / "a.h5", rng, t0=0, span=30_000, attrs=span)
    refs, size = sequence_windows([tmp_path / "a.h5"])
    assert [r.start_us for r in refs] == [0, 20_000, 40_000, 60_000, 80_000] and size == (16, 12)


def test_crops_and_flips_are_seeded_and_paired(tmp_path, rng):
    _sequence(tmp_path / "a.h5", rng)
    ds = PairedWindows([tmp_path / "a.h5"], crop=(8, 8), flip=True, seed=3)
    full_x, full_y = ds.grids(0)
    x, y = ds.item(0, epoch=0)
    assert x.shape == (1, 8, 8, 8)
    again = ds.item(0, epoch=0)
    assert np.array_equal(again[0], x) and np.array_equal(again[1], y)
    # input and target are cut and flipped identically: find the crop in the full grid
    found = False
    for flip_h in (False, True):
        for flip_v in (False, True):
            fx, fy = full_x, full_y
            if flip_h:
                fx, fy = fx[:, :, ::-1], fy[:, :, ::-1]
            if flip_v:
                fx, fy = fx[:, ::-1, :], fy[:, ::-1, :]
            for top in range(12 - 8 + 1):
                for left in range(16 - 8 + 1):
                    if np.array_equal(
                        fx[:, top : top + 8, left : left + 8], x[0]
                    ) and np.array_equal(fy[:, top : top + 8, left : left + 8], y[0]):
                        found = True
    assert found
    draws = {ds.item(0, epoch=e)[0].tobytes() for e in range(8)}
    assert len(draws) > 1  # epochs draw different crops


def test_bad_datasets(tmp_path, rng):
    with pytest.raises(EventFileError, match="no such dataset folder"):
        list_sequences(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(EventFileError, match="no sequence files"):
        list_sequences(tmp_path / "empty")
    _sequence(tmp_path / "a.h5", rng, size=(16, 12))
    _sequence(tmp_path / "b.h5", rng, size=(20, 12))
    with pytest.raises(EventFileError, match=r"sensor size \(20, 12\) differs from \(16, 12\)"):
        sequence_windows([tmp_path / "a.h5", tmp_path / "b.h5"])
    with pytest.raises(ValueError, match="exceeds the sensor 16x12"):
        PairedWindows([tmp_path / "a.h5"], crop=(13, 8))
    with pytest.raises(ValueError, match="exceeds the smallest of the sensors' 16x12"):
        PairedWindows([tmp_path / "a.h5", tmp_path / "b.h5"], crop=(8, 17))


def test_sequences_of_several_sensor_sizes(tmp_path, rng):
    _sequence(tmp_path / "a.h5", rng, size=(16, 12))
    b, _ = _sequence(tmp_path / "b.h5", rng, size=(20, 10))
    ds = PairedWindows([tmp_path / "a.h5", tmp_path / "b.h5"], crop=(8, 8))
    assert ds.sizes == [(16, 12), (20, 10)] and ds.sensor_size == (16, 10)
    n_a = sum(w.path.name == "a.h5" for w in ds.windows)
    # each window is encoded on its own sensor, then cropped to one shape
    assert ds.grids(0)[0].shape == (8, 12, 16) and ds.grids(n_a)[0].shape == (8, 10, 20)
    sel = (b["t"] >= ds.windows[n_a].start_us) & (b["t"] < ds.windows[n_a].start_us + 20_000)
    np.testing.assert_array_equal(
        ds.grids(n_a)[0], encode(b[sel], (20, 10), ds.windows[n_a].start_us, 20_000)
    )
    assert {ds.item(i, 0)[0].shape for i in range(len(ds))} == {(1, 8, 8, 8)}
    cached = PairedWindows([tmp_path / "a.h5", tmp_path / "b.h5"], crop=(8, 8), precompute=True)
    for i in range(len(ds)):
        np.testing.assert_array_equal(cached.item(i, 2)[0], ds.item(i, 2)[0])


def test_polarity_flip_swaps_on_and_off_of_both_grids_in_half_the_windows(tmp_path, rng):
    inp, _gt = _sequence(tmp_path / "a.h5", rng)
    plain = PairedWindows([tmp_path / "a.h5"], crop=(8, 8), flip=True, seed=3)
    ds = PairedWindows([tmp_path / "a.h5"], crop=(8, 8), flip=True, seed=3, polarity_flip=True)
    seen = []
    for epoch in range(16):
        x, y = ds.item(1, epoch)
        px, py = plain.item(1, epoch)  # the crop and flips are the plain dataset's draws
        rng_e = np.random.default_rng((3, epoch, 1))
        rng_e.integers(0, 5), rng_e.integers(0, 5), rng_e.random(), rng_e.random()
        negate = rng_e.random() < 0.5
        seen.append(negate)
        sign = -1 if negate else 1
        np.testing.assert_array_equal(x, sign * px)
        np.testing.assert_array_equal(y, sign * py)
        assert np.abs(px).sum() > 0 and x.dtype == np.float32
    assert any(seen) and not all(seen)
    # by hand: a flipped window is the encoding of the events with ON and OFF swapped
    full = PairedWindows([tmp_path / "a.h5"], polarity_flip=True, seed=3)
    # no crop, flips or shift: the negation is the first draw
    epoch = next(e for e in range(16) if np.random.default_rng((3, e, 1)).random() < 0.5)
    swapped = inp.copy()
    swapped["p"] = 1 - swapped["p"]
    sel = (swapped["t"] >= 1_020_000) & (swapped["t"] < 1_040_000)
    want = encode(swapped[sel], (16, 12), 1_020_000, 20_000)
    np.testing.assert_array_equal(full.item(1, epoch)[0][0], want)
    assert not np.array_equal(want, plain.grids(1)[0])


def test_precomputed_grids_equal_on_the_fly(tmp_path, rng):
    _sequence(tmp_path / "a.h5", rng)
    _sequence(tmp_path / "b.h5", rng)
    lazy = PairedWindows([tmp_path / "a.h5", tmp_path / "b.h5"], crop=(8, 8), flip=True)
    cached = PairedWindows(
        [tmp_path / "a.h5", tmp_path / "b.h5"], crop=(8, 8), flip=True, precompute=True
    )
    assert cached._cache is not None and cached._cache[0].dtype == np.int16
    for i in range(len(lazy)):
        for a, b in zip(lazy.item(i, 3), cached.item(i, 3), strict=True):
            np.testing.assert_array_equal(a, b)
            assert b.dtype == np.float32


def test_time_shift_is_the_window_started_whole_bins_later(tmp_path, rng):
    # windows of 20 ms, 8 bins of 2.5 ms: a shift of s bins is the window at start + 2.5 s ms
    inp, gt = _sequence(tmp_path / "a.h5", rng, t0=1_000_000, span=60_000)
    _sequence(tmp_path / "b.h5", rng, t0=1_000_000, span=30_000)
    plain = PairedWindows([tmp_path / "a.h5", tmp_path / "b.h5"], flip=True, seed=5)
    ds = PairedWindows([tmp_path / "a.h5", tmp_path / "b.h5"], flip=True, seed=5, time_shift=True)
    # a: windows 0, 1, 2 (0 and 1 continued by the next); b: windows 3, 4 (3 continued)
    assert ds._next.tolist() == [1, 2, -1, 4, -1]
    shifts = set()
    for epoch in range(12):
        x, y = ds.item(0, epoch)
        rng_e = np.random.default_rng((5, epoch, 0))
        flip_h, flip_v = rng_e.random() < 0.5, rng_e.random() < 0.5
        s = int(rng_e.integers(0, 8))
        shifts.add(s)
        start = 1_000_000 + s * 2_500
        want = []
        for ev in (inp, gt):
            sel = (ev["t"] >= start) & (ev["t"] < start + 20_000)
            g = encode(ev[sel], (16, 12), start, 20_000)
            g = g[:, :, ::-1] if flip_h else g
            want.append(g[:, ::-1, :] if flip_v else g)
        np.testing.assert_array_equal(x[0], want[0])
        np.testing.assert_array_equal(y[0], want[1])
        # the draws before the shift are the plain dataset's: the same flips
        if s == 0:
            np.testing.assert_array_equal(x, plain.item(0, epoch)[0])
    assert len(shifts) > 3
    # a sequence's last window is never shifted
    for epoch in range(6):
        np.testing.assert_array_equal(ds.item(2, epoch)[0], plain.item(2, epoch)[0])
