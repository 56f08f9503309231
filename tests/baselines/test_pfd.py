"""Tests of edeflare.baselines.pfd: golden masks of the original, hand traces, known answers."""

from __future__ import annotations

import numpy as np
import pytest
from baseline_helpers import background_noise, moving_edge, pfd_reference, square_flicker

from conftest import random_events
from edeflare.baselines.pfd import PFDFilter, pfd, pfd_mask
from edeflare.errors import ParameterError
from edeflare.events import EVENT_DTYPE, make_events

# --------------------------------------------------------------------------------------
# Golden masks of the original program (shicy17/PFD @ 5618127, PFDs)

GOLDEN_PFD = [
    # file, input, score, switches, events kept
    ("mix640_pfda_keep.npy", "mix640", "A", {}, 335_710),
    ("mix640_pfdb_keep.npy", "mix640", "B", {}, 223_211),
    ("mix640_pfda_keep_dscore.npy", "mix640", "A", {"real_valued_score": True}, 291_429),
    ("mix640_pfdb_keep_dscore.npy", "mix640", "B", {"real_valued_score": True}, 48_570),
    ("mix640_pfda_keep_polupd.npy", "mix640", "A", {"flip_against_previous": True}, 345_600),
    ("mix640_pfdb_keep_polupd.npy", "mix640", "B", {"flip_against_previous": True}, 100_924),
    ("davis346_lamps_pfda_keep.npy", "davis346_lamps", "A", {}, 54_941),
    ("davis346_lamps_pfdb_keep.npy", "davis346_lamps", "B", {}, 23_038),
]


def load_npz(path):
    with np.load(path) as z:
        events = np.empty(z["t"].size, dtype=EVENT_DTYPE)
        for k in "txyp":
            events[k] = z[k]
        return events, (int(z["width"]), int(z["height"]))


@pytest.mark.parametrize(
    ("golden", "name", "score", "switches", "kept"),
    GOLDEN_PFD,
    ids=[g[0].removesuffix(".npy") for g in GOLDEN_PFD],
)
def test_reproduces_the_original_program_exactly(golden_data, golden, name, score, switches, kept):
    events, size = load_npz(golden_data / f"{name}_input.npz")
    expected = np.load(golden_data / golden)
    mask = pfd_mask(events, size, score=score, **switches)
    assert mask.dtype == bool and mask.shape == expected.shape
    assert int(mask.sum()) == kept
    assert np.array_equal(mask, expected)


def test_golden_mask_by_component(golden_data):
    """The README's per-component counts of PFD-B on mix640 (the faithful truncated score)."""
    events, size = load_npz(golden_data / "mix640_input.npz")
    with np.load(golden_data / "mix640_input.npz") as z:
        source = z["source"]
    mask = pfd_mask(events, size, score="B")
    kept = [int(mask[source == c].sum()) for c in range(4)]
    assert kept == [178_765, 2_237, 42_017, 192]


# --------------------------------------------------------------------------------------
# The plain-Python reference on random streams, and state across chunks

SWITCHES = [
    {},
    {"real_valued_score": True},
    {"flip_against_previous": True},
    {"flip_against_previous": True, "real_valued_score": True},
]


@pytest.mark.parametrize("score", ["A", "B"])
@pytest.mark.parametrize("switches", SWITCHES, ids=["original", "dscore", "polupd", "both"])
def test_matches_the_reference_on_random_streams(rng, score, switches):
    size = (12, 9)
    events = random_events(rng, 6000, size, t0=0, span_us=300_000)
    expected = pfd_reference(
        events,
        size,
        score,
        polupd=switches.get("flip_against_previous", False),
        dscore=switches.get("real_valued_score", False),
    )
    mask = pfd_mask(events, size, score=score, **switches)
    assert mask.tolist() == expected
    assert 0 < mask.sum() < mask.size


def test_matches_the_reference_with_other_parameters(rng):
    size = (7, 7)
    events = random_events(rng, 3000, size, span_us=200_000)
    expected = pfd_reference(events, size, "A", 5_000, 8_000, 2, 4, 3)
    mask = pfd_mask(events, size, 5_000, 8_000, 2, 4, score="A", fifo_size=3)
    assert mask.tolist() == expected


@pytest.mark.parametrize("score", ["A", "B"])
def test_chunks_equal_one_pass(rng, score):
    size = (16, 16)
    events = random_events(rng, 20_000, size, span_us=1_000_000)
    whole = pfd_mask(events, size, score=score)
    f = PFDFilter(size, score=score)
    cuts = np.sort(rng.integers(0, events.size, 15))
    parts = [f.mask(c) for c in np.split(events, cuts)]
    assert np.array_equal(np.concatenate(parts), whole)
    kept = np.concatenate([PFDFilter(size, score=score).filter(events)])
    assert np.array_equal(kept, events[whole])


