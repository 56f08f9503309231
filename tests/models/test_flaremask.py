"""The mask presets: the per-event decision equals the dense gate it is trained through."""

import numpy as np
import pytest
import torch

from edeflare.events import make_events
from edeflare.models import create_model
from edeflare.models import mask_kernels as fm
from edeflare.models.flaremask import FlareMaskNet
from edeflare.models.mask_kernels import event_features, event_keep_mask
from edeflare.voxel import encode


def _events(n, size, seed):
    rng = np.random.default_rng(seed)
    w, h = size
    # distinct pixels, so no cell holds cancelling ON/OFF events (the documented condition)
    pix = rng.choice(w * h, n, replace=False)
    t = np.sort(rng.integers(0, 20_000, n))
    return make_events(t, pix % w, pix // w, rng.integers(0, 2, n))


@pytest.mark.parametrize("scale", [4, 8])
def test_event_features_equal_the_networks_features(scale):
    size = (37, 29)
    ev = _events(300, size, 1)
    net = FlareMaskNet(bins=8, scale=scale, features=(8, 16), groups=4)
    grid = torch.from_numpy(encode(ev, size, 0, 20_000, 8))[None, None]
    expected = net.features(grid)[0].numpy()
    got = event_features(ev, size, 0, 20_000, 8, scale)
    np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-6)


def test_per_event_decision_equals_the_dense_gate():
    torch.manual_seed(0)
    size = (45, 31)
    net = FlareMaskNet(bins=8, scale=4, features=(8, 16), groups=4).eval()
    torch.nn.init.normal_(net.final.weight, std=2.0)  # a non-trivial mask
    ev = _events(500, size, 2)
    grid = torch.from_numpy(encode(ev, size, 0, 20_000, 8))[None, None]
    with torch.no_grad():
        dense = net(grid)[0, 0].numpy()
        logits = net.logits(net.features(grid))[0].numpy()
    keep = event_keep_mask(logits, ev, 0, 20_000, 4)
    b = ev["t"] * 8 // 20_000
    gate = np.abs(dense[b, ev["y"], ev["x"]])  # one event per cell: the gate itself
    assert 0 < keep.sum() < ev.size  # the mask really drops some and keeps some
    np.testing.assert_array_equal(keep, gate > 0.5)


def test_mask_presets_are_small():
    assert sum(p.numel() for p in create_model("mask.lite").parameters()) == 150_096
    assert create_model("mask.fast").scale == 8


def test_keep_threshold_moves_the_decision_and_lower_keeps_a_superset(tmp_path):
    from edeflare.models.infer import ModelDeflarer
    from edeflare.models.weights import ModelCard, save_model

    ev = make_events([0, 15], [1, 1], [1, 1], [1, 1])
    lg = np.zeros((4, 1, 1), np.float32)  # keep probability sigma(0 + ln 3) = 3/4 everywhere
    assert event_keep_mask(lg, ev, 0, 20, 4, threshold=0.74).all()
    assert not event_keep_mask(lg, ev, 0, 20, 4, threshold=0.76).any()
    with pytest.raises(ValueError, match="threshold must be in"):
        event_keep_mask(lg, ev, 0, 20, 4, threshold=1.0)
    torch.manual_seed(3)
    net = create_model("mask.lite")
    with torch.no_grad():
        for p in net.parameters():
            p.add_(0.2 * torch.randn_like(p))
    path = tmp_path / "m.safetensors"
    save_model(path, net, ModelCard(preset="mask.lite", keep_threshold=0.3))
    rng = np.random.default_rng(0)
    n = 5000
    t = np.sort(rng.integers(0, 20_000, n))
    events = make_events(t, rng.integers(0, 64, n), rng.integers(0, 48, n), rng.integers(0, 2, n))
    kept = {}
    for threshold in (None, 0.1, 0.3, 0.6):
        d = ModelDeflarer(path, keep_threshold=threshold)
        ((_, out),) = d.windows([(0, events)], (64, 48))
        kept[threshold] = {tuple(e) for e in out.tolist()}
    assert kept[None] == kept[0.3]  # the card's threshold is the default
    assert kept[0.6] < kept[0.3] < kept[0.1]  # strict supersets as the threshold falls


