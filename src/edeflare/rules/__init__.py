"""The mask model's rules: one registry of window-level evidence that shifts keep logits.

A mask network judges each event from what its cells show. Some evidence lies
beyond them: where the window's lights are, where their ghosts can be, whether
an event lies on a light's diffraction spike, whether the window has a light at
all. Each rule turns one such piece of evidence into a shift of the events'
keep logits (a prior odds ratio, not a verdict).

A rule is a frozen parameter dataclass, whose fields are its knobs, plus a
function of the shared :class:`~edeflare.rules.context.WindowContext` that
returns the shift to add. The model card (:class:`~edeflare.models.weights.ModelCard`),
the ``model`` method's parameters and command-line options
(:class:`~edeflare.methods.ModelParams`), their validation and the rules'
reference page (``docs/rules.md``) are all made from this registry, so a
knob is declared once, in its rule.

================  ========================================================  ===========
rule              evidence                                                  windows
================  ========================================================  ===========
``ghost``         where a reflective ghost of the lights can be             with lights
``halo``          the band of scattered light around each light             with lights
``streak``        the lights' saturated diffraction spikes                  with lights
``far``           far from every light (flare lies around its source)       with lights
``light-free``    no light in the window (flare needs a bright source)      light-free
================  ========================================================  ===========

Examples
--------
>>> from edeflare.rules import RULES, RuleSet
>>> list(RULES)
['ghost', 'halo', 'streak', 'far', 'light-free']
>>> rules = RuleSet({"halo_shift": 3})
>>> rules["halo_shift"], rules["ghost_shift"], rules.active
(3.0, 0.0, True)
>>> RuleSet({"halo": 3})
Traceback (most recent call last):
...
edeflare.errors.ParameterError: unknown rule knob 'halo'; known: far_shift, ghost_shift, \
halo_shift, light_free_crowding, light_free_shift, light_free_support, scatter_shift, \
streak_shift
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .._registry import Registry, cli_option
from ..errors import ParameterError
from .context import WindowContext

__all__ = [
    "RULES",
    "Rule",
    "RuleSet",
    "WindowContext",
    "check_logit_shift",
    "check_support",
    "knob",
    "knob_fields",
    "register_rule",
]


def check_logit_shift(value: object, name: str) -> float:
    """A keep-logit shift (or other non-negative amount) ``name`` as a float: finite, >= 0.

    Examples
    --------
    >>> check_logit_shift(-1.0, "ghost_shift")
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: ghost_shift must be a finite number >= 0, got -1.0
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not math.isfinite(value)
        or value < 0
    ):
        raise ParameterError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


