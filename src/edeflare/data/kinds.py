"""Dataset kinds: what one sequence of a recipe is, each kind registered at its definition.

A kind (``recipe.kind``) brings its own config dataclass (``recipe.config``;
the :class:`~edeflare.data.recipe.Recipe` holds only what every kind
shares), its ``make_sequence(recipe, index, source)`` function, what a run
checks before it starts and what its files record. The built-in kinds:

- ``"flare"`` (:mod:`edeflare.data.eflare`): simulated training pairs
  (E-Flare-2.7K, eflare-mini, eflare-night),
  :class:`~edeflare.data.eflare.FlareConfig`;
- ``"optics"`` (:mod:`edeflare.data.eflare_r_sim`): the optics test pairs,
  :class:`~edeflare.sim.optics_scene.OpticsSceneConfig`;
- ``"dsec"`` (:mod:`edeflare.data.dsec_flare`): windows of a local DSEC copy,
  :class:`~edeflare.data.dsec_flare.DsecFlareConfig`.

This module imports no kind and no recipe: the kinds import it to register,
and :func:`get_kind` loads the built-in ones on first use.

Examples
--------
>>> list_kinds()
['dsec', 'flare', 'optics']
>>> get_kind("optics").config_field, get_kind("optics").test_only
('optics', True)
>>> get_kind("flare").config_type.__name__, get_kind("flare").config_field is None
('FlareConfig', True)
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
    "--weights",
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
    config_type : type
        The kind's config dataclass (``recipe.config``; ``from_dict`` /
        ``to_dict``); ``config_type()`` is the default config.
    config_field : str or None
        The key of the config in the recipe's dict (None: its keys sit beside
        the common ones, the layout recipe dicts had before kinds existed).
    test_only : bool
        Every sequence is a test sequence.
    count : callable, optional
        ``config -> number of sequences`` when the config fixes it.
    check : callable, optional
        ``recipe -> None``: find the kind's inputs before a run (errors surface early).
    identity : callable, optional
        ``config dict -> dict`` with paths that depend on the data's place removed.
    validate : callable, optional
        ``recipe -> None``: what the config asks of the common fields (checked
        when a recipe is made).
    file_attrs : callable, optional
        ``recipe -> dict``: root attributes of its files (default ``{"kind": name}``).
    file_groups : callable, optional
        ``recipe -> tuple or None``: the groups its files keep (None: every stream).
    cli_options : tuple of str
        The kind-specific options of ``edeflare simulate`` (:data:`KIND_OPTIONS`)
        that apply to this kind; the others are refused.
    """

    name: str
    make_sequence: Callable[..., KindSequence]
    config_type: type
    config_field: str | None = None
    test_only: bool = False
    count: Callable[[Any], int] | None = None
    check: Callable[[Any], None] | None = None
    identity: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    validate: Callable[[Any], None] | None = None
    file_attrs: Callable[[Any], dict[str, Any]] | None = None
    file_groups: Callable[[Any], tuple[str, ...] | None] | None = None
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
