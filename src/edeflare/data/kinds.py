"""Dataset kinds: what one sequence of a recipe is, each kind registered at its definition.

A kind (``recipe.kind``) brings its own config dataclass (the recipe field
named by ``config_field``), its ``make_sequence(recipe, index, source)``
function and what a run checks before it starts. The built-in kinds:

- ``"flare"`` (:mod:`edeflare.data.eflare`): simulated training pairs
  (E-Flare-2.7K, eflare-mini), settings in the recipe's composition fields;
- ``"optics"`` (:mod:`edeflare.data.eflare_r_sim`): the optics test pairs,
  :class:`~edeflare.sim.optics_scene.OpticsSceneConfig` in ``recipe.optics``;
- ``"dsec"`` (:mod:`edeflare.data.dsec_flare`): windows of a local DSEC copy,
  :class:`~edeflare.data.dsec_flare.DsecFlareConfig` in ``recipe.dsec``.

This module imports no kind and no recipe: the kinds import it to register,
and :func:`get_kind` loads the built-in ones on first use.

Examples
--------
>>> list_kinds()
['dsec', 'flare', 'optics']
>>> get_kind("optics").config_field, get_kind("optics").test_only
('optics', True)
>>> get_kind("nope")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
edeflare.errors.ParameterError: unknown dataset kind 'nope'; registered dataset kinds: dsec, ...
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._registry import Registry
from ..errors import EdeflareError

__all__ = [
    "DATASET_KINDS",
    "KIND_OPTIONS",
    "STAGES",
    "DatasetKind",
    "GenerationError",
    "KindSequence",
    "get_kind",
    "list_kinds",
    "register_kind",
]

STAGES = ("background", "render", "simulate", "compose", "write")
"""Stages timed per sequence."""
KIND_OPTIONS = (
    "--sequences",
    "--test-sequences",
    "--variant",
    "--flare7k",
    "--no-components",
    "--background",
    "--dsec-root",
    "--dsec-window",
    "--rectify",
)
"""Options of ``edeflare simulate`` that apply to some kinds only (each kind lists its own)."""

_BUILTIN = ("eflare", "eflare_r_sim", "dsec_flare")


class GenerationError(EdeflareError, ValueError):
    """A dataset cannot be generated as asked (the message says why and what to do)."""


@dataclass(frozen=True)
class KindSequence:
    """What a kind's ``make_sequence`` returns.

    Attributes
    ----------
    streams : dict
        Group name -> events (``input`` always; ``gt`` and the components when
        the kind has them).
    provenance : object
        Stored as the file's ``script`` attribute (its ``to_json()``).
    background : dict
        The background's JSON-ready provenance.
    seconds : dict
        Seconds per stage.
    components : object, optional
        The pure streams and their weights (kind ``"flare"``).
    frames : (times_us, images), optional
        The clean scene's intensity images at the windows' ends (kind
        ``"optics"`` with a synthetic street), for reconstruction benchmarks.
    """

    streams: dict[str, np.ndarray]
    provenance: Any
    background: dict[str, Any]
    seconds: dict[str, float]
    components: Any = None
    frames: tuple[np.ndarray, np.ndarray] | None = None


@dataclass(frozen=True)
class DatasetKind:
    """A registered dataset kind.

    Attributes
    ----------
    name : str
    make_sequence : callable
        ``(recipe, index, source) -> KindSequence``; ``source`` is the opened
        background source (None when the kind needs none).
    config_field : str or None
        The recipe field holding the kind's own config (None: the recipe's
        composition fields are the kind's).
    config_type : type or None
        That field's dataclass (``from_dict`` / ``to_dict``).
    test_only : bool
        Every sequence is a test sequence.
    uses_background : bool
        Sequences draw from the recipe's background source.
    count : callable, optional
        ``config -> number of sequences`` when the config fixes it.
    check : callable, optional
        ``recipe -> None``: find the kind's inputs before a run (errors surface early).
    identity : callable, optional
        ``config dict -> dict`` with paths that depend on the data's place removed.
    cli_options : tuple of str
        The kind-specific options of ``edeflare simulate`` (:data:`KIND_OPTIONS`)
        that apply to this kind; the others are refused.
    """

    name: str
    make_sequence: Callable[..., KindSequence]
    config_field: str | None = None
    config_type: type | None = None
    test_only: bool = False
    uses_background: bool = True
    count: Callable[[Any], int] | None = None
    check: Callable[[Any], None] | None = None
    identity: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    cli_options: tuple[str, ...] = ()


def register_kind(name: str, **options: Any) -> Callable[[Callable[..., KindSequence]], Any]:
    """Register ``make_sequence`` as dataset kind ``name`` (a decorator).

    ``options`` are the other fields of :class:`DatasetKind`. Registering a
    name twice is an error.
    """

    def deco(make_sequence: Callable[..., KindSequence]) -> Callable[..., KindSequence]:
        DATASET_KINDS.register(name, DatasetKind(name, make_sequence, **options))
        return make_sequence

    return deco


def _load_builtin() -> None:
    for module in _BUILTIN:
        importlib.import_module(f"{__package__}.{module}")


DATASET_KINDS: Registry[DatasetKind] = Registry("dataset kind", loader=_load_builtin)
"""The registered dataset kinds (the built-in ones load on first look-up)."""


def get_kind(name: str) -> DatasetKind:
    """The registered kind ``name`` (an unknown name lists the valid ones)."""
    return DATASET_KINDS[name]


def list_kinds() -> list[str]:
    """Names of the registered kinds, sorted."""
    return DATASET_KINDS.names()