def _pixel_net(seed: int = 0) -> FlareMaskNet:
    """A ``mask.pixel`` with random weights everywhere (its zero-initialised output too)."""
    torch.manual_seed(seed)
    net = create_model("mask.pixel").eval()
    with torch.no_grad():
        for p in net.parameters():
            p.add_(0.3 * torch.randn_like(p))
    return net


def test_pixel_refinement_starts_as_the_identity_and_its_event_path_equals_the_dense_one():
    size = (70, 50)
    rng = np.random.default_rng(1)
    n = 3000
    x, y = rng.integers(0, size[0], n), rng.integers(0, size[1], n)
    # many events per pixel, one polarity per pixel (no ON/OFF cancellation in the grid)
    ev = make_events(np.sort(rng.integers(0, 20_000, n)), x, y, (7 * x + 3 * y) % 2)
    grid = torch.from_numpy(encode(ev, size, 0, 20_000, 8))[None, None].float()
    assert torch.equal(create_model("mask.pixel")(grid), grid)  # identity at initialisation
    net = _pixel_net()
    with torch.no_grad():
        full = net.pixel_logits(grid)[0].numpy()
        coarse = net.logits(torch.from_numpy(event_features(ev, size, 0, 20_000, 8, 8))[None])
    channel = ev["t"] * 8 // 20_000 + 8 * (1 - ev["p"].astype(np.int64))
    dense = full[channel, ev["y"], ev["x"]]
    params = net.pixel_params()
    for threshold in (0.3, 0.5, 0.7):
        keep = event_keep_mask(
            coarse[0].numpy(), ev, 0, 20_000, 8, threshold, pixel_params=params, sensor_size=size
        )
        assert 0.05 < keep.mean() < 0.95  # a real mask
        np.testing.assert_array_equal(keep, dense > np.log(threshold / (1 - threshold)) - np.log(3))
    with pytest.raises(ValueError, match="needs the sensor size"):
        event_keep_mask(coarse[0].numpy(), ev, 0, 20_000, 8, pixel_params=params)


@pytest.mark.parametrize("side", [60, 12])
def test_event_logits_equal_the_dense_paths_whether_pixels_repeat_or_not(side):
    # side 60: most events fire a pixel of their own (the rings summed per event);
    # side 12: nearly all repeat one (each pixel's rings summed once, then read back)
    size = (64, 48)
    rng = np.random.default_rng(2)
    n = 2500
    x, y = rng.integers(2, 2 + side, n), rng.integers(2, 2 + min(side, 44), n)
    ev = make_events(np.sort(rng.integers(0, 20_000, n)), x, y, (7 * x + 3 * y) % 2)
    repeats = 1 - np.unique(y * size[0] + x).size / n
    assert (repeats < fm._RING_MEMO_REPEATS) == (side == 60)
    net = _pixel_net(3)
    grid = torch.from_numpy(encode(ev, size, 0, 20_000, 8))[None, None].float()
    with torch.no_grad():
        full = net.pixel_logits(grid)[0].numpy()
        coarse = net.logits(torch.from_numpy(event_features(ev, size, 0, 20_000, 8, 8))[None])
    channel = ev["t"] * 8 // 20_000 + 8 * (1 - ev["p"].astype(np.int64))
    got = fm.event_keep_logits(
        coarse[0].numpy(), ev, 0, 20_000, 8, pixel_params=net.pixel_params(), sensor_size=size
    )
    np.testing.assert_allclose(got, full[channel, ev["y"], ev["x"]], rtol=0, atol=1e-4)
    on, total, _ = fm._count_frames(*size, ev.size)
    assert not on.any() and not total.any()  # the frames are left zeroed for the next window
    # the events' support comes with the refinement's counts (memoised or not), and
    # without a refinement from event_support itself; either way a 5x5 box count
    counts = np.zeros((size[1] + 4, size[0] + 4), np.int64)
    np.add.at(counts, (ev["y"] + 2, ev["x"] + 2), 1)
    box = sum(np.roll(np.roll(counts, dy, 0), dx, 1) for dy in range(-2, 3) for dx in range(-2, 3))
    expected = box[ev["y"] + 2, ev["x"] + 2] - 1
    np.testing.assert_array_equal(fm.event_support(ev, size), expected)
    for params in (net.pixel_params(), None):
        support = np.full(ev.size, -7, np.int64)
        with_support = fm.event_keep_logits(
            coarse[0].numpy(), ev, 0, 20_000, 8, pixel_params=params, sensor_size=size,
            support=support,
        )  # fmt: skip
        np.testing.assert_array_equal(support, expected)
        if params is not None:
            np.testing.assert_array_equal(with_support, got)  # the logits do not change
    with pytest.raises(ValueError, match="support must be int64"):
        fm.event_keep_logits(coarse[0].numpy(), ev, 0, 20_000, 8, support=np.zeros(3, np.int64))


