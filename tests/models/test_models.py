"""Model presets: the paper's parameter count, identity at initialisation, any input size."""

from __future__ import annotations

import pytest
import torch

from edeflare.models import create_model, get_preset, list_models, register_model
from edeflare.models.blocks import ResBlock3d
from edeflare.models.unet3d import ResidualUNet3d


def test_paper_preset_has_the_papers_parameter_count():
    model = create_model("unet3d.paper")
    assert sum(p.numel() for p in model.parameters()) == 7_068_961
    assert model.features == (32, 64, 128, 256)


@pytest.mark.parametrize("name", list_models())
def test_every_preset_is_the_identity_at_init_on_odd_sizes(name):
    torch.manual_seed(0)
    model = create_model(name).eval()
    x = torch.randn(2, 1, 8, 26, 35)  # neither size a multiple of 8
    with torch.no_grad():
        y = model(x)
    assert y.shape == x.shape
    assert torch.equal(y, x)


@pytest.mark.parametrize("name", list_models())
def test_every_preset_learns_a_non_identity_map(name):
    torch.manual_seed(0)
    model = create_model(name)
    x = torch.randn(1, 1, 8, 16, 16)
    loss = (model(x) - 0.5 * x).pow(2).mean()
    loss.backward()
    final = [m for m in model.modules() if hasattr(m, "weight") and m.weight is not None][-1]
    assert final.weight.grad is not None and final.weight.grad.abs().sum() > 0


def test_unet3d_pools_all_axes_down_to_one_bin():
    net = ResidualUNet3d()
    seen = []
    net.ups[0].register_forward_hook(lambda m, i, o: seen.append(tuple(i[0].shape)))
    net(torch.zeros(1, 1, 8, 16, 16))
    assert seen == [(1, 256, 1, 2, 2)]  # the bottom level has one time bin


def test_wrong_input_shapes_are_rejected():
    model = create_model("unet2d.lite")
    with pytest.raises(ValueError, match=r"\(N, 1, 8, H, W\)"):
        model(torch.zeros(1, 1, 4, 8, 8))
    with pytest.raises(ValueError, match="N, 1, T, H, W"):
        create_model("unet3d.lite")(torch.zeros(1, 8, 8, 8))


def test_registry_errors_list_valid_names():
    with pytest.raises(ValueError, match=r"unknown model 'nope'; registered models: "):
        create_model("nope")
    with pytest.raises(ValueError, match="already registered"):
        register_model(get_preset("unet3d.paper"))


def test_block_groups_must_divide_channels():
    with pytest.raises(ValueError, match="groups"):
        ResBlock3d(1, 10, groups=4)
