"""Weights on disk: safetensors plus a JSON model card; never a pickle.

A weights file is a ``.safetensors`` file whose metadata holds
``edeflare_card``: the :class:`ModelCard` (preset name, bins, window, the
command, data recipe and seed that trained it, its metrics). Loading
checks the card's preset and every tensor's name and shape against a fresh
model of that preset before copying the values, so a file of another
preset, a truncated file or a pickle gives a clear error and no model.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file
from torch import nn

from ..errors import EdeflareError, ParameterError
from ..io._atomic import atomic_path
from ..rules import RuleSet, knob_fields
from . import create_model, get_preset
from .event_head import build_head, head_spec

__all__ = [
    "ModelCard",
    "WeightsError",
    "init_from",
    "load_model",
    "read_card",
    "read_metadata",
    "read_tensors",
    "save_model",
    "write_tensors",
    "write_weights",
]

_CARD_KEY = "edeflare_card"


class WeightsError(EdeflareError):
    """A weights file is missing, corrupt, a pickle, or does not fit its preset."""


@dataclass(frozen=True)
class ModelCard:
    """What a weights file is and how it was made.

    Examples
    --------
    >>> card = ModelCard(preset="unet2d.lite", seed=3)
    >>> ModelCard.from_dict(card.to_dict()) == card
    True
    """

    preset: str
    bins: int = 8
    window_us: int = 20_000
    command: str = ""
    data: str = ""
    seed: int | None = None
    metrics: dict[str, Any] = field(default_factory=dict)
    notes: str = ""
    keep_threshold: float = 0.5  # mask models: keep an event above this keep probability
    rules: dict[str, Any] = field(default_factory=dict)
    """Mask models: the rules' knobs this model sets (:mod:`edeflare.rules`; the rest off)."""
    head: dict[str, Any] = field(default_factory=dict)
    """Mask models: the learned per-event keep head's layout (feature names, hidden
    widths; :class:`~edeflare.models.event_head.EventHead`), empty for none."""
    unlit_model: str = ""
    """Mask models: another mask model (a bundled model's name, or a weights file named
    relative to this one's folder) that judges the windows where the light test finds no
    light (:attr:`~edeflare.rules.context.WindowContext.has_lights`); empty: this model
    judges every window (:class:`~edeflare.models.infer.ModelDeflarer`)."""

    def __post_init__(self) -> None:
        if not isinstance(self.unlit_model, str):
            raise WeightsError(
                f"model card: unlit_model must be text (a model's name or file), "
                f"got {self.unlit_model!r}"
            )
        try:
            RuleSet(self.rules)
            if self.head:
                object.__setattr__(self, "head", head_spec(self.head, "head"))
        except ParameterError as exc:
            raise WeightsError(f"model card: {exc}") from None

    def rule_set(self) -> RuleSet:
        """The card's rules, checked (:class:`~edeflare.rules.RuleSet`)."""
        return RuleSet(self.rules)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (without ``head`` or ``unlit_model`` when there is none: older
        cards stay as they were)."""
        out = dataclasses.asdict(self)
        for key in ("head", "unlit_model"):
            if not out[key]:
                del out[key]
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelCard:
        """Build from a dict, rejecting unknown keys.

        A rule's knob at the top level (as cards written before the rules had one
        registry hold them: ``{"halo_shift": 3, ...}``) moves into ``rules``.

        Examples
        --------
        >>> ModelCard.from_dict({"preset": "mask.lite", "halo_shift": 3.0}).rules
        {'halo_shift': 3.0}
        """
        known = {f.name for f in dataclasses.fields(cls)}
        knobs = set(knob_fields())
        data = dict(data)
        rules = dict(data.pop("rules", None) or {})
        fields = knob_fields()
        for key in sorted(set(data) & knobs):
            value = data.pop(key)
            if value != fields[key][1].default:  # an older card names every knob, off ones too
                rules.setdefault(key, value)
        unknown = sorted(set(data) - known)
        if unknown:
            raise WeightsError(f"unknown model card keys {unknown}; known: {sorted(known)}")
        if "preset" not in data:
            raise WeightsError("model card lacks 'preset'")
        try:
            checked = RuleSet(rules)
        except ParameterError as exc:
            raise WeightsError(f"model card: {exc}") from None
        return cls(**data, rules={k: checked[k] for k in rules})


def save_model(path: str | os.PathLike[str], model: nn.Module, card: ModelCard) -> None:
    """Write ``model``'s weights and ``card`` to a ``.safetensors`` file, atomically.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.models import create_model
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "m.safetensors"
    >>> save_model(p, create_model("unet2d.lite"), ModelCard(preset="unet2d.lite"))
    >>> load_model(p)[1].preset
    'unet2d.lite'
    """
    get_preset(card.preset)
    write_weights(path, model, _CARD_KEY, card.to_dict())


def write_weights(
    path: str | os.PathLike[str], model: nn.Module, key: str, card: dict[str, Any]
) -> None:
    """Write ``model``'s tensors to a ``.safetensors`` file, atomically, with ``card`` as JSON
    under metadata ``key`` (the one writer of edeflare's weights files).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "w.safetensors"
    >>> write_weights(p, nn.Linear(2, 1), "my_card", {"n": 1})
    >>> read_metadata(p), sorted(read_tensors(p))
    ({'my_card': '{"n": 1}'}, ['bias', 'weight'])
    """
    tensors = {k: v.detach().cpu().contiguous() for k, v in model.state_dict().items()}
    write_tensors(path, tensors, key, card)


def write_tensors(
    path: str | os.PathLike[str], tensors: dict[str, torch.Tensor], key: str, card: dict[str, Any]
) -> None:
    """Write ``tensors`` to a ``.safetensors`` file, atomically, with ``card`` as JSON under
    metadata ``key`` (what :func:`write_weights` does with a model's state).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "t.safetensors"
    >>> write_tensors(p, {"w": torch.zeros(2, dtype=torch.float16)}, "my_card", {"n": 2})
    >>> read_metadata(p), read_tensors(p)["w"].dtype
    ({'my_card': '{"n": 2}'}, torch.float16)
    """
    with atomic_path(Path(path)) as tmp:
        save_file(tensors, str(tmp), metadata={key: json.dumps(card)})


def read_metadata(path: Path) -> dict[str, str]:
    """The metadata of a weights file, without loading tensors (pickles refused)."""
    _check_file(path)
    try:
        from safetensors import safe_open

        with safe_open(str(path), framework="pt") as f:
            return f.metadata() or {}
    except (SafetensorError, OSError, ValueError) as exc:
        raise WeightsError(f"{path}: not a readable safetensors file ({exc})") from None


def read_tensors(path: Path) -> dict[str, torch.Tensor]:
    """The tensors of a weights file (a clear error for a corrupt one)."""
    try:
        return load_file(str(path))
    except (SafetensorError, OSError, ValueError) as exc:
        raise WeightsError(f"{path}: corrupt weights ({exc})") from None


def _check_file(path: Path) -> None:
    if not path.is_file():
        raise WeightsError(f"{path}: no such weights file")
    with open(path, "rb") as f:
        head = f.read(9)
    # safetensors: an 8-byte little-endian header length, then the JSON header "{...".
    # torch.save writes a zip ("PK"), older pickles start with the PROTO opcode 0x80.
    if head[8:9] != b"{" and (head[:2] == b"PK" or head[:1] == b"\x80"):
        raise WeightsError(
            f"{path}: looks like a pickle/torch.save file; edeflare only loads safetensors "
            "(pickles can run code)"
        )


def read_card(path: str | os.PathLike[str]) -> ModelCard:
    """The model card of a weights file (or of an exported ``.onnx``), without loading tensors."""
    path = Path(path)
    if path.suffix.lower() == ".onnx":
        from .export import read_onnx_card

        return read_onnx_card(path)
    meta = read_metadata(path)
    if _CARD_KEY not in meta:
        raise WeightsError(f"{path}: no edeflare model card in the metadata")
    try:
        return ModelCard.from_dict(json.loads(meta[_CARD_KEY]))
    except json.JSONDecodeError as exc:
        raise WeightsError(f"{path}: model card is not JSON ({exc})") from None


def init_from(model: nn.Module, path: str | os.PathLike[str]) -> list[str]:
    """Load the weights of ``path`` into ``model`` to fine-tune it; return the tensors left fresh.

    Every tensor of the file must exist in ``model`` with the same shape; the
    model may have more (layers a preset adds to the one the file was trained
    as, e.g. ``mask.pixel``'s refinement on ``mask.fast``), which keep their
    initial values and are returned by name.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.models import create_model
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "fast.safetensors"
    >>> save_model(p, create_model("mask.fast"), ModelCard(preset="mask.fast"))
    >>> init_from(create_model("mask.pixel"), p)
    ['pixel_gain', 'pixel_in.bias', 'pixel_in.weight', 'pixel_out.bias', 'pixel_out.weight']
    """
    path = Path(path)
    read_card(path)  # a safetensors file of edeflare's, not a pickle
    tensors = read_tensors(path)
    expected = model.state_dict()
    extra = sorted(set(tensors) - set(expected))
    wrong = sorted(k for k in tensors if k in expected and tensors[k].shape != expected[k].shape)
    if extra or wrong:
        raise WeightsError(
            f"{path}: cannot start {type(model).__name__} from these weights "
            f"(unexpected {extra[:3]}, other shapes {wrong[:3]})"
        )
    model.load_state_dict(tensors, strict=False)
    return sorted(set(expected) - set(tensors))


def card_model(path: Path, preset: str, head: Mapping[str, Any] | None) -> nn.Module:
    """A fresh model of a card's ``preset``, with its learned keep ``head`` (if any) as
    the submodule ``head``: the module whose tensors ``path`` must hold."""
    try:
        model = create_model(preset)
    except ValueError as exc:
        raise WeightsError(f"{path}: {exc}") from None
    if head:  # the learned keep head rides with the network, as its submodule
        model.head = build_head(head)
        context = model.head.context
        bins = getattr(model, "bins", None)
        if context and bins is not None and context["inputs"] != 4 * bins + 1:
            raise WeightsError(
                f"{path}: the keep head's context reads {context['inputs']} channels of cells; "
                f"a {preset} network gives {4 * bins + 1} ({bins} bins)"
            )
    return model


def load_model(
    path: str | os.PathLike[str], device: str | torch.device = "cpu"
) -> tuple[nn.Module, ModelCard]:
    """Build the card's preset and load the weights into it: ``(model in eval mode, card)``."""
    path = Path(path)
    card = read_card(path)
    model = card_model(path, card.preset, card.head)
    tensors = read_tensors(path)
    expected = model.state_dict()
    missing = sorted(set(expected) - set(tensors))
    extra = sorted(set(tensors) - set(expected))
    if missing or extra:
        raise WeightsError(
            f"{path}: tensors do not fit preset {card.preset!r} "
            f"(missing {missing[:3]}, unexpected {extra[:3]})"
        )
    for name, value in tensors.items():
        if value.shape != expected[name].shape:
            raise WeightsError(
                f"{path}: tensor {name} has shape {tuple(value.shape)}, preset {card.preset!r} "
                f"needs {tuple(expected[name].shape)}"
            )
    model.load_state_dict(tensors)
    return model.to(device).eval(), card
