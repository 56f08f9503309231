"""A model of two experts: the card's ``unlit_model`` judges the windows where the light
test finds no light, the model itself the others."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from edeflare import deflare
from edeflare.errors import EdeflareError
from edeflare.events import concat_events, make_events
from edeflare.models import create_model
from edeflare.models.event_head import EventHead
from edeflare.models.infer import ModelDeflarer
from edeflare.models.weights import ModelCard, WeightsError, read_card, save_model
from edeflare.rules.context import WindowContext

SIZE = (64, 48)
WINDOW = 20_000


def constant_head(logit: float) -> EventHead:
    """A head whose keep logit is ``logit`` for every event."""
    head = EventHead(["net_logit"], hidden=())
    with torch.no_grad():
        head.layers[0].weight.zero_()
        head.layers[0].bias.fill_(logit)
    return head


def save_expert(path, logit, *, threshold=0.5, unlit="", window_us=WINDOW):
    torch.manual_seed(0)
    net = create_model("mask.lite")
    net.head = constant_head(logit)
    card = ModelCard(
        preset="mask.lite",
        keep_threshold=threshold,
        window_us=window_us,
        head=net.head.spec(),
        unlit_model=unlit,
    )
    save_model(path, net, card)
    return path


def light_and_dark_windows() -> tuple[np.ndarray, list[bool]]:
    """Two windows: a 12x12 block firing 20 events per pixel (a light) among scattered
    events, then scattered events alone; and whether the light test finds a light."""
    rng = np.random.default_rng(1)

    def scatter(t0: int, k: int) -> np.ndarray:
        return make_events(
            t0 + np.sort(rng.integers(0, WINDOW, k)), rng.integers(0, SIZE[0], k),
            rng.integers(0, SIZE[1], k), rng.integers(0, 2, k),
        )  # fmt: skip

    yy, xx = np.mgrid[20:32, 30:42]
    k = 20 * xx.size
    block = make_events(
        np.arange(k) * WINDOW // k, np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20),
        np.ones(k, np.int64),
    )  # fmt: skip
    first = concat_events([scatter(0, 200), block])
    first = first[np.argsort(first["t"], kind="stable")]
    second = scatter(WINDOW, 200)
    found = [WindowContext(w, SIZE, WINDOW).has_lights for w in (first, second)]
    return concat_events([first, second]), found


def test_the_unlit_expert_judges_the_windows_without_a_light(tmp_path):
    ev, found = light_and_dark_windows()
    assert found == [True, False]
    save_expert(tmp_path / "drop.safetensors", -100.0)
    gated = save_expert(tmp_path / "keep.safetensors", 100.0, unlit="drop.safetensors")
    out = deflare(ev, SIZE, "model", weights=gated, phase_shift_us=0)
    # the lit window's events all kept (the model's own head), the dark window's all dropped
    assert out.size == np.count_nonzero(ev["t"] < WINDOW)
    assert (out["t"] < WINDOW).all()
    # and the other way round
    save_expert(tmp_path / "keep2.safetensors", 100.0)
    other = save_expert(tmp_path / "drop2.safetensors", -100.0, unlit="keep2.safetensors")
    out = deflare(ev, SIZE, "model", weights=other, phase_shift_us=0)
    assert out.size == np.count_nonzero(ev["t"] >= WINDOW) and (out["t"] >= WINDOW).all()


def test_each_window_logit_is_one_experts_own(tmp_path):
    ev, _ = light_and_dark_windows()
    dark = ModelDeflarer(save_expert(tmp_path / "a.safetensors", -1.5), runtime="torch")
    lit = ModelDeflarer(save_expert(tmp_path / "b.safetensors", 2.0), runtime="torch")
    gated = ModelDeflarer(
        save_expert(tmp_path / "g.safetensors", 2.0, unlit="a.safetensors"), runtime="torch"
    )
    batch = [(0, ev[ev["t"] < WINDOW]), (WINDOW, ev[ev["t"] >= WINDOW])]
    got = gated.window_logits(batch, SIZE)
    np.testing.assert_array_equal(got[0], lit.window_logits(batch[:1], SIZE)[0])
    np.testing.assert_array_equal(got[1], dark.window_logits(batch[1:], SIZE)[0])
    assert got[1] == pytest.approx(-1.5)


def test_the_unlit_experts_logits_move_onto_the_cards_threshold(tmp_path):
    ev, _ = light_and_dark_windows()
    # keep probability sigma(0 + ln 3) = 0.75: kept at its own threshold 0.5, dropped at 0.8
    p = 0.0
    save_expert(tmp_path / "strict.safetensors", p, threshold=0.8)
    save_expert(tmp_path / "loose.safetensors", p, threshold=0.5)
    for unlit, kept in (("strict.safetensors", False), ("loose.safetensors", True)):
        gated = save_expert(tmp_path / "g.safetensors", 100.0, threshold=0.5, unlit=unlit)
        out = deflare(ev, SIZE, "model", weights=gated, phase_shift_us=0)
        dark = np.count_nonzero(out["t"] >= WINDOW)
        assert dark == (np.count_nonzero(ev["t"] >= WINDOW) if kept else 0), unlit
    d = ModelDeflarer(gated, runtime="torch")
    assert d.unlit is not None and d._unlit_shift == 0.0
    d = ModelDeflarer(
        save_expert(tmp_path / "g2.safetensors", 1.0, threshold=0.5, unlit="strict.safetensors"),
        runtime="torch",
    )
    assert d._unlit_shift == pytest.approx(0.0 - math.log(0.8 / 0.2), abs=1e-6)


def test_the_card_names_the_unlit_model_only_where_there_is_one(tmp_path):
    assert "unlit_model" not in ModelCard(preset="mask.lite").to_dict()
    card = ModelCard.from_dict({"preset": "mask.lite", "unlit_model": "learned"})
    assert card.unlit_model == "learned" and card.to_dict()["unlit_model"] == "learned"
    save_expert(tmp_path / "a.safetensors", 0.0)
    save_expert(tmp_path / "g.safetensors", 0.0, unlit="a.safetensors")
    assert read_card(tmp_path / "g.safetensors").unlit_model == "a.safetensors"
    with pytest.raises(WeightsError, match="unlit_model must be text"):
        ModelCard.from_dict({"preset": "mask.lite", "unlit_model": 3})


def test_a_bundled_models_name_is_an_unlit_model(tmp_path):
    d = ModelDeflarer(save_expert(tmp_path / "g.safetensors", 0.0, unlit="learned-absolute"))
    assert d.unlit is not None and d.unlit.card.head and d.unlit.card.keep_threshold == 0.4


def test_bad_unlit_models_are_refused_naming_the_problem(tmp_path):
    bad = save_expert(tmp_path / "g.safetensors", 0.0, unlit="missing.safetensors")
    with pytest.raises(WeightsError, match=r"g.safetensors: its card's unlit_model 'missing"):
        ModelDeflarer(bad)
    with pytest.raises(EdeflareError, match="moonlight"):
        ModelDeflarer(save_expert(tmp_path / "n.safetensors", 0.0, unlit="moonlight"))
    save_expert(tmp_path / "b.safetensors", 0.0, unlit="learned-absolute")
    chain = save_expert(tmp_path / "c.safetensors", 0.0, unlit="b.safetensors")
    with pytest.raises(WeightsError, match="names an unlit_model of its own; one level only"):
        ModelDeflarer(chain)
    save_expert(tmp_path / "w.safetensors", 0.0, window_us=10_000)
    other = save_expert(tmp_path / "o.safetensors", 0.0, unlit="w.safetensors")
    with pytest.raises(WeightsError, match="10000 us windows, this model 20000 us"):
        ModelDeflarer(other)
    voxel = tmp_path / "v.safetensors"
    save_model(voxel, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny"))
    mixed = save_expert(tmp_path / "m.safetensors", 0.0, unlit="v.safetensors")
    with pytest.raises(WeightsError, match="both experts must be mask models"):
        ModelDeflarer(mixed)


def test_bundling_refuses_an_unlit_model_that_cannot_be_found(tmp_path):
    from edeflare.models.bundle import bundle_weights

    save_expert(tmp_path / "a.safetensors", 0.0)
    out = tmp_path / "out" / "g.safetensors"
    out.parent.mkdir()
    with pytest.raises(WeightsError, match=r"unlit_model 'a.safetensors' is not a file"):
        bundle_weights(tmp_path / "a.safetensors", out, assignments=["unlit_model=a.safetensors"])
    assert not out.exists()
    with pytest.raises(EdeflareError, match="moonlight"):
        bundle_weights(tmp_path / "a.safetensors", out, assignments=["unlit_model=moonlight"])
    card = bundle_weights(
        tmp_path / "a.safetensors", out, assignments=["unlit_model=learned-absolute"]
    )
    assert card["unlit_model"] == "learned-absolute" and ModelDeflarer(out).unlit is not None


def test_the_cards_rules_act_on_both_experts_windows(tmp_path):
    ev, _ = light_and_dark_windows()
    save_expert(tmp_path / "a.safetensors", -3.0)  # drops the dark window alone
    pair = save_expert(tmp_path / "g.safetensors", 2.0, unlit="a.safetensors")
    batch = [(0, ev[ev["t"] < WINDOW]), (WINDOW, ev[ev["t"] >= WINDOW])]
    # the light-free rule raises every event of the dark window (the unlit expert's)
    plain = ModelDeflarer(pair, runtime="torch").window_logits(batch, SIZE)
    raised = ModelDeflarer(pair, runtime="torch", light_free_shift=5.0).window_logits(batch, SIZE)
    np.testing.assert_allclose(raised[1] - plain[1], 5.0)
    np.testing.assert_array_equal(raised[0], plain[0])
    lit = np.count_nonzero(ev["t"] < WINDOW)
    assert deflare(ev, SIZE, "model", weights=pair, phase_shift_us=0).size == lit
    kept = deflare(ev, SIZE, "model", weights=pair, light_free_shift=5.0, phase_shift_us=0)
    assert kept.size == ev.size
    # and the rule terms split them as de-flaring decides
    terms = ModelDeflarer(pair, runtime="torch").rule_terms(ev, SIZE, (0,))
    cut = -math.log(3.0)  # keep probability 0.5
    assert np.count_nonzero(terms.logits({}, views=[0]) > cut) == lit
    assert np.count_nonzero(terms.logits({"light_free_shift": 5.0}, views=[0]) > cut) == ev.size


def test_an_unlit_model_that_sets_rules_is_refused(tmp_path):
    torch.manual_seed(0)
    net = create_model("mask.lite")
    net.head = constant_head(0.0)
    card = ModelCard(preset="mask.lite", head=net.head.spec(), rules={"halo_shift": 3.0})
    save_model(tmp_path / "r.safetensors", net, card)
    pair = save_expert(tmp_path / "g.safetensors", 0.0, unlit="r.safetensors")
    with pytest.raises(WeightsError, match=r"sets rule knobs \['halo_shift'\]"):
        ModelDeflarer(pair)


def test_head_inputs_of_two_experts_are_refused(tmp_path):
    save_expert(tmp_path / "a.safetensors", 0.0)
    d = ModelDeflarer(save_expert(tmp_path / "g.safetensors", 0.0, unlit="a.safetensors"))
    with pytest.raises(EdeflareError, match="two experts"):
        d.head_inputs([(0, make_events([1], [1], [1], [1]))], SIZE)


def test_onnx_runtime_decides_as_torch_with_two_experts(tmp_path):
    pytest.importorskip("onnxruntime")
    ev, _ = light_and_dark_windows()
    save_expert(tmp_path / "a.safetensors", -100.0)
    gated = save_expert(tmp_path / "g.safetensors", 100.0, unlit="a.safetensors")
    a = deflare(ev, SIZE, "model", weights=gated, runtime="torch")
    b = deflare(ev, SIZE, "model", weights=gated, runtime="onnx")
    assert a.size == b.size and np.array_equal(a["t"], b["t"])
    assert ModelDeflarer(gated, runtime="onnx").unlit.runtime == "onnx"


def test_info_names_the_unlit_model(capsys):
    from edeflare.cli import main

    assert main(["info", "learned"]) == 0
    out = capsys.readouterr().out
    assert "unlit       learned-absolute judges the windows where no light is found" in out
    assert "; 16 count channels relative to the window's mean" in out
    assert main(["info", "learned-absolute"]) == 0
    assert "unlit " not in capsys.readouterr().out


def test_a_pairs_network_logits_for_training_are_its_networks_in_every_window():
    from edeflare.models.head_training import NetworkLogits
    from edeflare.models.infer import bundled_weights

    ev, found = light_and_dark_windows()
    batch = [(0, ev[ev["t"] < WINDOW]), (WINDOW, ev[ev["t"] >= WINDOW])]
    pair = NetworkLogits(bundled_weights("learned")).deflarer.window_logits(batch, SIZE)
    alone = NetworkLogits(bundled_weights("learned-absolute")).deflarer.window_logits(batch, SIZE)
    assert found == [True, False]
    for a, b in zip(pair, alone, strict=True):
        np.testing.assert_array_equal(a, b)  # night's network, no head, in both windows
