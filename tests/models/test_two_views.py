"""Mask models judge each event in two windowings (aligned, and delayed by a quarter window)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from edeflare import deflare, read_events, write_events
from edeflare.errors import ParameterError
from edeflare.events import EVENT_DTYPE, make_events, select_events
from edeflare.methods import create_method, deflare_file
from edeflare.models import create_model
from edeflare.models.infer import ModelDeflarer
from edeflare.models.mask_kernels import keep_logit_threshold
from edeflare.models.two_view import TwoViewStreamer
from edeflare.models.weights import ModelCard, save_model

SIZE = (40, 30)


def _fake_logits(calls):
    """+2 in aligned windows, -4 in the delayed window starting at 15 ms, else 0."""

    def logits(batch):
        calls.append([(start, ev.size) for start, ev in batch])
        out = []
        for start, ev in batch:
            value = 2.0 if start % 20_000 == 0 else (-4.0 if start == 15_000 else 0.0)
            out.append(np.full(ev.size, value))
        return out

    return logits


def test_two_views_keep_where_the_mean_logit_passes_by_hand():
    t = np.arange(0, 40_000, 1_000)
    ev = make_events(t, t % 7, t % 5, np.ones(t.size, int))
    calls = []
    streamer = TwoViewStreamer(20_000, 5_000, _fake_logits(calls), cut=0.0, batch_windows=4)
    out = np.concatenate([streamer.process(ev, 40_000), streamer.flush()])
    # [0, 15): views +2 and 0 (window from -5 ms): kept; [15, 20) and [20, 35): +2 and -4:
    # dropped; [35, 40): +2 and 0 (window from 35 ms): kept
    assert out["t"].tolist() == [*range(0, 15_000, 1_000), *range(35_000, 40_000, 1_000)]
    starts = sorted(s for batch in calls for s, _ in batch)
    assert starts == [-5_000, 0, 15_000, 20_000, 35_000]


def test_numpy_blas_runs_one_thread_per_view_while_both_views_run():
    from threadpoolctl import ThreadpoolController

    blas = ThreadpoolController().select(user_api="blas")
    if not blas.lib_controllers:
        pytest.skip("numpy's BLAS cannot be limited here")
    seen = []

    def logits(batch):  # a head's matrix products run here, in both views' threads
        seen.append({c["num_threads"] for c in blas.info()})
        return [np.zeros(ev.size) for _, ev in batch]

    t = np.arange(0, 40_000, 1_000)
    ev = make_events(t, t % 7, t % 5, np.ones(t.size, int))
    with blas.limit(limits=2):  # as on a 2-core machine, whatever this one has
        s = TwoViewStreamer(20_000, 5_000, logits, cut=-1.0, batch_windows=1)
        assert np.concatenate([s.process(ev, 40_000), s.flush()]).size == ev.size
        after = {c["num_threads"] for c in blas.info()}
    both = seen[:-1]  # the last batch (the flush) runs alone
    assert both and all(v == {1} for v in both)
    assert after == {2}  # restored once the views are done


def test_the_second_view_runs_on_one_thread_for_the_whole_stream():
    # the per-event kernels keep their frames per thread (16 MB at 1280x720): a thread
    # per window zeroed fresh frames every window
    import threading

    threads = []

    def logits(batch):
        threads.append(threading.current_thread())
        return [np.zeros(ev.size) for _, ev in batch]

    t = np.arange(0, 100_000, 1_000)
    ev = make_events(t, t % 7, t % 5, np.ones(t.size, int))
    s = TwoViewStreamer(20_000, 5_000, logits, cut=-1.0, batch_windows=1)
    warmed = []
    s.warm_up(lambda: warmed.append(threading.current_thread()))
    out = [s.process(ev[(ev["t"] >= a) & (ev["t"] < a + 20_000)], a + 20_000)
           for a in range(0, 100_000, 20_000)]  # fmt: skip
    main = threading.current_thread()
    second = {th for th in threads if th is not main}
    assert len(threads) > 8 and len(second) == 1  # both views of each window, one helper
    (helper,) = second
    assert warmed == [helper]  # the warm-up ran on the thread the second view then used
    assert helper.is_alive()
    assert np.concatenate([*out, s.flush()]).size == ev.size
    assert not helper.is_alive()  # the flush ends the stream and its thread


def test_two_views_emit_events_once_both_windows_are_done_and_chunks_change_nothing():
    t = np.arange(0, 40_000, 1_000)
    ev = make_events(t, t % 7, t % 5, np.ones(t.size, int))
    one = TwoViewStreamer(20_000, 5_000, _fake_logits([]), cut=0.0, batch_windows=1)
    whole = np.concatenate([one.process(ev, 40_000), one.flush()])
    s = TwoViewStreamer(20_000, 5_000, _fake_logits([]), cut=0.0, batch_windows=1)
    first = s.process(ev[ev["t"] < 16_000], 16_000)
    # at 16 ms the aligned window [0, 20) is open: nothing can be decided yet
    assert first.size == 0
    second = s.process(ev[(ev["t"] >= 16_000) & (ev["t"] < 36_000)], 36_000)
    # [0, 20) and [15, 35) are done (and [-5, 15)): events before 20 ms are decided
    assert second["t"].tolist() == list(range(0, 15_000, 1_000))
    rest = np.concatenate([s.process(ev[ev["t"] >= 36_000], 40_000), s.flush()])
    assert np.array_equal(np.concatenate([first, second, rest]), whole)


@pytest.fixture(scope="module")
def pixel_weights(tmp_path_factory):
    """A ``mask.pixel`` with random weights, so that it keeps some events and drops some."""
    torch.manual_seed(3)
    net = create_model("mask.pixel").eval()
    with torch.no_grad():
        for p in net.parameters():
            p.add_(0.3 * torch.randn_like(p))
    path = tmp_path_factory.mktemp("w") / "pixel.safetensors"
    save_model(path, net, ModelCard(preset="mask.pixel"))
    return path


@pytest.fixture
def stream():
    rng = np.random.default_rng(5)
    n = 6_000
    return make_events(
        np.sort(rng.integers(3_000, 97_000, n)),
        rng.integers(0, SIZE[0], n),
        rng.integers(0, SIZE[1], n),
        rng.integers(0, 2, n),
    )


def test_the_model_method_averages_the_two_views_logits(pixel_weights, stream):
    d = ModelDeflarer(pixel_weights)
    views = []
    for delay in (0, 5_000):
        start = (stream["t"] + delay) // 20_000 * 20_000 - delay
        v = np.empty(stream.size)
        for s in np.unique(start):
            sel = start == s
            (v[sel],) = d.window_logits([(int(s), stream[sel])], SIZE)
        views.append(v)
    cut = keep_logit_threshold(0.5)
    expected = select_events(stream, (views[0] + views[1]) / 2 > cut)
    got = deflare(stream, SIZE, "model", weights=pixel_weights)
    assert np.array_equal(got, expected)
    one = select_events(stream, views[0] > cut)
    assert not np.array_equal(one, expected)  # the second view changes decisions here
    assert np.array_equal(
        deflare(stream, SIZE, "model", weights=pixel_weights, phase_shift_us=0), one
    )


def test_the_model_deflarer_gives_the_same_result_as_deflare(pixel_weights, stream):
    # the two-view logic is the model's: its deflarer and the method agree, both views
    d = ModelDeflarer(pixel_weights)
    assert np.array_equal(d(stream, SIZE), deflare(stream, SIZE, "model", weights=pixel_weights))
    assert np.array_equal(
        d(stream, SIZE, phase_shift_us=0),
        deflare(stream, SIZE, "model", weights=pixel_weights, phase_shift_us=0),
    )
    assert not np.array_equal(d(stream, SIZE), d(stream, SIZE, phase_shift_us=0))


def test_streaming_a_file_with_two_views_equals_one_pass(pixel_weights, stream, tmp_path):
    src, out = tmp_path / "in.h5", tmp_path / "out.h5"
    write_events(src, stream, SIZE)
    method = create_method("model", weights=pixel_weights)
    deflare_file(src, out, method, 7_000, progress=False)  # chunks that are not windows
    got, size = read_events(out)
    assert size == SIZE and np.array_equal(got, method(stream, SIZE))
    empty = method(np.zeros(0, dtype=EVENT_DTYPE), SIZE)
    assert empty.size == 0


def test_phase_shift_is_checked(pixel_weights, tmp_path):
    voxel = tmp_path / "tiny.safetensors"
    save_model(voxel, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny"))
    assert create_method("model", weights=voxel).params["phase_shift_us"] == 0
    assert create_method("model", weights=pixel_weights).params["phase_shift_us"] == 5_000
    with pytest.raises(ParameterError, match=r"needs a mask model; .*tiny.safetensors"):
        create_method("model", weights=voxel, phase_shift_us=5_000)
    for bad in (-1, 20_000, 2.5, True):
        with pytest.raises(ParameterError, match=r"phase_shift_us must be an int in \[0, 20000\)"):
            create_method("model", weights=pixel_weights, phase_shift_us=bad)
