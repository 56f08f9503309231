"""Real paired captures: strobe alignment, glare cleaning, noise, crop and slicing, ``pair``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import kill_at_random_moments, random_events, same_events
from edeflare.cli import main
from edeflare.data.pairs import PairedWindows
from edeflare.errors import EventFileError, ParameterError
from edeflare.eval.evaluate import evaluate
from edeflare.events import EVENT_DTYPE, center_crop, make_events
from edeflare.io import read_events, write_events
from edeflare.io.sequence import list_sequences, read_sequence
from edeflare.lights import (
    Circle,
    Polygon,
    detect_light_source,
    light_mask,
    load_lights,
    parse_light,
    parse_lights,
)
from edeflare.realworld import (
    PairConfig,
    PairingError,
    Signature,
    clean_reference,
    draw_noise,
    estimate_background_rate,
    estimate_offset,
    glare_mask,
    inject_noise,
    pair_recordings,
    plot_alignment,
    polarity_signature,
    scan_recording,
)
from edeflare.realworld.align import _ncc

SIZE = (96, 72)
LIGHT = (48, 36, 4)  # cx, cy, r of the strobe in the synthetic scenes


def strobe_pass(
    rng: np.random.Generator,
    edges_us: np.ndarray,
    clock_shift_us: int,
    *,
    size: tuple[int, int] = SIZE,
    light: tuple[int, int, int] = LIGHT,
    per_px: int = 2,
    flare_events: int = 0,
    flare_radius: float = 0.0,
    noise_hz: float = 2.0,
    span_us: int | None = None,
    latency_us: float = 150.0,
) -> np.ndarray:
    """One pass over a strobe scene, on a clock that reads scene time + ``clock_shift_us``.

    At each edge (even: switch-on, odd: switch-off) every source pixel fires
    ``per_px`` events of that polarity, delayed by exponential latencies; the
    observation adds ``flare_events`` per edge spread over a disc of
    ``flare_radius`` (the filter's flare), so the passes differ in counts.
    Background noise covers ``[0, span_us)`` of the pass's own clock, so both
    recordings start near 0, as a camera's do.
    """
    width, height = size
    cx, cy, r = light
    yy, xx = np.mgrid[:height, :width]
    dist = np.hypot(xx - cx, yy - cy).ravel()
    source = np.flatnonzero(dist <= r)
    halo = np.flatnonzero((dist > r) & (dist <= flare_radius))
    span = span_us or int(edges_us[-1]) + clock_shift_us + 20_000
    parts = []
    for k, edge in enumerate(edges_us):
        pix = rng.choice(source, source.size * per_px)
        if flare_events:
            pix = np.concatenate([pix, rng.choice(halo, flare_events)])
        ev = np.empty(pix.size, EVENT_DTYPE)
        ev["t"] = edge + clock_shift_us + rng.exponential(latency_us, pix.size).astype(np.int64)
        ev["x"], ev["y"], ev["p"] = pix % width, pix // width, 1 - k % 2
        parts.append(ev)
    n = rng.poisson(noise_hz * width * height * span / 1e6)
    noise = np.empty(n, EVENT_DTYPE)
    noise["t"] = rng.integers(0, span, n)
    noise["x"], noise["y"], noise["p"] = (
        rng.integers(0, width, n),
        rng.integers(0, height, n),
        rng.integers(0, 2, n),
    )
    events = np.concatenate([*parts, noise])
    events = events[np.argsort(events["t"], kind="stable")]
    return events[(events["t"] >= 0) & (events["t"] < span)]


def random_edges(rng: np.random.Generator, n: int, start_us: int = 20_000) -> np.ndarray:
    """Switching times of a non-periodic strobe: on/off intervals of 1.5-8 ms."""
    return start_us + np.cumsum(rng.integers(1_500, 8_000, n))


def signatures(obs: np.ndarray, ref: np.ndarray, bin_us: int = 100) -> tuple[Signature, Signature]:
    return polarity_signature(obs, bin_us), polarity_signature(ref, bin_us)


# ----------------------------------------------------------------------------- signatures


def test_polarity_signature_counts_by_hand():
    ev = make_events(
        [95, 100, 150, 199, 200, 420, 500], [0, 1, 2, 0, 1, 2, 0], [0] * 7, [1, 1, 0, 1, 0, 0, 1]
    )
    sig = polarity_signature(ev, 100, t_start_us=100, t_end_us=500)  # [100, 500), 4 bins
    assert (sig.t_start_us, sig.bin_us, sig.n_bins, sig.t_end_us) == (100, 100, 4, 500)
    assert sig.on.tolist() == [2, 0, 0, 0] and sig.off.tolist() == [1, 1, 0, 1]
    g = 2 / 5
    assert sig.overall_on_fraction == pytest.approx(g)
    assert sig.on_fraction().tolist() == pytest.approx([2 / 3, 0.0, g, 0.0])
    assert sig.on_fraction(1.0).tolist() == pytest.approx([(2 + g) / 4, g / 2, g, g / 2])
    assert sig.imbalance().tolist() == pytest.approx([2 - 3 * g, -g, 0, -g])
    mask = np.zeros((1, 3), dtype=bool)
    mask[0, 1] = True  # only x == 1
    masked = polarity_signature(ev, 100, t_start_us=100, mask=mask)  # to the last event + 1
    assert masked.on.tolist() == [1, 0, 0, 0, 0] and masked.off.tolist() == [0, 1, 0, 0, 0]
    coarse = sig.rebin(3)
    assert coarse.on.tolist() == [2, 0] and coarse.off.tolist() == [2, 1]


def test_scan_of_a_file_equals_the_in_memory_figures(tmp_path, rng):
    events = random_events(rng, 30_000, SIZE, t0=5_000, span_us=400_000)
    path = tmp_path / "rec.h5"
    write_events(path, events, SIZE)
    scan = scan_recording(path, 250)
    assert scan.sensor_size == SIZE and scan.n_events == events.size
    assert (scan.t_first_us, scan.t_last_us) == (events["t"][0], events["t"][-1])
    ref = polarity_signature(events, 250)
    assert scan.signature.t_start_us == ref.t_start_us
    assert np.array_equal(scan.signature.on, ref.on) and np.array_equal(scan.signature.off, ref.off)
    flat = events["y"].astype(np.int64) * SIZE[0] + events["x"]
    assert np.array_equal(scan.counts.ravel(), np.bincount(flat, minlength=SIZE[0] * SIZE[1]))
    on = events["p"] == 1
    assert np.array_equal(scan.on_counts.ravel(), np.bincount(flat[on], minlength=96 * 72))


def test_normalised_cross_correlation_matches_numpy(rng):
    a = rng.normal(size=300)
    b = np.roll(a, 7)[:250] + 0.1 * rng.normal(size=250)
    lags = np.arange(-40, 41)
    expected = [
        np.corrcoef(a[max(0, -k) : min(300, 250 - k)], b[max(0, -k) + k : min(300, 250 - k) + k])[
            0, 1
        ]
        for k in lags
    ]
    fft = _ncc(a, b, lags, 10)  # > 64 lags: the FFT path
    direct = np.concatenate([_ncc(a, b, lags[:40], 10), _ncc(a, b, lags[40:], 10)])
    assert fft == pytest.approx(expected, abs=1e-9)
    assert direct == pytest.approx(expected, abs=1e-9)
    assert lags[np.argmax(fft)] == 7
    assert np.isnan(_ncc(a, b, np.array([245]), 10)).all()  # overlap of 5 < 10


# ----------------------------------------------------------------------------- alignment


@pytest.mark.parametrize("shift_us", [3_437, -12_345, 250_001])
def test_known_shift_is_recovered_within_16_us(shift_us):
    rng = np.random.default_rng(abs(shift_us))
    edges = random_edges(rng, 250)
    obs = strobe_pass(rng, edges, 0, flare_events=400, flare_radius=30)
    ref = strobe_pass(rng, edges, shift_us, per_px=1, noise_hz=3.0)
    assert obs.size > 2 * ref.size  # the filter's flare: very different counts
    a = estimate_offset(*signatures(obs, ref), max_offset_us=400_000, expected_offset_us=0)
    assert abs(a.offset_us - shift_us) < 16  # the claim of the README and the tutorial
    assert a.confidence > 0.4 and not a.at_edge
    assert a.correlation > a.second_peak + 0.4
    assert a.search_us == (-400_000, 400_000) and a.bin_us == 1_000 and a.refine_bin_us == 100


def test_offset_error_over_40_random_pairs_is_the_documented_one():
    """README and tutorial: error below 16 µs, RMS below 8 µs, offsets up to ±0.5 s."""
    errors = []
    for seed in range(40):
        rng = np.random.default_rng(seed)
        shift_us = int(rng.integers(-500_000, 500_001))
        edges = random_edges(rng, 250)
        obs = strobe_pass(rng, edges, 0, flare_events=400, flare_radius=30)
        ref = strobe_pass(rng, edges, shift_us, per_px=1, noise_hz=3.0)
        sigs = signatures(obs, ref)
        a = estimate_offset(*sigs, max_offset_us=600_000, expected_offset_us=0)
        errors.append(a.offset_us - shift_us)
    errors = np.abs(errors)
    assert errors.max() < 16 and np.sqrt(np.mean(errors**2)) < 8


def test_default_search_centre_aligns_the_first_events():
    rng = np.random.default_rng(1)
    edges = random_edges(rng, 150)
    obs = strobe_pass(rng, edges, 0)
    ref = strobe_pass(rng, edges, 3_437)
    ref["t"] += 7_000_000  # a clock that started elsewhere: the prior absorbs it
    a = estimate_offset(*signatures(obs, ref), max_offset_us=50_000)
    assert abs(a.offset_us - 7_003_437) < 16


def test_periodic_strobe_is_exact_within_half_a_period_and_ambiguous_beyond():
    rng = np.random.default_rng(2)
    edges = 20_000 + 5_000 * np.arange(200)  # 100 Hz square wave: period 10 ms
    obs = strobe_pass(rng, edges, 0, flare_events=300, flare_radius=30)
    ref = strobe_pass(rng, edges, 3_437)
    sigs = signatures(obs, ref)
    near = estimate_offset(*sigs, max_offset_us=4_900, expected_offset_us=0)
    assert abs(near.offset_us - 3_437) < 16 and near.confidence > 0.5
    wide = estimate_offset(*sigs, max_offset_us=50_000, expected_offset_us=0)
    assert wide.second_peak > 0.9 * wide.correlation  # one period away fits as well
    assert wide.confidence < 0.1
    assert abs((wide.offset_us - 3_437) % 10_000 - 5_000) > 4_900  # right phase, any period


def test_a_peak_at_the_edge_of_the_search_range_has_no_confidence():
    rng = np.random.default_rng(3)
    edges = random_edges(rng, 150)
    obs = strobe_pass(rng, edges, 0)
    sigs = signatures(obs, strobe_pass(rng, edges, 10_600))  # just beyond the range
    a = estimate_offset(*sigs, max_offset_us=10_000, expected_offset_us=0)
    assert a.at_edge and a.confidence == 0.0 and a.offset_us == pytest.approx(10_000, abs=50)
    assert "at the edge" in a.describe()
    assert a.to_dict()["at_edge"] is True
    sigs = signatures(obs, strobe_pass(rng, edges, 30_000))  # far beyond: only noise matches
    assert estimate_offset(*sigs, max_offset_us=10_000, expected_offset_us=0).confidence < 0.1


def test_estimate_offset_rejects_bad_input():
    sig = Signature(0, 100, np.array([5, 0] * 50), np.array([0, 5] * 50))
    other = Signature(0, 200, sig.on, sig.off)
    with pytest.raises(ParameterError, match="different bins"):
        estimate_offset(sig, other)
    with pytest.raises(ParameterError, match="multiple"):
        estimate_offset(sig, sig, bin_us=250)
    empty = Signature(0, 100, np.zeros(10, np.int64), np.zeros(10, np.int64))
    with pytest.raises(PairingError, match="reference signature holds no events"):
        estimate_offset(sig, empty)
    with pytest.raises(PairingError, match="overlap"):
        estimate_offset(sig, sig, max_offset_us=1_000, expected_offset_us=50_000)


def test_plot_alignment_writes_a_png(tmp_path):
    rng = np.random.default_rng(4)
    edges = random_edges(rng, 60)
    obs, ref = strobe_pass(rng, edges, 0), strobe_pass(rng, edges, 2_000)
    sigs = signatures(obs, ref)
    a = estimate_offset(*sigs, max_offset_us=20_000)
    path = tmp_path / "plot" / "a.png"
    image = plot_alignment(*sigs, a, path)
    assert image.shape == (760, 1000, 3) and image.dtype == np.uint8
    assert path.stat().st_size > 10_000
    assert (image != 255).any(axis=2).sum() > 20_000  # curves, axes and text were drawn


# ----------------------------------------------------------------------------- geometry


def test_parse_lights_from_strings_and_json(tmp_path):
    assert parse_light(" Circle: 320, 240.5, 15 ") == Circle(320, 240.5, 15)
    assert parse_light("polygon:1,2,3,4,5,6") == Polygon(((1, 2), (3, 4), (5, 6)))
    path = tmp_path / "lights.json"
    path.write_text(
        json.dumps(
            {
                "lights": [
                    {"type": "circle", "cx": 1, "cy": 2, "r": 3},
                    {"type": "polygon", "points": [[0, 0], [4, 0], [4, 4]]},
                    "circle:9,9,1",
                ]
            }
        )
    )
    lights = parse_lights(["circle:5,5,2", str(path)])
    assert [str(s.shape) for s in lights] == [
        "circle:5,5,2",
        "circle:1,2,3",
        "polygon:0,0,4,0,4,4",
        "circle:9,9,1",
    ]
    assert [parse_light(str(s.shape)) for s in lights] == [s.shape for s in lights]  # round trip
    # the older layout of a pairing's lights loads as fixed sources of the one type
    assert load_lights(path).sources == tuple(lights[1:])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("circle:1,2", "a circle needs 3 numbers"),
        ("circle:1,2,0", "radius must be positive"),
        ("circle:1,2,x", "'x' is not a number"),
        ("circle:1,2,nan", "not a finite number"),
        ("polygon:0,0,1,1", "even number (>= 6)"),
        ("polygon:0,0,1,1,2", "even number (>= 6)"),
        ("square:1,2,3", "expected circle:CX,CY,R"),
        ("320,240,15", "expected circle:CX,CY,R"),
    ],
)
def test_bad_light_strings_say_what_is_expected(text, message):
    with pytest.raises(ParameterError) as exc:
        parse_light(text)
    assert message in str(exc.value) and repr(text) in str(exc.value)


def test_bad_light_files_name_the_file(tmp_path):
    with pytest.raises(EventFileError, match=r"missing\.json: no such file"):
        load_lights(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('[{"type": "circle", "cx": 1, "cy": 2}]')
    with pytest.raises(
        EventFileError, match=r"bad.json: light 0: a circle needs exactly cx, cy, r"
    ):
        load_lights(bad)
    bad.write_text("{not json")
    with pytest.raises(EventFileError, match=r"bad\.json: is not a JSON file"):
        load_lights(bad)


def test_light_masks_by_hand():
    circle = Circle(5, 4, 2)
    expected = {(x, y) for x in range(12) for y in range(10) if (x - 5) ** 2 + (y - 4) ** 2 <= 4}
    ys, xs = np.nonzero(circle.mask((12, 10)))
    assert set(zip(xs.tolist(), ys.tolist(), strict=True)) == expected and len(expected) == 13
    rect = Polygon(((2, 1), (6, 1), (6, 4), (2, 4)))  # pixels 2 <= x < 6, 1 <= y < 4
    mask = rect.mask((8, 6))
    assert mask.sum() == 12 and mask[1:4, 2:6].all()
    triangle = Polygon(((0, 0), (4, 0), (0, 4)))  # x + y < 4, edges half-open
    ys, xs = np.nonzero(triangle.mask((6, 6)))
    assert set(zip(xs.tolist(), ys.tolist(), strict=True)) == {
        (x, y) for x in range(6) for y in range(6) if x + y < 4
    }
    off = Circle(-50, -50, 3)
    assert not light_mask([off], (8, 6)).any()
    assert light_mask([circle, rect], (12, 10)).sum() == len(
        expected | {(x, y) for x in range(2, 6) for y in range(1, 4)}
    )


def test_glare_mask_is_the_ring_around_a_circle_and_the_band_around_a_polygon():
    size = (40, 30)
    yy, xx = np.mgrid[:30, :40]
    ring = glare_mask([Circle(20, 15, 3)], size, 5)
    d = np.hypot(xx - 20, yy - 15)
    assert np.array_equal(ring, (d > 3) & (d <= 8))
    square = Polygon(((10, 10), (20, 10), (20, 20), (10, 20)))  # pixels 10..19
    band = glare_mask([square], size, 2)
    dx = np.maximum(np.maximum(10 - xx, xx - 20), 0)
    dy = np.maximum(np.maximum(10 - yy, yy - 20), 0)
    inside = (xx >= 10) & (xx < 20) & (yy >= 10) & (yy < 20)
    assert np.array_equal(band, (np.hypot(dx, dy) <= 2) & ~inside)
    assert not glare_mask([Circle(20, 15, 3)], size, 0).any()
    with pytest.raises(ParameterError, match="glare_radius_px"):
        glare_mask([], size, -1)


def test_clean_reference_removes_exactly_the_glare_zone(rng):
    size = (40, 30)
    events = random_events(rng, 20_000, size)
    before = events.copy()
    lights = [Circle(10, 10, 3), Polygon(((25, 5), (35, 5), (35, 12), (25, 12)))]
    cleaned = clean_reference(events, size, lights, glare_radius_px=4)
    zone = glare_mask(lights, size, 4)
    on_zone = zone[events["y"], events["x"]]
    assert same_events(cleaned, events[~on_zone])
    assert on_zone.sum() > 1000  # something was removed
    inside = light_mask(lights, size)[events["y"], events["x"]]
    assert inside.sum() > 500 and np.isin(np.flatnonzero(inside), np.flatnonzero(~on_zone)).all()
    assert same_events(events, before)  # input unchanged
    assert same_events(clean_reference(events, size, [], glare_radius_px=4), events)


def test_detect_light_source_finds_the_bright_disc(rng):
    height, width = 72, 96
    yy, xx = np.mgrid[:height, :width]
    counts = rng.poisson(3.0, (height, width)).astype(float)  # background
    d = np.hypot(xx - 60.3, yy - 25.6)
    counts += rng.poisson(np.where(d <= 5, 400.0, 0.0))  # the source
    counts += rng.poisson(60.0 * np.exp(-np.maximum(d - 5, 0) / 6))  # residual glare
    counts[5, 5] = 50_000  # a hot pixel
    counts[60, 10:14] = 900  # a short bright line (two pixels wide at most after filtering)
    (light,) = detect_light_source(counts)
    assert light.cx == pytest.approx(60.3, abs=0.5) and light.cy == pytest.approx(25.6, abs=0.5)
    assert light.mask((width, height))[d <= 5].all() and light.r < 7  # the rim stays a source
    counts += rng.poisson(np.where(np.hypot(xx - 20, yy - 50) <= 3, 300.0, 0.0))
    first, second = detect_light_source(counts, max_sources=2, level=0.2)
    assert round(first.cx) == 60 and (round(second.cx), round(second.cy)) == (20, 50)
    events = make_events([0, 1], [3, 4], [3, 4], [1, 1])
    with pytest.raises(ParameterError, match="no events"):
        detect_light_source(events, (10, 10))  # isolated pixels vanish in the median filter


# ----------------------------------------------------------------------------- noise


def test_background_rate_is_measured_in_quiet_regions(rng):
    size = (128, 96)
    seconds, rate, on_fraction = 5.0, 2.0, 0.4
    on = rng.poisson(rate * seconds * on_fraction, size[::-1])
    off = rng.poisson(rate * seconds * (1 - on_fraction), size[::-1])
    counts = on + off
    counts[10:50, 10:70] += rng.poisson(40.0, (40, 60))  # a moving object
    light = Circle(100, 70, 6)
    glare = glare_mask([light], size, 15)
    counts[light.mask(size) | glare] += 5_000  # the flare, excluded
    counts[80, 5] += 10_000  # a hot pixel
    est = estimate_background_rate(
        counts,
        int(seconds * 1e6),
        on_counts=on,
        exclude=light.mask(size) | glare,
    )
    se = math.sqrt(rate * seconds / est.pixels) / seconds  # Poisson SE of the pooled mean
    assert abs(est.rate_hz - rate) < 4 * se, (est, se)
    assert est.on_fraction == pytest.approx(on_fraction, abs=0.02)
    assert est.tiles >= 20 and est.pixels > 5_000  # the static tiles, not the object's
    with pytest.raises(ParameterError, match="no quiet region"):
        estimate_background_rate(counts, 1_000_000, exclude=np.ones(size[::-1], dtype=bool))


def test_injected_noise_matches_the_target_rate_statistically(rng):
    size = (80, 60)
    mask = glare_mask([Circle(40, 30, 5)], size, 20)
    rate, t0, t1 = 7.5, 1_000_000, 3_000_000
    noise = draw_noise(size, rate, t0, t1, mask=mask, on_fraction=0.3, rng=rng)
    expected = rate * 2.0 * mask.sum()
    assert abs(noise.size - expected) < 4 * math.sqrt(expected)
    assert mask[noise["y"], noise["x"]].all()  # only on the mask
    assert noise["t"].min() >= t0 and noise["t"].max() < t1
    assert (np.diff(noise["t"]) >= 0).all()
    per_pixel = np.bincount(noise["y"].astype(int) * 80 + noise["x"], minlength=4800)[mask.ravel()]
    assert per_pixel.mean() == pytest.approx(15.0, rel=0.03)
    assert per_pixel.var() / per_pixel.mean() == pytest.approx(1.0, abs=0.12)  # Poisson
    assert noise["p"].mean() == pytest.approx(0.3, abs=4 * math.sqrt(0.21 / noise.size))
    assert same_events(
        draw_noise(size, rate, t0, t1, mask=mask, on_fraction=0.3, rng=5),
        draw_noise(size, rate, t0, t1, mask=mask, on_fraction=0.3, rng=5),
    )
    assert draw_noise(size, 0.0, t0, t1, rng=1).size == 0
    events = random_events(rng, 500, size, t0=t0, span_us=2_000_000)
    before = events.copy()
    merged = inject_noise(events, size, rate, t0, t1, mask=mask, rng=3)
    assert merged.size == events.size + draw_noise(size, rate, t0, t1, mask=mask, rng=3).size
    assert (np.diff(merged["t"]) >= 0).all() and same_events(events, before)
    with pytest.raises(ParameterError, match="rate_hz"):
        draw_noise(size, -1.0, t0, t1)


# ----------------------------------------------------------------------------- pipeline


def write_pair(tmp_path, shift_us=3_437, *, edges=None, n_edges=200, seed=0, name="scene"):
    """Observation and reference files of one synthetic strobe scene."""
    rng = np.random.default_rng(seed)
    edges = random_edges(rng, n_edges) if edges is None else edges
    obs = strobe_pass(rng, edges, 0, flare_events=500, flare_radius=25)
    ref = strobe_pass(rng, edges, shift_us, flare_events=60, flare_radius=9)  # residual glare
    obs_path, ref_path = tmp_path / f"{name}_obs.h5", tmp_path / f"{name}_ref.h5"
    write_events(obs_path, obs, SIZE)
    write_events(ref_path, ref, SIZE)
    return obs_path, ref_path, obs, ref


def test_pair_recordings_writes_exactly_the_expected_pairs(tmp_path):
    obs_path, ref_path, obs, ref = write_pair(tmp_path)
    out = tmp_path / "out"
    light = Circle(*LIGHT)
    config = PairConfig(
        name="s1",
        lights=(light,),
        glare_radius_px=8,
        crop=(64, 48),
        noise_rate_hz=0.0,
        max_offset_us=50_000,
    )
    report = pair_recordings(obs_path, ref_path, out, config, progress=False)
    a = report.alignment
    assert abs(a.offset_us - 3_437) < 16 and a.confidence > 0.4
    shift = round(a.offset_us)
    end = min(int(obs["t"][-1]), int(ref["t"][-1]) - shift) + 1
    n = (end - 100_000) // 100_000  # windows from 100 ms (the first one starting after 0)
    assert [p.name for p in report.files] == [f"s1_{k:04d}.h5" for k in range(n)]
    assert list_sequences(out / "test") == report.files
    zone = glare_mask([light], SIZE, 8)
    for k, path in enumerate(report.files):
        start = 100_000 * (k + 1)
        inp, gt, size, t0, t1 = read_sequence(path)
        assert (size, t0, t1) == ((64, 48), start, start + 100_000)
        o = obs[(obs["t"] >= start) & (obs["t"] < start + 100_000)]
        r = ref[(ref["t"] >= start + shift) & (ref["t"] < start + shift + 100_000)].copy()
        r["t"] -= shift
        r = r[~zone[r["y"], r["x"]]]
        assert same_events(inp, center_crop(o, SIZE, (64, 48))[0])
        assert same_events(gt, center_crop(r, SIZE, (64, 48))[0])
        assert same_events(read_events(out / "test" / "input" / path.name).events, inp)
        assert same_events(read_events(out / "test" / "gt" / path.name).events, gt)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == "edeflare-pairs/1" and manifest["sensor_size"] == [64, 48]
    scene = manifest["scenes"]["s1"]
    assert scene["alignment"]["offset_us"] == pytest.approx(a.offset_us, abs=1e-3)
    assert scene["lights"] == [light.to_dict()]
    assert scene["lights_in_crop"] == [Circle(32, 24, 4).to_dict()]
    assert scene["crop"] == {"x0": 16, "y0": 12, "width": 64, "height": 48}
    assert scene["observation"]["file"] == obs_path.name and scene["windows"] == n
    assert scene["events"]["removed"] > 500 and scene["events"]["noise"] == 0
    assert [f["file"] for f in manifest["files"]] == [f"test/s1_{k:04d}.h5" for k in range(n)]
    assert (out / scene["plot"]).is_file()
    # The training dataset and the evaluation read it unchanged.
    ds = PairedWindows(report.files)
    assert len(ds) == 5 * n and ds[0][0].shape == (1, 8, 48, 64)
    result = evaluate(out / "test" / "gt", {"raw": out / "test" / "input"})
    assert result.methods["raw"].n_segments == 5 * n


def test_pair_injects_measured_noise_into_the_cleaned_zone(tmp_path):
    obs_path, ref_path, *_ = write_pair(tmp_path, seed=1)
    out = tmp_path / "out"
    config = PairConfig(detect_light=True, glare_radius_px=10, crop=None, max_offset_us=50_000)
    report = pair_recordings(obs_path, ref_path, out, config, progress=False)
    (light,) = report.lights
    assert (light.cx, light.cy) == pytest.approx(LIGHT[:2], abs=0.7)
    assert report.noise is not None and report.noise.rate_hz == pytest.approx(2.0, rel=0.05)
    zone = glare_mask(report.lights, SIZE, 10)
    in_zone = 0
    for path in report.files:
        _, gt, size, *_ = read_sequence(path)
        assert size == SIZE
        in_zone += int(zone[gt["y"], gt["x"]].sum())
    expected = report.noise_rate_hz * 0.1 * zone.sum() * len(report.files)
    assert abs(in_zone - expected) < 4 * math.sqrt(expected)  # only the injected noise is left
    assert report.entry["noise"]["region_pixels"] == zone.sum()


def test_cli_pair_then_benchmark_and_evaluate(tmp_path, capsys):
    obs_path, ref_path, *_ = write_pair(tmp_path)
    out = tmp_path / "bench"
    argv = ["pair", str(obs_path), str(ref_path), str(out), "--light", "circle:48,36,4"]
    argv += ["--glare-radius", "8", "--crop", "64x48", "--max-offset-ms", "50", "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "scene_obs: offset 3.4" in printed and "windows of 100 ms at 64x48" in printed
    assert main(["benchmark", str(out / "test"), "--methods", "raw", "pfd-b"]) == 0
    assert "| raw (input) |" in capsys.readouterr().out
    argv = ["evaluate", "--gt", str(out / "test" / "gt"), "--pred", f"raw={out / 'test' / 'input'}"]
    assert main(argv) == 0
    assert "| raw (input) |" in capsys.readouterr().out


def test_a_rerun_after_a_kill_finishes_cleanly_and_scenes_accumulate(tmp_path):
    obs_path, ref_path, *_ = write_pair(tmp_path)
    out = tmp_path / "out"
    config = PairConfig(name="a", lights=(Circle(*LIGHT),), crop=(64, 48), max_offset_us=50_000)
    first = pair_recordings(obs_path, ref_path, out, config, progress=False)
    manifest = (out / "manifest.json").read_text()
    # A killed run: no manifest yet, a temporary file and a window the new run will not write.
    (out / "manifest.json").unlink()
    (out / "test" / ".a_0000.h5.x.partial.h5").write_bytes(b"half")
    (out / "test" / "a_0042.h5").write_bytes(b"stale")
    (out / "test" / "gt" / "a_0042.h5").write_bytes(b"stale")
    again = pair_recordings(obs_path, ref_path, out, config, progress=False)
    assert (out / "manifest.json").read_text() == manifest  # bit-identical files and manifest
    assert (
        not (out / "test" / "a_0042.h5").exists()
        and not (out / "test" / "gt" / "a_0042.h5").exists()
    )
    assert again.files == first.files and list_sequences(out / "test") == first.files
    assert not list(out.rglob("*.partial.h5"))
    # A second scene joins the folder.
    obs2, ref2, *_ = write_pair(tmp_path, shift_us=-2_000, seed=7, name="other")
    pair_recordings(obs2, ref2, out, PairConfig(name="b", crop=(64, 48)), progress=False)
    data = json.loads((out / "manifest.json").read_text())
    assert sorted(data["scenes"]) == ["a", "b"]
    assert data["scenes"]["b"]["alignment"]["offset_us"] == pytest.approx(-2_000, abs=16)
    assert len(data["files"]) == len(list_sequences(out / "test"))
    with pytest.raises(PairingError, match="use the same crop"):
        pair_recordings(obs2, ref2, out, PairConfig(name="c", crop=(32, 24)), progress=False)


@pytest.mark.slow
def test_pair_killed_at_random_moments_leaves_no_partial_output_and_reruns_exactly(tmp_path):
    obs_path, ref_path, *_ = write_pair(tmp_path, n_edges=2_000)
    out = tmp_path / "out"
    argv = ["pair", str(obs_path), str(ref_path), str(out), "--light", "circle:48,36,4"]
    argv += ["--crop", "64x48", "--max-offset-ms", "50", "--no-progress"]
    killed = kill_at_random_moments(argv, out, tmp_path / "reference", range(4))
    assert killed >= 3
    assert not [p for p in out.rglob("*") if ".partial" in p.name]


def test_low_confidence_warns_or_refuses(tmp_path):
    edges = 20_000 + 5_000 * np.arange(200)  # periodic: ambiguous over a wide range
    obs_path, ref_path, *_ = write_pair(tmp_path, edges=edges)
    out = tmp_path / "out"
    config = PairConfig(crop=(64, 48), max_offset_us=100_000)
    with pytest.warns(UserWarning, match="low alignment confidence"):
        pair_recordings(obs_path, ref_path, out, config, progress=False)
    strict = PairConfig(crop=(64, 48), max_offset_us=100_000, min_confidence=0.3, name="strict")
    with pytest.raises(PairingError, match=r"confidence 0\.0\d+ is below 0\.3"):
        pair_recordings(obs_path, ref_path, out, strict, progress=False)
    assert not list((out / "test").glob("strict_*"))


@pytest.fixture
def pair_files(tmp_path):
    obs_path, ref_path, *_ = write_pair(tmp_path, n_edges=80)
    return obs_path, ref_path


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--light", "circle:1,2"], "light 'circle:1,2': a circle needs 3 numbers"),
        (["--light", "lights.json"], "lights.json: no such file"),
        (["--light", "circle:500,500,3"], "covers no pixel of the 96x72 sensor"),
        (["--crop", "640x480"], "does not fit the 96x72 sensor"),
        (["--window-ms", "100000"], "no complete 100000 ms window"),
        (["--min-confidence", "0.99"], "is below 0.99"),
        (
            ["--bin-ms", "0.25"],
            "--bin-ms 250 must be a multiple of --refine-bin-ms 100 "
            "(in µs; --bin-ms, --refine-bin-ms take ms)",
        ),
        (["--name", "../x"], "name must be"),
    ],
)
def test_cli_errors_are_one_line_and_write_nothing(
    pair_files, tmp_path, monkeypatch, capsys, extra, message
):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    argv = ["pair", *map(str, pair_files), str(out), "--crop", "64x48", "--max-offset-ms", "50"]
    assert main([*argv, *extra, "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("edeflare: error: ") and message in err, err
    assert err.count("\n") == 1
    assert not (out / "manifest.json").exists() and not list(out.rglob("*.h5"))


def test_bad_recordings_are_named(tmp_path, pair_files, capsys):
    obs_path, ref_path = pair_files
    small = tmp_path / "small.h5"
    write_events(small, make_events([0, 10], [0, 1], [0, 1], [1, 0]), (48, 36))
    empty = tmp_path / "empty.h5"
    write_events(empty, make_events([], [], [], []), SIZE)
    out = tmp_path / "out"
    assert main(["pair", str(obs_path), str(small), str(out), "--crop", "none"]) == 1
    assert "sensor 96x72 differs from the reference's 48x36" in capsys.readouterr().err
    assert main(["pair", str(obs_path), str(empty), str(out), "--crop", "none"]) == 1
    assert f"{empty}: holds no events" in capsys.readouterr().err
    (out).mkdir()
    (out / "manifest.json").write_text(json.dumps({"format": "edeflare-dataset/1"}))
    assert main(["pair", str(obs_path), str(ref_path), str(out), "--crop", "none"]) == 1
    assert "belongs to another kind of dataset" in capsys.readouterr().err
    assert not list(out.rglob("*.h5"))


def test_pair_config_rejects_bad_values():
    with pytest.raises(ParameterError, match="noise_region"):
        PairConfig(noise_region="everywhere")
    with pytest.raises(ParameterError, match="lights must be"):
        PairConfig(lights=("circle:1,2,3",))
    with pytest.raises(ParameterError, match="seed"):
        PairConfig(seed=-1)


# ----------------------------------------------------------------------------- real data


def test_real_flickering_lamps_align_with_a_disjoint_shifted_half(real_data):
    events, _ = read_events(real_data / "davis346_flicker_lamps.aedat4")
    rng = np.random.default_rng(0)
    half = rng.random(events.size) < 0.5  # two passes that share no event
    obs, ref = events[half], events[~half].copy()
    ref["t"] += 3_437
    keep = rng.random(ref.size) < 0.6  # and different event counts
    a = estimate_offset(
        *signatures(obs, ref[keep]), max_offset_us=4_000, expected_offset_us=0
    )  # lamps flicker at 100 Hz: search less than half a period
    assert abs(a.offset_us - 3_437) < 2 and a.confidence > 0.5  # the README's "within 2 µs"
