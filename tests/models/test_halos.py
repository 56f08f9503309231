"""The halo prior (the annulus around each window's lights) and its logit shift."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from conftest import random_events
from edeflare.errors import EdeflareError, ParameterError
from edeflare.events import make_events, merge_events
from edeflare.lights.cells import (
    MIN_LIGHT_RADIUS,
    light_cells,
    light_pixels,
    window_lights,
)
from edeflare.methods import create_method
from edeflare.models import create_model
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.models.mask_kernels import event_support
from edeflare.models.weights import ModelCard, save_model
from edeflare.rules.ghost import ghost_cells, in_ghost_prior
from edeflare.rules.halo import (
    FAR_RADII,
    FAR_REACH,
    HALO_EXTENT,
    HALO_MAX_REACH,
    far_from_lights,
    halo_pixels,
    in_halo_prior,
)

SIZE = (192, 64)  # wide enough that no halo here meets HALO_MAX_REACH (38 px)


def _block(x0: int, y0: int, side: int = 10, per_pixel: int = 20, t0: int = 0) -> np.ndarray:
    """``per_pixel`` events in each pixel of a ``side`` x ``side`` block, within 20 ms."""
    yy, xx = np.mgrid[y0 : y0 + side, x0 : x0 + side]
    n = per_pixel * xx.size
    return make_events(
        t0 + np.arange(n) * (20_000 // n),
        np.tile(xx.ravel(), per_pixel),
        np.tile(yy.ravel(), per_pixel),
        np.ones(n),
    )


def test_a_light_is_its_bright_pixels_and_its_radius_the_largest_disc_inside():
    labels, radii = light_pixels(_block(40, 20), SIZE, 20_000)
    expected = np.zeros((64, 192), dtype=int)
    expected[20:30, 40:50] = 1
    np.testing.assert_array_equal(labels, expected)
    assert radii.tolist() == [5.0]  # the block's centre pixels are 5 px from outside it
    # two lights far apart are two; a hole in one is filled
    two = merge_events(_block(0, 0, side=8), _block(70, 40, side=16, per_pixel=10))
    two = two[~((two["x"] == 77) & (two["y"] == 47))]
    labels, radii = light_pixels(two, SIZE, 20_000)
    assert sorted(np.bincount(labels.ravel())[1:].tolist()) == [64, 256]
    assert sorted(radii.tolist()) == [4.0, 8.0]
    # a light that sweeps a stroke during the window: its radius is half the stroke's
    # width, not that of a disc of the stroke's area
    stroke = merge_events(*(_block(10 + 6 * i, 30, side=6, t0=i) for i in range(10)))
    assert light_pixels(stroke, SIZE, 20_000)[1].tolist() == [3.0]


def test_a_light_needs_its_rate():
    # one whole 8x8 cell: 5 events per pixel in 20 ms is the rate (0.25 / px / ms); 4 is
    # not, nor 5 in 40 ms
    assert light_pixels(_block(40, 16, side=8, per_pixel=5), SIZE, 20_000)[1].size == 1
    assert light_pixels(_block(40, 16, side=8, per_pixel=4), SIZE, 20_000)[1].size == 0
    assert light_pixels(_block(40, 16, side=8, per_pixel=5), SIZE, 40_000)[1].size == 0
    assert not halo_pixels(make_events([], [], [], []), SIZE, 20_000).any()


def test_a_hot_pixel_is_no_light_but_a_3x3_block_is():
    # 400 events on one pixel in 20 ms pass its cell's rate (320), but a light is at
    # least a solid 3x3 block (radius 2): no light, no halo
    n = 400
    hot = make_events(np.arange(n) * 50, np.full(n, 47), np.full(n, 20), np.ones(n))
    ring = make_events([n * 50], [56], [20], [1])  # 9 px away, two cells over
    ev = merge_events(hot, ring)
    assert light_pixels(ev, SIZE, 20_000)[1].size == 0
    assert not in_halo_prior(ev, SIZE, 20_000).any()
    block = _block(45, 19, side=3, per_pixel=40)  # 360 events, radius 2: out to 10 px
    assert light_pixels(block, SIZE, 20_000)[1].tolist() == [MIN_LIGHT_RADIUS]
    assert in_halo_prior(merge_events(block, ring), SIZE, 20_000)[-1]


def test_the_halo_is_the_band_from_the_rim_to_five_radii_beyond_the_light():
    p = halo_pixels(_block(40, 20), SIZE, 20_000)
    # each pixel's distance to the nearest pixel of the block (x 40-49, y 20-29)
    yy, xx = np.mgrid[0:64, 0:192]
    d = np.hypot(np.clip(xx, 40, 49) - xx, np.clip(yy, 20, 29) - yy)
    # the light's cells are those its block fills at the rate: x 40-47, y 16-31 (cells
    # x 5, y 2-3; the column x 48-55 holds too few); out with the 8 cells around each:
    # cells x 4-6, y 1-4 -> pixels x 32-55, y 8-39
    near = np.zeros((64, 192), dtype=bool)
    near[8:40, 32:56] = True
    reach = (HALO_EXTENT - 1) * 5.0
    np.testing.assert_array_equal(p, (d > 2.0) & (d <= reach) & ~near)
    assert p[24, 56] and p[24, 74] and not p[24, 75]
    wider = halo_pixels(_block(40, 20), SIZE, 20_000, extent=8.0)
    assert wider[24, 84] and not p[24, 84]
    with pytest.raises(ValueError, match="extent must be > 1"):
        halo_pixels(_block(40, 20), SIZE, 20_000, extent=1.0)


def test_a_large_lights_halo_stops_at_a_fifth_of_the_sensors_width(rng):
    # a 20x20 block (radius 10) would reach 50 px beyond itself; on a 160 px wide sensor
    # the band stops 32 px out. Both ways of measuring the band agree on it.
    size = (160, 120)
    assert HALO_MAX_REACH * size[0] == 32.0
    light = _block(30, 50, side=20, per_pixel=20)
    p = halo_pixels(light, size, 20_000)
    assert light_pixels(light, size, 20_000)[1].tolist() == [10.0]
    assert p[60, 49 + 32] and not p[60, 49 + 33]  # the block's right edge is x = 49
    assert not p[60, 49 + 45]
    ev = merge_events(light, random_events(rng, 5_000, size, t0=0, span_us=20_000))
    inside = in_halo_prior(ev, size, 20_000)
    np.testing.assert_array_equal(inside, halo_pixels(ev, size, 20_000)[ev["y"], ev["x"]])
    assert not inside[(ev["x"] > 49 + 32) & (ev["y"] >= 50) & (ev["y"] < 70)].any()
    # on a sensor twice as wide, the same light reaches its five radii
    wide = halo_pixels(light, (320, 120), 20_000)
    assert wide[60, 49 + 45] and wide[60, 49 + 50] and not wide[60, 49 + 51]


def test_in_halo_prior_reads_each_events_pixel():
    far = make_events([1, 2, 3], [70, 90, 44], [24, 60, 36], [1, 0, 1])
    ev = merge_events(_block(40, 20), far)
    inside = in_halo_prior(ev, SIZE, 20_000)
    np.testing.assert_array_equal(inside, halo_pixels(ev, SIZE, 20_000)[ev["y"], ev["x"]])
    # (70, 24): 21 px from the light's pixels; (90, 60): 50.6; (44, 36): 7, but in the
    # cell below the light's
    assert inside[ev["x"] == 70].all() and not inside[ev["x"] == 90].any()
    assert not inside[(ev["x"] == 44) & (ev["y"] == 36)].any()


@pytest.mark.parametrize(
    ("name", "prior", "light", "size"),
    [
        ("halo_shift", in_halo_prior, (40, 20, 10, 20), SIZE),  # a light mid-frame
        ("ghost_shift", in_ghost_prior, (0, 0, 8, 20), (64, 64)),  # in a corner: ghosts across
    ],
)
def test_a_prior_shift_lowers_exactly_the_logits_inside_the_prior(name, prior, light, size, rng):
    ev = merge_events(_block(*light), random_events(rng, 300, size, t0=0, span_us=20_000))
    weights = bundled_weights()
    plain = ModelDeflarer(weights, **{name: 0.0}).window_logits([(0, ev)], size)[0]
    shifted = ModelDeflarer(weights, **{name: 2.5}).window_logits([(0, ev)], size)[0]
    inside = prior(ev, size, 20_000)
    assert 0 < inside.sum() < len(ev)
    np.testing.assert_allclose(plain - shifted, 2.5 * inside, atol=1e-5)
    # the method keeps a subset, and drops more only inside the prior (one windowing: the
    # second's windows hold parts of this one, with priors of their own)
    kept = create_method("model", phase_shift_us=0, **{name: 0.0})(ev, size, rng=0)
    kept_shifted = create_method("model", phase_shift_us=0, **{name: 6.0})(ev, size, rng=0)
    assert np.isin(kept_shifted, kept).all() and len(kept_shifted) < len(kept)
    lost = kept[~np.isin(kept, kept_shifted)]
    assert prior(ev, size, 20_000)[np.isin(ev, lost)].all()


def test_both_priors_add_up_and_share_one_count_of_the_light_cells(rng):
    size = (64, 64)
    ev = merge_events(_block(0, 0, 8, 20), random_events(rng, 600, size, t0=0, span_us=20_000))
    lights = light_cells(ev, size, 20_000)
    halo, ghost = in_halo_prior(ev, size, 20_000), in_ghost_prior(ev, size, 20_000)
    assert halo.any() and ghost.any() and (halo != ghost).any()
    np.testing.assert_array_equal(in_halo_prior(ev, size, 20_000, lights=lights), halo)
    np.testing.assert_array_equal(in_ghost_prior(ev, size, 20_000, lights=lights), ghost)
    weights = bundled_weights()
    plain = ModelDeflarer(weights, halo_shift=0.0, ghost_shift=0.0)
    both = ModelDeflarer(weights, halo_shift=2.5, ghost_shift=1.5)
    np.testing.assert_allclose(
        plain.window_logits([(0, ev)], size)[0] - both.window_logits([(0, ev)], size)[0],
        2.5 * halo + 1.5 * ghost,
        atol=1e-5,
    )


def test_without_a_light_the_shift_changes_nothing(rng):
    ev = random_events(rng, 2_000, SIZE, t0=0, span_us=100_000)
    plain = create_method("model", halo_shift=0.0)(ev, SIZE, rng=0)
    np.testing.assert_array_equal(create_method("model", halo_shift=5.0)(ev, SIZE, rng=0), plain)


@pytest.mark.parametrize("name", ["halo_shift", "ghost_shift", "streak_shift"])
@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), True, "2"])
def test_a_bad_prior_shift_is_refused(name, bad):
    with pytest.raises(ParameterError, match=f"{name} must be a finite number >= 0"):
        create_method("model", **{name: bad})


@pytest.mark.parametrize("name", ["halo_shift", "ghost_shift", "streak_shift"])
def test_a_prior_shift_needs_a_mask_model_and_defaults_to_the_cards(name, tmp_path):
    path = tmp_path / "v.safetensors"
    save_model(path, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny"))
    with pytest.raises(EdeflareError, match=f"{name} needs a mask model"):
        ModelDeflarer(path, **{name: 1.0})
    assert ModelDeflarer(path).rules[name] == 0.0
    carded = tmp_path / "m.safetensors"
    save_model(carded, create_model("mask.lite"), ModelCard(preset="mask.lite", rules={name: 1.5}))
    assert ModelDeflarer(carded).rules[name] == 1.5
    assert ModelDeflarer(carded, **{name: 0.0}).rules[name] == 0.0


def test_the_events_band_is_the_pixel_maps_band(rng):
    # in_halo_prior measures distances at the events (a k-d tree of each light's edge),
    # halo_pixels on a pixel map (a distance transform): the same band, exactly. Three
    # lights (a disc, a square, a stroke) over random events, one near the sensor's edge.
    size = (320, 240)
    yy, xx = np.mgrid[-9:10, -9:10]
    disc = np.hypot(xx, yy) <= 9
    lit = make_events(
        np.arange(30 * disc.sum()) % 20_000,
        np.tile(150 + xx[disc], 30),
        np.tile(120 + yy[disc], 30),
        np.ones(30 * disc.sum()),
    )
    stroke = merge_events(*(_block(200 + 6 * i, 30, side=6, t0=i) for i in range(12)))
    ev = merge_events(lit, _block(2, 200, side=12), stroke,
                      random_events(rng, 20_000, size, t0=0, span_us=20_000))  # fmt: skip
    inside = in_halo_prior(ev, size, 20_000)
    np.testing.assert_array_equal(inside, halo_pixels(ev, size, 20_000)[ev["y"], ev["x"]])
    assert light_pixels(ev, size, 20_000)[1].size == 3 and 500 < inside.sum() < 10_000


def test_the_inside_of_a_ring_shaped_light_is_the_lights_not_its_halo(rng):
    # a bright ring (radii 22-30 px) with a dark middle: its filled hole is the light's,
    # and the events there (beyond the cells next to the ring's) are in no halo, in the
    # events' band as on the pixel map
    size = (320, 240)
    yy, xx = np.mgrid[-30:31, -30:31]
    ring = (np.hypot(xx, yy) <= 30) & (np.hypot(xx, yy) >= 22)
    lit = make_events(
        np.arange(30 * ring.sum()) * 20_000 // (30 * ring.sum()),
        np.tile(160 + xx[ring], 30),
        np.tile(120 + yy[ring], 30),
        np.ones(30 * ring.sum()),
    )
    middle = make_events([5, 6, 7], [160, 157, 163], [120, 122, 118], [1, 0, 1])
    ev = merge_events(lit, middle, random_events(rng, 5_000, size, t0=0, span_us=20_000))
    inside = in_halo_prior(ev, size, 20_000)
    np.testing.assert_array_equal(inside, halo_pixels(ev, size, 20_000)[ev["y"], ev["x"]])
    in_middle = np.hypot(ev["x"].astype(float) - 160, ev["y"].astype(float) - 120) <= 4
    assert in_middle.sum() >= 3 and not inside[in_middle].any()
    assert inside.sum() > 1_000  # the band around the ring is there


@pytest.mark.parametrize("shape", ["disc", "ring", "stroke"])
def test_the_band_of_a_lights_box_is_the_distance_transforms(shape):
    # _in_band decides most pixels by bounds, then measures the rest in a loop (few
    # pairs of pixel and edge pixel: the disc, the ring) or a k-d tree (many: a stroke
    # 600 px long); each way, the band of scipy's exact distance transform
    from scipy import ndimage

    from edeflare.lights.cells import _edge_pixels
    from edeflare.rules.halo import _in_band

    yy, xx = np.mgrid[0:40, 0:640]
    r = np.hypot(yy - 20, xx - 20)
    own = {"disc": r <= 9, "ring": (r <= 15) & (r >= 9), "stroke": (yy >= 14) & (yy < 26)}[shape]
    own = ndimage.binary_fill_holes(own)
    d = ndimage.distance_transform_edt(~own)
    py, px = np.mgrid[-60:100, -60:700]
    py, px = py.ravel(), px.ravel()
    inside = (py >= 0) & (py < 40) & (px >= 0) & (px < 640)
    reach = 5.0 * 9.0
    band = _in_band(own, _edge_pixels(own), py, px, reach)
    want = np.zeros(py.size, dtype=bool)
    want[inside] = (d[py[inside], px[inside]] > 2.0) & (d[py[inside], px[inside]] <= reach)
    np.testing.assert_array_equal(band[inside], want[inside])
    assert band[inside].sum() > 1_000 and not band[inside][own[py[inside], px[inside]]].any()
    outside = ~inside  # off the box: the nearest light pixel is as far as the box allows
    assert not band[outside & ((py < -46) | (py > 85) | (px > 685))].any()


@pytest.mark.parametrize("seed", range(5))
def test_a_lights_filled_holes_radius_and_edge_are_scipys(seed):
    from scipy import ndimage

    from edeflare.lights.cells import _edge_pixels, _fill_holes, _inscribed_radius

    mask = np.random.default_rng(seed).random((40, 56)) < 0.55
    np.testing.assert_array_equal(_fill_holes(mask), ndimage.binary_fill_holes(mask))
    # the light's radius and edge, as scipy's distance transform and erosion give them
    own = ndimage.binary_fill_holes(ndimage.binary_opening(mask))
    want = ndimage.distance_transform_edt(np.pad(own, 1)).max()
    assert _inscribed_radius(own) == want and want >= 1.0
    np.testing.assert_array_equal(
        _edge_pixels(own), np.argwhere(own & ~ndimage.binary_erosion(own, border_value=0))
    )
    assert _fill_holes(np.zeros((3, 4), bool)).sum() == 0
    assert _fill_holes(np.ones((3, 4), bool)).all()


def test_the_priors_of_a_window_share_its_lights_and_no_other_window_does(rng):
    ev = merge_events(_block(40, 20), random_events(rng, 300, SIZE, t0=0, span_us=20_000))
    lights = light_cells(ev, SIZE, 20_000)
    first = in_halo_prior(ev, SIZE, 20_000, lights=lights)
    np.testing.assert_array_equal(first, in_halo_prior(ev, SIZE, 20_000))  # kept = computed
    # another window (a new array, its light moved) with the same light cells array: its
    # own lights are found, not the last window's
    moved = ev.copy()
    moved["x"][moved["x"] < 60] += 30
    np.testing.assert_array_equal(
        in_halo_prior(moved, SIZE, 20_000, lights=light_cells(moved, SIZE, 20_000)),
        in_halo_prior(moved, SIZE, 20_000),
    )
    assert (in_halo_prior(moved, SIZE, 20_000) != first).any()


def test_a_window_without_a_light_has_its_logits_raised_by_the_light_free_shift(rng):
    weights = bundled_weights()
    dark = random_events(rng, 300, SIZE, t0=0, span_us=20_000)
    lit = merge_events(_block(40, 20), random_events(rng, 300, SIZE, t0=0, span_us=20_000))
    plain = ModelDeflarer(weights, light_free_shift=0.0)
    raised = ModelDeflarer(weights, light_free_shift=1.5, light_free_support=0)
    batch = [(0, dark), (0, lit)]
    (d0, l0), (d1, l1) = plain.window_logits(batch, SIZE), raised.window_logits(batch, SIZE)
    np.testing.assert_allclose(d1 - d0, 1.5, atol=1e-9)  # every event, by the shift
    np.testing.assert_array_equal(l1, l0)  # a light in the window: no change
    with pytest.raises(ParameterError, match="light_free_shift"):
        ModelDeflarer(weights, light_free_shift=-1.0)
    assert create_method("model").params["light_free_shift"] is None  # the card's: 4


def test_the_light_free_shift_raises_only_the_events_with_support_in_their_5x5_square(rng):
    weights = bundled_weights()
    # no light: a 3x3 patch of nine events (each has 8 others within 2 px), a pair two
    # pixels apart (1 each), a pair three apart (0: outside the 5x5 square), a lone event
    xs = [40, 41, 42, 40, 41, 42, 40, 41, 42, 100, 102, 150, 153, 10]
    ys = [30, 30, 30, 31, 31, 31, 32, 32, 32, 50, 52, 20, 20, 60]
    dark = make_events(np.arange(len(xs)) * 1_000, xs, ys, np.arange(len(xs)) % 2)
    np.testing.assert_array_equal(event_support(dark, SIZE), [8] * 9 + [1, 1, 0, 0, 0])
    plain = ModelDeflarer(weights, light_free_shift=0.0)
    base = plain.window_logits([(0, dark)], SIZE)[0]
    for support, raised in ((0, 14), (1, 11), (2, 9), (9, 0)):
        d = ModelDeflarer(
            weights, light_free_shift=2.0, light_free_support=support, light_free_crowding=0
        )
        delta = d.window_logits([(0, dark)], SIZE)[0] - base
        np.testing.assert_allclose(delta[:raised], 2.0, atol=1e-9)
        np.testing.assert_allclose(delta[raised:], 0.0, atol=1e-9)
    for bad in (-1, 1.5, True, float("nan")):
        with pytest.raises(ParameterError, match="light_free_support"):
            ModelDeflarer(weights, light_free_support=bad)
    assert create_method("model").params["light_free_support"] is None  # the card's: 2
    assert ModelDeflarer(weights).rules["light_free_support"] == 2


def test_far_from_the_lights_is_beyond_a_share_of_the_width_and_radii_from_every_light():
    # a lamp in the cells x 5-6, y 2-3 (pixels x 40-55, y 16-31; radius 8): beyond both
    # 0.3 x 192 = 57.6 px and 8 radii, 64 px
    assert (FAR_REACH, FAR_RADII) == (0.3, 8.0)
    lamp = _block(40, 16, side=16, per_pixel=20)
    lights = window_lights(lamp, SIZE, 20_000)
    # cells in row 2 whose centres are 0, 56 and 72 px right of the lamp's right cell
    # (x 6), and one 40 px left of its left cell (x 5); the window's last four events
    ev = merge_events(
        lamp, make_events([19_996, 19_997, 19_998, 19_999], [52, 108, 124, 4], [20] * 4, [1] * 4)
    )
    tail = slice(-4, None)
    assert far_from_lights(ev, SIZE, 20_000)[tail].tolist() == [False, False, True, False]
    # the same with the lights counted; with a share of 0.2 (38.4 px) the radii decide
    assert far_from_lights(ev, SIZE, 20_000, lights=lights)[tail].tolist() == [
        False, False, True, False
    ]  # fmt: skip
    assert far_from_lights(ev, SIZE, 20_000, reach=0.2)[tail].tolist() == [
        False, False, True, False
    ]  # fmt: skip
    # and with 4 radii (32 px): the share of 0.2 decides
    assert far_from_lights(ev, SIZE, 20_000, reach=0.2, radii=4.0)[tail].tolist() == [
        False, True, True, True
    ]  # fmt: skip
    # cells left out (the lights' ghosts' cells, in the model) are never far
    out = np.zeros_like(lights)
    out[2, 15] = True  # the cell of the far event (x 124)
    assert not far_from_lights(ev, SIZE, 20_000, exclude=out)[tail].any()
    dark = ev[-4:]  # no light: all far, but for the cells left out
    assert far_from_lights(dark, SIZE, 20_000).all()
    assert far_from_lights(dark, SIZE, 20_000, exclude=out).tolist() == [True, True, False, True]
    with pytest.raises(ValueError, match="shape"):
        far_from_lights(ev, SIZE, 20_000, lights=lights[:, :-1])
    with pytest.raises(ValueError, match="exclude"):
        far_from_lights(ev, SIZE, 20_000, exclude=out[:-1])


def test_the_far_shift_raises_the_events_far_from_the_lights_outside_their_ghosts(rng):
    # a lamp near the left edge; scattered events over the whole sensor
    lamp = _block(8, 16, side=16, per_pixel=20)
    scatter = random_events(rng, 2000, SIZE, t0=0, span_us=20_000)
    window = merge_events(lamp, scatter)
    weights = bundled_weights()
    plain = ModelDeflarer(weights, far_shift=0.0).window_logits([(0, window)], SIZE)[0]
    raised = ModelDeflarer(weights, far_shift=2.5).window_logits([(0, window)], SIZE)[0]
    lights = window_lights(window, SIZE, 20_000)
    cy, cx = window["y"] // 8, window["x"] // 8
    ghosts = ghost_cells(window, SIZE, 20_000, lights=lights)[cy, cx]
    far = far_from_lights(window, SIZE, 20_000, lights=lights) & ~ghosts
    # far: more than 57.6 px (and 8 radii, 64 px) between the event's cell and every lamp
    # cell (x 1-2, y 2-3)
    lamp_cells = np.argwhere(lights)
    gap = np.hypot(cy[:, None] - lamp_cells[:, 0], cx[:, None] - lamp_cells[:, 1]).min(axis=1)
    np.testing.assert_array_equal(far, (8 * gap > 64) & ~ghosts)
    assert far.sum() > 500 and (far & (window["x"] < 72)).sum() == 0
    assert (ghosts & (8 * gap > 64)).any()  # across the centre: not raised
    np.testing.assert_allclose((raised - plain)[far], 2.5, atol=1e-9)
    np.testing.assert_array_equal(raised[~far], plain[~far])
    # a window without a light gets the light-free shift only
    dark = scatter[scatter["x"] >= 100]
    only_far = ModelDeflarer(weights, far_shift=2.5, light_free_shift=0.0, scatter_shift=0.0)
    both = ModelDeflarer(weights, far_shift=2.5, light_free_shift=1.0, light_free_support=0)
    (d0,), (d1,) = only_far.window_logits([(0, dark)], SIZE), both.window_logits([(0, dark)], SIZE)
    np.testing.assert_allclose(d1 - d0, 1.0, atol=1e-9)
    with pytest.raises(ParameterError, match="far_shift"):
        ModelDeflarer(weights, far_shift=float("nan"))


def test_dense_scene_and_hot_pixels_are_no_lights_and_get_the_light_free_shift(rng):
    # three groups of light cells: a lamp (1 event per pixel and ms), a patch of dense
    # texture at 0.4 (over the cell rate, 0.25, under the lights' core rate, 0.55) and
    # a hot pixel firing 400 times (its cell passes; no 3x3 block: no light)
    lamp, texture = _block(40, 16, side=16, per_pixel=20), _block(120, 40, side=16, per_pixel=8)
    hot = make_events(np.arange(400) * 50, np.full(400, 180), np.full(400, 8), np.ones(400))
    groups = ndimage.label(light_cells(merge_events(lamp, texture, hot), SIZE, 20_000))[1]
    assert groups == 3  # all three pass the cell rate; only the lamp fires as a light does
    cells = window_lights(merge_events(lamp, texture, hot), SIZE, 20_000)
    expected = np.zeros_like(cells)
    expected[2:4, 5:7] = True  # the lamp's four cells
    np.testing.assert_array_equal(cells, expected)
    # a window with only the texture and the hot pixel has no light: every logit is
    # raised by the light-free shift, none lowered by a prior
    weights = bundled_weights()
    dark = merge_events(texture, hot, random_events(rng, 300, SIZE, t0=0, span_us=20_000))
    assert not window_lights(dark, SIZE, 20_000).any()
    plain = ModelDeflarer(weights, light_free_shift=0.0).window_logits([(0, dark)], SIZE)[0]
    raised = ModelDeflarer(weights, light_free_shift=1.5, light_free_support=0)
    raised = raised.window_logits([(0, dark)], SIZE)[0]
    np.testing.assert_allclose(raised - plain, 1.5, atol=1e-9)


def test_a_light_in_the_part_of_a_window_the_stream_covers_is_found():
    # a stream that ends 5 ms into its last window: its light fires 4 events per pixel in
    # those 5 ms (0.8 per ms; 0.2 over the whole window, under the light rate of 0.25)
    from edeflare.lights.cells import covered_us

    ev = _block(40, 20, per_pixel=4, t0=15_000)
    ev["t"] = 15_000 + (ev["t"] - 15_000) // 4  # squeezed into 15-20 ms
    part = ev[ev["t"] >= 15_000]
    assert covered_us(part, 15_000, 20_000) == 5_000
    assert not light_cells(part, SIZE, 20_000).any() and light_cells(part, SIZE, 5_000).any()
    weights = bundled_weights()
    far = make_events([16_000, 17_000], [60, 62], [24, 26], [1, 0])  # in the halo
    window = merge_events(part, far)
    logits = ModelDeflarer(weights, halo_shift=0.0).window_logits([(15_000, window)], SIZE)[0]
    shifted = ModelDeflarer(weights, halo_shift=2.0).window_logits([(15_000, window)], SIZE)[0]
    in_far = np.isin(window, far)
    np.testing.assert_allclose((logits - shifted)[in_far], 2.0, atol=1e-9)