def check_support(value: object, name: str) -> int:
    """A count of neighbouring events ``name`` as an int: whole, >= 0.

    Examples
    --------
    >>> check_support(2.0, "light_free_support")
    2
    >>> check_support(1.5, "light_free_support")
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: light_free_support must be a whole number >= 0, got 1.5
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not math.isfinite(value)
        or value < 0
        or value != int(value)
    ):
        raise ParameterError(f"{name} must be a whole number >= 0, got {value!r}")
    return int(value)


def knob(
    default: float | int,
    flag: str,
    help: str,
    *,
    check: Callable[[object, str], Any] = check_logit_shift,
    metavar: str = "LOGIT",
) -> Any:
    """A rule's knob: a dataclass field with its command-line option and its check.

    The option's value type follows the check (a count for :func:`check_support`).
    """
    kind = int if check is check_support else float
    return dataclasses.field(
        default=default,
        metadata={
            **cli_option(
                flag, f"mask models: {help}", metavar=metavar, type=kind,
                default_text="the model card's",
            ),
            "check": check,
        },
    )  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Rule:
    """One rule: its knobs (``params``, a frozen dataclass of :func:`knob` fields), the
    shift it adds to a window's keep logits, and in which windows it applies.

    ``shift(params, ctx)`` returns the amount to add to the keep logits of the
    context's events (an array of their length, or a number); ``active(params)``
    says whether the rule does anything at those values; ``windows`` is
    ``"lights"`` (windows with a light) or ``"light-free"``.
    """

    name: str
    params: type
    shift: Callable[[Any, WindowContext], np.ndarray | float]
    active: Callable[[Any], bool]
    windows: str
    summary: str


RULES: Registry[Rule] = Registry("rule")
"""The registered rules, in the order they apply."""


def register_rule(rule: Rule) -> Rule:
    """Add a rule to the registry (its knobs' names must be new)."""
    if rule.windows not in ("lights", "light-free"):
        raise ParameterError(f"rule {rule.name!r}: windows must be 'lights' or 'light-free'")
    taken = set(knob_fields())
    for f in dataclasses.fields(rule.params):
        if f.name in taken:
            raise ParameterError(f"rule {rule.name!r}: knob {f.name!r} is already a knob")
    return RULES.register(rule.name, rule)


def knob_fields() -> dict[str, tuple[Rule, dataclasses.Field[Any]]]:
    """Every rule's knobs: ``{knob: (rule, field)}``, in the rules' order."""
    return {f.name: (rule, f) for rule in RULES.values() for f in dataclasses.fields(rule.params)}


class RuleSet:
    """The rules' knob values of one model, checked: what its card says, with overrides.

    Parameters
    ----------
    values : mapping, optional
        ``{knob: value}``; a knob left out takes its rule's default (off). ``None``
        values are left out (they mean "the card's" one layer up).
    """

    def __init__(self, values: Mapping[str, Any] | None = None) -> None:
        self._fields = knob_fields()
        given = {k: v for k, v in dict(values or {}).items() if v is not None}
        for name in given:
            if name not in self._fields:
                raise ParameterError(
                    f"unknown rule knob {name!r}; known: {', '.join(sorted(self._fields))}"
                )
        self.params: dict[str, Any] = {}
        for rule in RULES.values():
            kw = {}
            for f in dataclasses.fields(rule.params):
                if f.name in given:
                    kw[f.name] = f.metadata["check"](given[f.name], f.name)
            self.params[rule.name] = rule.params(**kw)
        # the rules that act, per kind of window (the values are frozen: decided once)
        self._acting = {
            kind: [r for r in RULES.values() if r.windows == kind and r.active(self.params[r.name])]
            for kind in ("lights", "light-free")
        }
        from .light_free import needs_support

        self.active: bool = any(self._acting.values())
        """Whether any rule does anything."""
        self.needs_support: bool = needs_support(self.params["light-free"])
        """Whether a rule reads the events' 5x5 support (:attr:`WindowContext.support`)."""

    def __getitem__(self, name: str) -> Any:
        rule, _ = self._fields[name]
        return getattr(self.params[rule.name], name)

    @property
    def values(self) -> dict[str, Any]:
        """Every knob's value, in the rules' order."""
        return {k: self[k] for k in self._fields}

    def changed(self) -> dict[str, Any]:
        """The knobs whose values differ from their rules' defaults."""
        return {k: v for k, v in self.values.items() if v != self._fields[k][1].default}

    def apply(self, logits: np.ndarray, ctx: WindowContext) -> None:
        """Add every active rule's shift for the context's window to ``logits``, in place."""
        if not self.active:
            return
        for rule in self._acting["lights" if ctx.has_lights else "light-free"]:
            logits += rule.shift(self.params[rule.name], ctx)

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v:g}" for k, v in self.changed().items())
        return f"RuleSet({shown})"


def _load() -> None:
    from .far import FAR_RULE
    from .ghost import GHOST_RULE
    from .halo import HALO_RULE
    from .light_free import LIGHT_FREE_RULE
    from .streak import STREAK_RULE

    # the order they apply in (a window's shifts add in this order)
    for rule in (GHOST_RULE, HALO_RULE, STREAK_RULE, FAR_RULE, LIGHT_FREE_RULE):
        register_rule(rule)


RULES._loader = _load


def reference_markdown() -> str:
    """The rules' reference page (``docs/rules.md``), made from the registry.

    Examples
    --------
    >>> reference_markdown().splitlines()[0].startswith("# The mask model")
    True
    """
    lines = [
        "# The mask model's rules",
        "",
        "<!-- generated by edeflare.rules.reference_markdown(); "
        "python docs/make_rules_reference.py -->",
        "",
        "Each rule shifts the keep logits of a mask model's events where its evidence",
        "holds. Its knobs are `model` parameters, `edeflare deflare` options and model-card",
        "fields (`rules`); a knob not given takes the card's value, and a card's rules are",
        "off unless it sets them. In a window the rules add their shifts in this order.",
        "",
        "Each shift knob adds itself times evidence that does not depend on it, so",
        "`ModelDeflarer.rule_terms(events, size)` splits a stream's keep logits into the",
        "model's own (the network's, or its keep head's) and each knob's term",
        "(`edeflare.rules.terms`): a search over the knobs on annotated recordings",
        "(`benchmarks/flare_targets.py`'s leave-one-out) then runs the model once.",
        "",
    ]
    for rule in RULES.values():
        where = "windows with a light" if rule.windows == "lights" else "windows without a light"
        lines += [f"## `{rule.name}`", "", f"{rule.summary[0].upper()}{rule.summary[1:]}; "
                  f"applies in {where}.", "", "| knob | option | default | what it does |",
                  "|---|---|---|---|"]  # fmt: skip
        for f in dataclasses.fields(rule.params):
            opt = f.metadata["cli"]
            text = opt.help.removeprefix("mask models: ")
            lines.append(f"| `{f.name}` | `{opt.flag} {opt.metavar}` | {f.default:g} | {text} |")
        lines.append("")
    return "\n".join(lines)