# --------------------------------------------------------------------------------------
# Hand-traced steps


def test_flips_count_against_the_first_polarity_unless_switched():
    """ON, OFF, OFF at one pixel: the original counts two flips, the intended one."""
    ev = make_events([100, 200, 300], [1] * 3, [1] * 3, [1, 0, 0])
    f = PFDFilter((3, 3))
    f.mask(ev)
    assert f.pixel_state(1, 1)["flips"] == [200, 300]
    assert f.pixel_state(1, 1)["polarity"] == 1  # never updated
    g = PFDFilter((3, 3), flip_against_previous=True)
    g.mask(ev)
    assert g.pixel_state(1, 1)["flips"] == [200]
    assert g.pixel_state(1, 1)["polarity"] == -1


def test_flip_buffer_keeps_the_last_five():
    t = [100 * (i + 1) for i in range(8)]
    ev = make_events(t, [0] * 8, [0] * 8, [1, 0, 1, 0, 1, 0, 1, 0])  # ON first: OFFs flip
    f = PFDFilter((1, 1), flip_against_previous=True)  # then every change is a flip
    f.mask(ev)
    assert f.pixel_state(0, 0)["flips"] == t[3:]
    state = f.pixel_state(0, 0)
    assert (state["last_on"], state["last_off"], state["last_t"]) == (700, 800, 800)


def _block(t_first, polarity=1, skip=()):
    """The 8 neighbours of (1, 1) on a 3x3 sensor, one event each, 1 µs apart."""
    coords = [(x, y) for y in range(3) for x in range(3) if (x, y) != (1, 1) and (x, y) not in skip]
    t = [t_first + i for i in range(len(coords))]
    return make_events(t, [c[0] for c in coords], [c[1] for c in coords], [polarity] * len(t))


def test_stage1_needs_a_recent_same_polarity_neighbour():
    base = _block(1_000_000, polarity=1)
    for t_centre, p_centre, expected in (
        (1_000_100, 1, True),  # ON neighbours 100 µs before: pass
        (1_000_100, 0, False),  # no OFF neighbour ever: stage 1 fails
        (1_020_000, 1, True),  # the last neighbour at 1_000_007 is 19_993 µs old (< 20 ms)
        (1_020_008, 1, False),  # all 20_001+ µs old
    ):
        ev = np.concatenate([base, make_events([t_centre], [1], [1], [p_centre])])
        assert bool(pfd_mask(ev, (3, 3))[-1]) is expected, (t_centre, p_centre)


def test_time_zero_means_never():
    """An event at exactly t = 0 is invisible to its neighbours' stage 1 (0 = never)."""
    ev = make_events([0, 10], [0, 1], [0, 0], [1, 1])
    f = PFDFilter((3, 3), min_active=0)  # n_active > 0 suffices: isolate stage 1
    assert f.mask(ev).tolist() == [False, False]
    ev = make_events([1, 10], [0, 1], [0, 0], [1, 1])
    assert PFDFilter((3, 3), min_active=0).mask(ev).tolist() == [False, True]


def test_every_neighbour_is_active_during_the_first_window():
    """Last-event times start at 0: while t <= 20 ms every in-bounds neighbour counts."""
    for t0, expected in ((10_000, True), (19_999, True), (20_000, False), (5_000_000, False)):
        ev = make_events([t0, t0 + 1], [0, 1], [1, 1], [1, 1])  # one real neighbour only
        assert bool(pfd_mask(ev, (3, 3))[-1]) is expected, t0


def test_truncated_score_keeps_what_the_real_score_drops():
    """PFD-B score C_nbr / n_active = 12 / 8 = 1.5: int(1.5) = 1 <= 1, but 1.5 > 1."""
    t = 1_000_000
    neighbours = _block(t)
    flips = _block(t + 100, polarity=0)  # every neighbour flips once ...
    extra = _block(t + 200, polarity=0, skip=[(0, 0), (2, 0), (0, 2), (2, 2)])  # ... 4 twice
    centre = make_events([t + 300], [1], [1], [0])
    ev = np.concatenate([neighbours, flips, extra, centre])
    assert bool(pfd_mask(ev, (3, 3), score="B")[-1]) is True
    assert bool(pfd_mask(ev, (3, 3), score="B", real_valued_score=True)[-1]) is False
    # PFD-A on the same: |C_self - 12/8| = |0 - 1.5| = 1.5 (the centre never flipped)
    assert bool(pfd_mask(ev, (3, 3), score="A")[-1]) is True
    assert bool(pfd_mask(ev, (3, 3), score="A", real_valued_score=True)[-1]) is False


