"""The diffraction-spike prior (saturated radial runs in opposite pairs) and its shift."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import random_events
from edeflare.events import make_events, merge_events
from edeflare.lights.cells import light_cells
from edeflare.methods import create_method
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.rules.streak import _runs, in_streak_prior

SIZE = (200, 120)
CX, CY = 100, 60  # the light's centre: a 10x10 block, radius 5


def _light(cx: int = CX, cy: int = CY) -> np.ndarray:
    yy, xx = np.mgrid[cy - 5 : cy + 5, cx - 5 : cx + 5]
    n = 20 * xx.size
    return make_events(np.arange(n), np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20), np.ones(n))


def _ray(direction: int, r0: int, r1: int, per_px: int = 4, cx=CX, cy=CY) -> np.ndarray:
    """``per_px`` events at each pixel of the light's row from ``r0`` to ``r1`` px out,
    to the right (``direction`` 1) or the left (-1), within the sensor."""
    x = cx + direction * np.arange(r0, r1)
    x = np.repeat(x[(x >= 0) & (x < SIZE[0])], per_px)
    return make_events(np.arange(x.size) + 5_000, x, np.full(x.size, cy), np.zeros(x.size))


def _on(ev: np.ndarray, part: np.ndarray) -> np.ndarray:
    """Which of ``part``'s events the prior covers, in ``ev`` merged."""
    inside = in_streak_prior(ev, SIZE, 20_000)
    return inside[np.isin(ev, part)]


def test_runs_bridge_short_gaps_and_stop_at_long_ones():
    filled = np.array(
        [
            [1, 1, 0, 1, 0, 0, 0, 1],  # gap of 1 bridged, gap of 3 stops: 4 rings
            [1, 0, 0, 1, 1, 0, 0, 0],  # gap of 2 bridged: 5 rings
            [0, 0, 0, 1, 1, 1, 1, 1],  # starts with a long gap: 0
            [1, 1, 1, 1, 1, 1, 1, 1],  # to the end: 8
        ],
        dtype=bool,
    )
    np.testing.assert_array_equal(_runs(filled, 2), [4, 5, 0, 8])
    np.testing.assert_array_equal(_runs(filled, 0), [2, 1, 0, 8])


def test_flank_medians_are_the_medians_of_the_angles_on_each_side():
    from edeflare.rules.streak import _flank_medians

    run = np.arange(20) ** 2 % 7  # 0 1 4 2 2 4 1 0 1 4 ...
    left, right = _flank_medians(run, 4, 2)  # the angles 2-4 bins away on each side
    assert left[5] == np.median(run[[1, 2, 3]]) == 2.0
    assert right[5] == np.median(run[[7, 8, 9]]) == 1.0
    assert left[0] == np.median(run[[16, 17, 18]])  # around the circle
    assert right[19] == np.median(run[[1, 2, 3]])
    even_left, _ = _flank_medians(run, 4, 1)  # four angles: the mean of the middle two
    assert even_left[5] == np.median(run[[1, 2, 3, 4]])


def test_opposite_saturated_spikes_are_covered_and_the_light_and_the_rest_are_not(rng):
    spikes = merge_events(_ray(1, 8, 90), _ray(-1, 8, 90))
    other = random_events(rng, 200, SIZE, t0=0, span_us=20_000)
    light = _light()
    ev = merge_events(light, spikes, other)
    on = in_streak_prior(ev, SIZE, 20_000)
    # the light's centre is (99.5, 59.5); its farthest pixel 6.4 px from it; the spikes
    # start past it, a 2 px rim and two radii (10 px): 18.4 px out
    r = np.hypot(ev["x"] - 99.5, ev["y"] - 59.5)
    is_spike = np.isin(ev, spikes)
    assert on[is_spike & (r > 20)].all()
    assert not on[is_spike & (r < 18)].any()
    assert not on[np.isin(ev, light)].any()
    # a few random events fall on the spikes' rows: nothing else is covered
    assert on[np.isin(ev, other)].sum() <= 3


def test_a_spike_without_its_partner_is_no_spike():
    spike = _ray(1, 8, 90)
    assert not _on(merge_events(_light(), spike), spike).any()
    # unless the border hides where the partner would be: a light 12 px from the left
    near = _ray(1, 8, 100, cx=12)
    on = _on(merge_events(_light(cx=12), near), near)
    r = near["x"] - 11.5
    # (a spike's last ring, partly covered, is too thin a share to be filled)
    assert on[(r > 20) & (r < 84)].all() and not on[r < 18].any()


def test_a_sparse_spike_is_left_to_the_network():
    # one event per pixel: none saturated; two a pixel: the same rays are a spike pair
    spikes = merge_events(_ray(1, 8, 90, per_px=1), _ray(-1, 8, 90, per_px=1))
    assert not _on(merge_events(_light(), spikes), spikes).any()
    saturated = merge_events(_ray(1, 8, 90, per_px=2), _ray(-1, 8, 90, per_px=2))
    assert _on(merge_events(_light(), saturated), saturated).mean() > 0.8