def test_records_are_the_events_in_bands_of_rows_and_serve_both_kernels():
    size = (40, 37)  # a height that is no multiple of the bands' 8 rows
    rng = np.random.default_rng(4)
    n = 3000
    ev = make_events(
        np.sort(rng.integers(0, 20_000, n)), rng.integers(0, 40, n), rng.integers(0, 37, n),
        rng.integers(0, 2, n),
    )  # fmt: skip
    records = fm.event_records(ev, 0, 20_000, 8, size)
    assert (records.bins, records.sensor_size) == (8, size)
    rec = records.rows
    order = rec[:, 3]
    assert sorted(order.tolist()) == list(range(n))  # every event once
    band = ev["y"][order] // 8
    assert (np.diff(band) >= 0).all()  # band by band
    assert all((np.diff(order[band == b]) > 0).all() for b in range(5))  # in time order
    np.testing.assert_array_equal(rec[:, 0], ev["x"][order])
    np.testing.assert_array_equal(rec[:, 1], ev["y"][order])
    channel = ev["t"] * 8 // 20_000 + 8 * (1 - ev["p"].astype(np.int64))
    np.testing.assert_array_equal(rec[:, 2], 2 * channel[order] + ev["p"][order])
    # given or made inside, the same features and logits
    net = _pixel_net(5)
    feats = fm.event_features(ev, size, 0, 20_000, 8, 8)
    got = fm.event_features(ev, size, 0, 20_000, 8, 8, records=records)
    np.testing.assert_array_equal(got, feats)
    with torch.no_grad():
        coarse = net.logits(torch.from_numpy(feats)[None])[0].numpy()
    kw = {"pixel_params": net.pixel_params(), "sensor_size": size}
    np.testing.assert_array_equal(
        fm.event_keep_logits(coarse, ev, 0, 20_000, 8, records=records, **kw),
        fm.event_keep_logits(coarse, ev, 0, 20_000, 8, **kw),
    )
    # records the kernels would overrun are refused, not read
    short = records._replace(rows=rec[1:])
    with pytest.raises(ValueError, match="3000 event_records at 8 bins"):
        fm.event_keep_logits(coarse, ev, 0, 20_000, 8, records=short, **kw)
    with pytest.raises(ValueError, match="3000 event_records at 4 bins"):
        fm.event_features(ev, size, 0, 20_000, 4, 8, records=records)
    unchecked = fm.event_records(ev, 0, 20_000, 8)
    with pytest.raises(ValueError, match=r"made without a sensor; .* need them on \(40, 37\)"):
        fm.event_keep_logits(coarse, ev, 0, 20_000, 8, records=unchecked, **kw)
    with pytest.raises(ValueError, match="outside the window"):
        fm.event_records(ev, 0, 10_000, 8, size)


