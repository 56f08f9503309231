"""The one registry: names, parameters, errors; CLI options made from parameter dataclasses."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from edeflare._registry import Registry, cli_option, param_defaults
from edeflare.ablate import ABLATIONS
from edeflare.baselines.efr import EFRFilter, EFRParams
from edeflare.baselines.pfd import PFDFilter, PFDParams
from edeflare.cli import build_parser
from edeflare.data.kinds import DATASET_KINDS
from edeflare.data.recipe import RECIPES
from edeflare.errors import ParameterError
from edeflare.methods import METHODS, method_parameters
from edeflare.models import MODELS
from edeflare.train import TRAIN_PRESETS


@dataclasses.dataclass(frozen=True)
class _Params:
    size_us: int = dataclasses.field(
        default=3_000, metadata=cli_option("--size-ms", "a size", unit="ms", type=float)
    )
    on: bool = dataclasses.field(default=False, metadata=cli_option("--on", "on", kind="flag"))


def test_register_create_and_errors():
    reg: Registry = Registry("widget")
    reg.register("a", lambda size_us=3_000, on=False: (size_us, on), params=_Params)
    assert reg.create("a", size_us=5) == (5, False)
    assert list(reg) == ["a"] and "a" in reg and len(reg) == 1
    with pytest.raises(
        ParameterError, match="widget 'a' has no parameters 'x', 'y'; valid: size_us, on"
    ):
        reg.create("a", x=1, y=2)
    with pytest.raises(ParameterError, match="unknown widget 'b'; registered widgets: a"):
        reg["b"]
    with pytest.raises(ParameterError, match="widget 'a' is already registered"):
        reg.register("a", print)
    with pytest.raises(ParameterError, match="non-empty string"):
        reg.register("", print)
    assert param_defaults(_Params) == {"size_us": 3_000, "on": False}


def test_every_registry_has_the_same_shape():
    for reg in (METHODS, MODELS, RECIPES, TRAIN_PRESETS, ABLATIONS, DATASET_KINDS):
        assert isinstance(reg, Registry) and reg.names() == sorted(reg)
        with pytest.raises(ParameterError, match=f"unknown {reg.kind} 'nope'"):
            reg["nope"]


def test_parameters_are_declared_once():
    assert method_parameters("efr") == param_defaults(EFRParams)
    assert method_parameters("pfd-a") == param_defaults(PFDParams)
    efr = EFRFilter((2, 2))
    assert (efr.frequency_hz, efr.rho1) == (EFRParams.frequency_hz, EFRParams.rho1)
    pfd = PFDFilter((2, 2))
    assert (pfd.window_us, pfd.fifo_size) == (PFDParams.window_us, PFDParams.fifo_size)


def test_deflare_options_come_from_the_parameter_dataclasses():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    flags = {s for a in sub.choices["deflare"]._actions for s in a.option_strings}
    for name in METHODS:
        params = METHODS.params(name)
        if params is None:
            continue
        for f in dataclasses.fields(params):
            opt = f.metadata.get("cli")
            if opt is not None:
                assert opt.flag in flags, (name, f.name)
    helps = {s: a.help for a in sub.choices["deflare"]._actions for s in a.option_strings if a.help}
    assert helps["--pfd-fifo-size"] == "flip times kept per pixel [5]"
    assert helps["--efr-merge-ms"] == "merge window [10]"