def test_a_dense_object_beside_the_light_spans_too_many_angles():
    # a solid 40x40 block just right of the light (a ball of a Newton's cradle), and its
    # mirror on the left: runs at every angle the blocks span, no narrow spike
    blocks = []
    for x0 in (118, 42):
        yy, xx = np.mgrid[40:80, x0 : x0 + 40]
        blocks.append(
            make_events(
                np.arange(4 * xx.size),
                np.tile(xx.ravel(), 4),
                np.tile(yy.ravel(), 4),
                np.ones(4 * xx.size),
            )
        )
    both = merge_events(*blocks)
    assert not _on(merge_events(_light(), both), both).any()


def test_without_a_light_nothing_is_covered(rng):
    ev = merge_events(_ray(1, 8, 90), _ray(-1, 8, 90), random_events(rng, 500, SIZE, 0, 20_000))
    assert not in_streak_prior(ev, SIZE, 20_000).any()


def test_the_shift_lowers_exactly_the_logits_on_the_spikes(rng):
    ev = merge_events(
        _light(), _ray(1, 8, 90), _ray(-1, 8, 90), random_events(rng, 300, SIZE, 0, 20_000)
    )
    weights = bundled_weights()
    plain = ModelDeflarer(weights, streak_shift=0.0).window_logits([(0, ev)], SIZE)[0]
    shifted = ModelDeflarer(weights, streak_shift=2.5).window_logits([(0, ev)], SIZE)[0]
    lights = light_cells(ev, SIZE, 20_000)
    inside = in_streak_prior(ev, SIZE, 20_000, lights=lights)
    assert 0 < inside.sum() < len(ev)
    np.testing.assert_allclose(plain - shifted, 2.5 * inside, atol=1e-5)
    kept = create_method("model", streak_shift=0.0, phase_shift_us=0)(ev, SIZE, rng=0)
    cut = create_method("model", streak_shift=20.0, phase_shift_us=0)(ev, SIZE, rng=0)
    assert np.isin(cut, kept).all()
    assert in_streak_prior(ev, SIZE, 20_000)[np.isin(ev, kept[~np.isin(kept, cut)])].all()


@pytest.mark.parametrize("size", [(200, 120), (1280, 720)])
def test_an_empty_window_has_no_spikes(size):
    assert in_streak_prior(make_events([], [], [], []), size, 20_000).shape == (0,)


def test_a_round_light_on_a_spike_of_another_keeps_its_events():
    # a second lamp (radius 4) 40 px along one spike of the first: the spike runs
    # through it, and the lamp is kept; the spike's events beyond it are covered
    yy, xx = np.mgrid[56:64, 136:144]
    n = 20 * xx.size
    lamp = make_events(
        np.arange(n) + 10_000, np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20), np.zeros(n)
    )
    spikes = merge_events(_ray(1, 8, 90), _ray(-1, 8, 90))
    ev = merge_events(_light(), lamp, spikes)
    on = in_streak_prior(ev, SIZE, 20_000)
    assert not on[np.isin(ev, lamp)].any()
    beyond = np.isin(ev, spikes) & (ev["x"] > 150)
    assert beyond.any() and on[beyond].all()


def test_the_compiled_angle_runs_are_the_polar_bins_filled_and_followed(rng):
    # _angle_runs bins, fills and follows in one loop; the same from the numpy steps
    from edeflare.rules.streak import (
        ANGLE_BINS,
        FILL_SHARE,
        MAX_GAP_BINS,
        RADIAL_BIN_PX,
        _angle_runs,
        _polar_bins,
    )

    cy, cx, start, n_rings, reach = 200.4, 310.7, 14.0, 40, 170.0
    r = rng.uniform(0, 180, 6000)
    a = rng.choice([0.3, 0.3 + np.pi, 2.0], 6000) + rng.normal(0, 0.02, 6000)
    pix = np.unique(np.stack([cy + r * np.sin(a), cx + r * np.cos(a)]).astype(np.int64), axis=1)
    sy, sx = pix  # sorted by row, as the prior's saturated pixels are
    run = _angle_runs(sy, sx, 0, sy.size, cy, cx, reach, start, n_rings, 8.0)
    near = np.abs(sx - cx) <= reach
    _, ring, tb = _polar_bins(sx[near] - cx, sy[near] - cy, start, n_rings)
    hot = np.bincount(tb * n_rings + ring, minlength=ANGLE_BINS * n_rings)
    mid = start + RADIAL_BIN_PX * (np.arange(n_rings) + 0.5)
    area = np.tile(2 * np.pi / ANGLE_BINS * RADIAL_BIN_PX * mid, ANGLE_BINS)
    filled = ((hot >= FILL_SHARE * area) | (area < 1.0)).reshape(ANGLE_BINS, n_rings)
    np.testing.assert_array_equal(run, _runs(filled, MAX_GAP_BINS))
    assert run.max() == n_rings and (run > 20).sum() >= 3  # the three spikes, to the end
    # too few saturated pixels for a run of 60 rings: none followed
    assert not _angle_runs(sy, sx, 0, 30, cy, cx, reach, start, n_rings, 200.0).any()


