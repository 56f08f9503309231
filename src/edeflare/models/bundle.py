"""A trained run's weights as a bundled model: the tensors copied, the card's fields set.

A run's ``model.safetensors`` carries the card that training wrote (preset,
command, training data folder, validation metrics). Bundling copies its
tensors unchanged into a new file whose card says how the model was made and
how to use it: the data's description, the keep threshold and priors of a
mask model, the scores measured after training. The bundled models in
``edeflare/assets`` are made this way (``edeflare bundle``). Both kinds of
weights files are handled: de-flaring models (:class:`~edeflare.models.weights.ModelCard`)
and reconstructors (:class:`~edeflare.recon.weights.ReconCard`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import types
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import torch

from ..errors import ParameterError
from ..rules import knob_fields
from .weights import (
    ModelCard,
    WeightsError,
    read_metadata,
    read_tensors,
    write_tensors,
)

__all__ = ["bundle_weights", "parse_card_fields"]

_MODEL_KEY = "edeflare_card"
_RECON_KEY = "edeflare_recon_card"  # edeflare.recon.weights


def parse_card_fields(pairs: Sequence[str], card_type: type = ModelCard) -> dict[str, Any]:
    """``KEY=VALUE`` strings (as on the command line) as the fields of a ``card_type``.

    A text field (``command``, ``data``, ``notes``) takes VALUE as written (a
    JSON string literal is unquoted); any other takes VALUE read as JSON where
    it parses, else the string (which :func:`bundle_weights` then refuses for a
    number field, saying so).

    Examples
    --------
    >>> parse_card_fields(["keep_threshold=0.4", "seed=null", 'metrics={"a": 1}'])
    {'keep_threshold': 0.4, 'seed': None, 'metrics': {'a': 1}}
    >>> parse_card_fields(['data={"sequences": 3}', "notes=a mask model", 'command="x"'])
    {'data': '{"sequences": 3}', 'notes': 'a mask model', 'command': 'x'}
    >>> parse_card_fields(["seed"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: card fields look like KEY=VALUE (...), got 'seed'
    """
    hints = typing.get_type_hints(card_type)
    fields: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key:
            raise ParameterError(
                f"card fields look like KEY=VALUE (e.g. keep_threshold=0.4), got {pair!r}"
            )
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text
        if hints.get(key) is str and not isinstance(value, str):
            value = text  # a text field holds what was written, JSON-like or not
        fields[key] = value
    return fields


def bundle_weights(
    weights: str | os.PathLike[str],
    out: str | os.PathLike[str],
    fields: Mapping[str, Any] | None = None,
    *,
    assignments: Sequence[str] = (),
    metrics: Mapping[str, Any] | None = None,
    half: bool = False,
) -> dict[str, Any]:
    """Copy the tensors of ``weights`` to ``out`` (atomically) with card fields set.

    Parameters
    ----------
    weights : path-like
        A de-flaring model's or a reconstructor's ``.safetensors`` file.
    out : path-like
        The file to write (may be ``weights`` itself).
    fields : mapping, optional
        Card fields to set, e.g. ``{"keep_threshold": 0.4, "data": "..."}``.
        Unknown fields and values of the wrong type are errors; an int is
        accepted for a float field.
    assignments : sequence of str
        More fields as ``KEY=VALUE`` strings, as the command line gives them
        (:func:`parse_card_fields` for the card's type), set after ``fields``.
    metrics : mapping, optional
        Merged into the card's ``metrics`` (after ``fields``).
    half : bool
        Store floating-point tensors as float16 (half the size; loading casts
        them back to the model's float32).

    Returns
    -------
    dict
        The new card.

    Raises
    ------
    WeightsError
        ``weights`` is not an edeflare weights file, or its tensors do not fit
        the new card (e.g. another preset).
    ParameterError
        An unknown field or a value of the wrong type.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.models import create_model
    >>> from edeflare.models.weights import read_card, save_model
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> save_model(d / "run.safetensors", create_model("mask.fast"), ModelCard(preset="mask.fast"))
    >>> card = bundle_weights(d / "run.safetensors", d / "out.safetensors",
    ...                       {"keep_threshold": 0.4, "halo_shift": 3}, metrics={"score": 0.9})
    >>> c = read_card(d / "out.safetensors")
    >>> c.keep_threshold, c.rules, c.metrics
    (0.4, {'halo_shift': 3.0}, {'score': 0.9})
    """
    path = Path(weights)
    meta = read_metadata(path)
    if _MODEL_KEY in meta:
        key, card_type = _MODEL_KEY, ModelCard
    elif _RECON_KEY in meta:
        from ..recon.weights import ReconCard

        key, card_type = _RECON_KEY, ReconCard
    else:
        raise WeightsError(f"{path}: no edeflare model or reconstructor card in the metadata")
    try:
        card = json.loads(meta[key])
    except json.JSONDecodeError as exc:
        raise WeightsError(f"{path}: the card is not JSON ({exc})") from None
    changes = {**(fields or {}), **parse_card_fields(assignments, card_type)}
    card = _with_fields(card_type, card, changes)
    if metrics:
        card["metrics"] = {**card.get("metrics", {}), **dict(metrics)}
    card = card_type.from_dict(card).to_dict()  # type: ignore[attr-defined]
    if card.get("unlit_model"):  # found where it will be loaded from, or refused now
        from .infer import unlit_model_file

        unlit_model_file(card["unlit_model"], out)
    tensors = read_tensors(path)
    _check_fits(path, tensors, key, card)
    if half:
        tensors = {k: v.half() if v.is_floating_point() else v for k, v in tensors.items()}
    write_tensors(out, tensors, key, card)
    return card


def _with_fields(card_type: type, card: dict[str, Any], fields: dict[str, Any]) -> dict[str, Any]:
    """``card`` with ``fields`` set, each checked against the card type's annotation."""
    hints = typing.get_type_hints(card_type)
    known = [f.name for f in dataclasses.fields(card_type)]
    # a model card's rules are set knob by knob (edeflare.rules checks each)
    knobs = set(knob_fields()) if card_type is ModelCard else set()
    unknown = sorted(set(fields) - set(known) - knobs)
    if unknown:
        valid = ", ".join(known + sorted(knobs))
        raise ParameterError(f"unknown {card_type.__name__} field(s) {unknown}; valid: {valid}")
    out = dict(card)
    for name, value in fields.items():
        if name in knobs:
            out["rules"] = {**out.get("rules", {}), name: value}
        else:
            out[name] = _checked(name, value, hints[name])
    return out


def _checked(name: str, value: Any, hint: Any) -> Any:
    """``value`` if it is of type ``hint`` (an int made float for a float field)."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        allowed = tuple(typing.get_origin(a) or a for a in typing.get_args(hint))
    else:
        allowed = (typing.get_origin(hint) or hint,)
    if float in allowed and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, bool) and bool not in allowed:
        ok = False
    else:
        ok = isinstance(value, allowed)
    if not ok:
        names = " or ".join("null" if a is type(None) else a.__name__ for a in allowed)
        raise ParameterError(f"card field {name!r} must be {names}, got {value!r}")
    return value


def _check_fits(path: Path, tensors: dict[str, torch.Tensor], key: str, card: dict) -> None:
    """Raise unless ``tensors`` are exactly those of the model ``card`` describes."""
    if key == _MODEL_KEY:
        from .weights import card_model

        expected = card_model(path, card["preset"], card.get("head")).state_dict()
        what = f"preset {card['preset']!r}" + (" with its keep head" if card.get("head") else "")
    else:
        from ..recon.network import FireNet

        expected = FireNet(card["bins"], card["features"]).state_dict()
        what = f"a FireNet of {card['bins']} bins and {card['features']} features"
    wrong = sorted(set(expected) ^ set(tensors)) or sorted(
        k for k in expected if tensors[k].shape != expected[k].shape
    )
    if wrong:
        raise WeightsError(f"{path}: tensors do not fit {what} ({wrong[:3]})")