def test_an_events_own_flip_counts_in_its_score():
    """PFD-A with steady neighbours: the centre's own flips raise |C_self - 0| past 1."""
    t = 1_000_000
    corners = [(0, 0), (2, 0), (0, 2), (2, 2)]
    edges = [(1, 0), (0, 1), (2, 1), (1, 2)]
    neighbours = np.concatenate([_block(t, 1, skip=edges), _block(t + 4, 0, skip=corners)])
    centre = make_events([t + 10, t + 20, t + 30], [1] * 3, [1] * 3, [1, 0, 0])
    ev = np.concatenate([neighbours, centre])
    mask = pfd_mask(ev, (3, 3), score="A", real_valued_score=True)
    assert mask[-3:].tolist() == [True, True, False]  # C_self = 0, 1, 2


def test_sensor_edges_have_fewer_neighbours():
    """A corner has 3 in-bounds neighbours, never more than min_active = 3."""
    t = 1_000_000
    ev = np.concatenate([_block(t), make_events([t + 40, t + 50], [1, 0], [1, 0], [1, 1])])
    assert bool(pfd_mask(ev, (3, 3))[-1]) is False
    assert bool(pfd_mask(ev, (3, 3), min_active=2)[-1]) is True


# --------------------------------------------------------------------------------------
# Known answers on synthetic scenes


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(3)
    size, duration = (64, 48), 400_000
    # Lamp pixels with C_on < C_off: 2 ON and 1 or 2 OFF per period, each on its own phase.
    parts = [
        square_flicker(50, 4, 4, 14, duration, rng, n_on=2, n_off=(1, 2), sync=False),
        square_flicker(120, 36, 4, 14, duration, rng, n_on=2, n_off=(1, 2), sync=False),
        moving_edge(4, 60, 22, 10, duration, rng),
        background_noise(0.5, size, duration, rng, region=(0, 34, 64, 14)),
    ]
    labels = np.concatenate([np.full(p.size, i) for i, p in enumerate(parts)])
    events = np.concatenate(parts)
    order = np.argsort(events["t"], kind="stable")
    return events[order], size, labels[order]


def _kept(mask, labels, component):
    return mask[labels == component].mean()


def test_pfd_b_score_truncation_decides_the_50_hz_flicker(scene):
    """As in the golden README: truncated PFD-B keeps most of a 50 Hz flicker, real drops it."""
    events, size, labels = scene
    truncated = pfd_mask(events, size, score="B")
    real = pfd_mask(events, size, score="B", real_valued_score=True)
    # 1.5 flips per neighbour and 20 ms window: int(1.5) = 1 passes, 1.5 does not.
    assert _kept(truncated, labels, 0) >= 0.90  # measured 0.96
    assert _kept(real, labels, 0) <= 0.15  # measured 0.06
    assert _kept(truncated, labels, 1) <= 0.10  # 120 Hz: 3.6 flips per window, both drop
    assert _kept(real, labels, 1) <= 0.10


def test_pfd_a_removes_isolated_noise_and_keeps_dense_flicker(scene):
    events, size, labels = scene
    mask = pfd_mask(events, size, score="A")
    assert _kept(mask, labels, 3) <= 0.05  # background activity (measured 0.0)
    assert _kept(mask, labels, 0) >= 0.90  # measured 0.97
    assert _kept(mask, labels, 1) >= 0.85  # measured 0.94
    assert _kept(mask, labels, 2) >= 0.5  # the moving edge (measured 0.71)


def test_pfd_returns_the_kept_events_in_order(scene):
    events, size, _ = scene
    copy = events.copy()
    kept = pfd(events, size, score="B")
    assert np.array_equal(events, copy)
    assert np.array_equal(kept, events[pfd_mask(events, size, score="B")])
    assert kept.dtype == EVENT_DTYPE and np.all(np.diff(kept["t"]) >= 0)


# --------------------------------------------------------------------------------------
# Input handling


def test_empty_input():
    empty = np.zeros(0, dtype=EVENT_DTYPE)
    assert pfd_mask(empty, (4, 4)).shape == (0,)
    assert pfd(empty, (4, 4)).dtype == EVENT_DTYPE


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"score": "C"}, "score must be 'A' or 'B'"),
        ({"window_us": -1}, "window_us must be an int >= 0"),
        ({"stage1_window_us": 2.5}, "stage1_window_us must be an int"),
        ({"fifo_size": 0}, "fifo_size must be an int >= 1"),
        ({"fifo_size": 300}, "fifo_size must be at most 255"),
        ({"min_active": True}, "min_active must be an int"),
    ],
)
def test_bad_parameters_say_what_is_wrong(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        PFDFilter((4, 4), **kwargs)


def test_rejects_chunks_out_of_order():
    f = PFDFilter((4, 4))
    f.mask(make_events([100], [0], [0], [1]))
    with pytest.raises(ParameterError, match="time order"):
        f.mask(make_events([50], [0], [0], [1]))