STAR_SIZE = (240, 240)
STAR_C = 120  # the star's centre, x and y


def _star(angles_deg, *, core=10, half_width=3, length=70, per_px=20) -> np.ndarray:
    """A light whose spikes pass the light test themselves: a disc of radius ``core``
    and arms ``2 half_width + 1`` px wide, ``length`` px from the centre, at the
    ``angles_deg``, ``per_px`` events at every pixel."""
    yy, xx = np.mgrid[: STAR_SIZE[1], : STAR_SIZE[0]]
    dy, dx = yy - STAR_C, xx - STAR_C
    on = np.hypot(dx, dy) <= core
    for a in np.radians(angles_deg):
        along = dx * np.cos(a) + dy * np.sin(a)
        across = np.abs(-dx * np.sin(a) + dy * np.cos(a))
        on |= (along >= 0) & (along <= length) & (across <= half_width)
    y, x = np.nonzero(on)
    n = per_px * x.size
    return make_events(
        np.arange(n) * 20_000 // n, np.tile(x, per_px), np.tile(y, per_px), np.ones(n)
    )


def _distance(ev: np.ndarray) -> np.ndarray:
    return np.hypot(ev["x"] - STAR_C, ev["y"] - STAR_C)


def test_a_star_bright_enough_to_be_the_light_loses_its_arms_and_keeps_its_centre():
    star = _star([0, 60, 120, 180, 240, 300])
    on = in_streak_prior(star, STAR_SIZE, 20_000)
    r = _distance(star)
    # its radius is the core's (the arms are narrower); the arms start 1.5 radii out
    assert not on[r <= 12].any()
    # nearly all of the arms (a few pixels fall in angle bins under the fill share)
    assert on[(r > 25) & (r < 65)].mean() > 0.9


def test_a_light_with_fewer_than_four_arms_keeps_them():
    # a lamp's tube or a moving light's stroke: two ends, opposite each other
    bar = _star([0, 180], half_width=6)
    assert not in_streak_prior(bar, STAR_SIZE, 20_000).any()
    three = _star([0, 120, 240])  # no arm has a partner
    assert not in_streak_prior(three, STAR_SIZE, 20_000).any()


def test_arms_inside_a_dense_scene_are_no_spikes():
    # a cross of lines through a lit window of a facade: four arms in opposite pairs,
    # but with the facade's saturated pixels at the angles between them
    cross = _star([0, 90, 180, 270])
    yy, xx = np.mgrid[STAR_C - 80 : STAR_C + 80, STAR_C - 80 : STAR_C + 80]
    lit = (yy % 4 != 0) & (xx % 4 != 0)  # rows of windows, dark between (56 % of pixels)
    yy, xx = yy[lit], xx[lit]
    n = 2 * xx.size
    facade = make_events(
        np.arange(n) * 20_000 // n, np.tile(xx.ravel(), 2), np.tile(yy.ravel(), 2), np.zeros(n)
    )
    assert in_streak_prior(cross, STAR_SIZE, 20_000).any()  # alone, it is a star
    ev = merge_events(cross, facade)
    assert not in_streak_prior(ev, STAR_SIZE, 20_000)[np.isin(ev, cross)].any()


def test_arm_angles_need_partners_and_dark_flanks():
    from edeflare.rules.streak import ANGLE_BINS, _arms

    run = np.zeros(ANGLE_BINS, dtype=np.int64)
    arms = [0, 40, 80, 120, 160, 200]  # six arms 60 degrees apart, 5 bins wide
    for a in arms:
        run[a : a + 5] = 20
    got = _arms(run, run, 5.0)
    np.testing.assert_array_equal(np.flatnonzero(got), np.flatnonzero(run))
    # the saturated pixels fill the angles between the arms: no spike stands out
    assert not _arms(run, np.full(ANGLE_BINS, 15), 5.0).any()
    # three arms, none opposite another
    three = np.zeros(ANGLE_BINS, dtype=np.int64)
    for a in (0, 80, 160):
        three[a : a + 5] = 20
    assert not _arms(three, three, 5.0).any()
    # an arm wider than ARM_MAX_DEG (60 degrees: 40 bins) is the body of something
    wide = run.copy()
    wide[0:45] = 20
    assert not _arms(wide, wide, 5.0)[0:45].any()


def test_a_lights_core_is_its_inscribed_discs_centre_not_its_mean():
    from edeflare.rules.streak import _centre, _core

    yy, xx = np.mgrid[:60, :120]
    own = np.hypot(yy - 30, xx - 30) <= 10  # a disc at (30, 30)
    own |= (np.abs(yy - 30) <= 2) & (xx >= 30) & (xx < 110)  # and one long arm to the right
    cy, cx = _core(own)
    assert (cy, cx) == (30.0, 30.0)
    assert _centre(own, 0, 0)[1] > 40  # the mean of its pixels leans towards the arm