@pytest.mark.parametrize("n", [65_535, 65_536])
def test_counts_of_the_largest_windows_do_not_wrap(n):
    # below 65,536 events the count frames are uint16 (no pixel's count nor square's sum
    # can reach it), from there int32: every event at one pixel, on both sides of it
    size = (16, 16)
    ev = make_events(np.arange(n) * 20_000 // n, np.full(n, 5), np.full(n, 5), np.arange(n) % 2)
    net = _pixel_net(6)
    coarse = np.zeros((16, 2, 2), np.float32)
    support = np.empty(n, np.int64)
    logits = fm.event_keep_logits(
        coarse, ev, 0, 20_000, 8, pixel_params=net.pixel_params(), sensor_size=size,
        support=support,
    )  # fmt: skip
    assert (support == n - 1).all()
    on, off = n // 2, n - n // 2
    counts = np.array([[on, off, 0, 0], [off, on, 0, 0]], np.float64)  # ON and OFF events
    with torch.no_grad():
        w = {k: v.astype(np.float64) for k, v in net.pixel_params().items()}
    hidden = np.maximum(np.log1p(counts) @ w["w_in"].T + w["b_in"], 0.0)
    expected = hidden @ w["w_out"] + w["b_out"][0]  # the network's logit is 0 here
    np.testing.assert_allclose(logits[:2], expected[ev["p"][:2] ^ 1], rtol=0, atol=1e-9)
    assert len(np.unique(logits)) == len(np.unique(counts, axis=0))  # one logit a polarity


def test_pixel_features_count_the_pixel_and_its_neighbours_by_hand():
    from edeflare.models.mask_kernels import event_pixel_features

    # a hot pixel at (5, 5): 4 ON events; one OFF there; a lone ON at (6, 5); one at (8, 5)
    ev = make_events([0, 1, 2, 3, 4, 5, 6], [5, 5, 5, 5, 5, 6, 8], [5] * 7, [1, 1, 1, 1, 0, 1, 1])
    f = np.expm1(event_pixel_features(ev, (12, 10))).round().astype(int)
    assert f[0].tolist() == [4, 1, 1, 0]  # own 4 ON, other 1 OFF, (6, 5) beside; (8, 5) 3 away
    assert f[4].tolist() == [1, 4, 1, 0]
    assert f[5].tolist() == [1, 0, 5, 1]  # the 5 events of (5, 5) beside; (8, 5) 2 away: the ring
    assert f[6].tolist() == [1, 0, 0, 1]  # (6, 5) in its ring; (5, 5) 3 away: outside


def test_events_outside_the_window_or_the_sensor_are_refused_not_read_out_of_bounds():
    from edeflare.models.mask_kernels import event_pixel_features

    lg = np.zeros((16, 2, 2), np.float32)
    late = make_events([5, 20_000], [1, 1], [1, 1], [1, 1])  # t = 20 000: the next window
    with pytest.raises(ValueError, match=r"event 1 \(t=20000.*outside the window \[0, 20000\)"):
        event_keep_mask(lg, late, 0, 20_000, 8)
    with pytest.raises(ValueError, match="outside the window"):
        event_features(late, (16, 16), 0, 20_000, 8, 8)
    off = make_events([5, 6], [1, 16], [1, 1], [1, 1])  # x = 16 on a 16-pixel-wide sensor
    with pytest.raises(ValueError, match="16x16 sensor"):
        event_features(off, (16, 16), 0, 20_000, 8, 8)
    with pytest.raises(ValueError, match="16x16 sensor"):
        event_pixel_features(off, (16, 16))
    params = _pixel_net().pixel_params()
    with pytest.raises(ValueError, match="16x16 sensor"):
        event_keep_mask(lg, off, 0, 20_000, 8, pixel_params=params, sensor_size=(16, 16))
    assert event_keep_mask(lg, off, 0, 20_000, 8).shape == (2,)  # no frame: clipped sampling


def test_keep_loss_window_cells_keep_an_edge_the_flare_shifted_by_a_bin():
    """Two ON events in each of two bins; the target has all four in the second bin.
    Per bin, the first bin's two are to drop; per window, all four are to keep. The
    untrained net's keep probability is 3/4 everywhere."""
    from edeflare.models.mask_loss import keep_loss

    net = FlareMaskNet(bins=2, scale=4, features=(8, 16), groups=4)
    x = torch.zeros(1, 1, 2, 8, 8)
    x[0, 0, :, 1, 1] = 2
    y = torch.zeros_like(x)
    y[0, 0, 1, 1, 1] = 4
    per_bin = -(0.5 * np.log(0.75) + 0.5 * np.log(0.25))
    assert keep_loss(net, x, y).item() == pytest.approx(per_bin, abs=1e-5)
    per_window = -0.5 * np.log(0.75)  # nothing to drop
    assert keep_loss(net, x, y, cells="window").item() == pytest.approx(per_window, abs=1e-5)
    with pytest.raises(ValueError, match="cells must be"):
        keep_loss(net, x, y, cells="pixel")
