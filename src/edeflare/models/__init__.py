"""E-DeflareNet and lighter networks, created by name from a registry.

==================  ===========================================  ==========
name                architecture                                 parameters
==================  ===========================================  ==========
``unet3d.paper``    residual 3D U-Net, 32/64/128/256 (the paper)  7,068,961
``unet3d.lite``     residual 3D U-Net, 8/16/32/64                    442,441
``unet2d.lite``     residual 2D U-Net, bins as channels, 16/32/64    146,424
``unet2d.tiny``     residual 2D U-Net, bins as channels, 8/16/32      ~37 k
``mask.lite``       flare mask on 4x4-pixel cells, 8/16/32/64        150,096
``mask.fast``       flare mask on 8x8-pixel cells, 8/16/32/64        150,096
``mask.pixel``      ``mask.fast`` + per-pixel refinement (8 wide)    150,153
==================  ===========================================  ==========

The ``mask`` presets (:mod:`edeflare.models.flaremask`) estimate a keep
probability per cell below the sensor's resolution and decide per event.

Every model maps ``(N, 1, bins, H, W)`` voxel grids to grids of the same
shape, is the identity at initialisation, and takes any ``H, W``.

Examples
--------
>>> "unet3d.paper" in list_models()
True
>>> sum(p.numel() for p in create_model("unet3d.paper").parameters())
7068961
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from torch import nn

from .._registry import Registry
from .flaremask import FlareMaskNet
from .unet2d import ResidualUNet2d
from .unet3d import ResidualUNet3d

__all__ = ["MODELS", "ModelPreset", "create_model", "get_preset", "list_models", "register_model"]


@dataclass(frozen=True)
class ModelPreset:
    """A named architecture: the class to build and its fixed keyword arguments."""

    name: str
    builder: Callable[..., nn.Module]
    kwargs: dict[str, Any] = field(default_factory=dict)
    description: str = ""


MODELS: Registry[ModelPreset] = Registry("model")
"""The registered presets: name -> :class:`ModelPreset`."""


def register_model(preset: ModelPreset) -> ModelPreset:
    """Add a preset to the registry (a name can be registered once)."""
    return MODELS.register(preset.name, preset)


def list_models() -> list[str]:
    """Names of the registered model presets."""
    return MODELS.names()


def get_preset(name: str) -> ModelPreset:
    """The preset called ``name``; unknown names raise ``ParameterError`` (a ``ValueError``)
    listing the valid ones."""
    return MODELS[name]


def create_model(name: str) -> nn.Module:
    """Build a fresh (identity-initialised) model of the preset ``name``."""
    preset = get_preset(name)
    return preset.builder(**preset.kwargs)


register_model(
    ModelPreset(
        "unet3d.paper",
        ResidualUNet3d,
        {"features": (32, 64, 128, 256), "groups": 8},
        "E-DeflareNet as in the paper: 4-level residual 3D U-Net, 7.07 M parameters",
    )
)
register_model(
    ModelPreset(
        "unet3d.lite",
        ResidualUNet3d,
        {"features": (8, 16, 32, 64), "groups": 4},
        "the paper's architecture with a quarter of the features (CPU)",
    )
)
register_model(
    ModelPreset(
        "unet2d.lite",
        ResidualUNet2d,
        {"bins": 8, "features": (16, 32, 64), "groups": 8},
        "3-level residual 2D U-Net with the 8 bins as channels (fast on CPU)",
    )
)
register_model(
    ModelPreset(
        "unet2d.tiny",
        ResidualUNet2d,
        {"bins": 8, "features": (8, 16, 32), "groups": 4},
        "the 2D U-Net at half width, for the fastest CPU inference",
    )
)
register_model(
    ModelPreset(
        "mask.lite",
        FlareMaskNet,
        {"bins": 8, "scale": 4, "features": (8, 16, 32, 64), "groups": 4},
        "flare mask on 4x4-pixel cells, decided per event at full resolution",
    )
)
register_model(
    ModelPreset(
        "mask.fast",
        FlareMaskNet,
        {"bins": 8, "scale": 8, "features": (8, 16, 32, 64), "groups": 4},
        "flare mask on 8x8-pixel cells, for embedded use",
    )
)
register_model(
    ModelPreset(
        "mask.pixel",
        FlareMaskNet,
        {"bins": 8, "scale": 8, "features": (8, 16, 32, 64), "groups": 4, "pixel_hidden": 8},
        "mask.fast and a per-pixel refinement (a lone event or a hot pixel beside a light)",
    )
)
