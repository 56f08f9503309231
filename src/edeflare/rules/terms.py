"""What each rule knob adds to a stream's keep logits (the rules are linear in their shifts).

A mask model's keep logit is its network's (or its keep head's) plus each active rule's shift
(:meth:`~edeflare.rules.RuleSet.apply`). Every rule's shift is a sum of its shift
knobs (``halo_shift``, ``scatter_shift``, ...), each times evidence that does not depend
on the knob (only on which of the rule's knobs are on), so one pass over a stream gives
the logits at any values of them:

.. math:: \\ell(k) = \\ell_0 + \\sum_j k_j u_j

with :math:`\\ell_0` the model's logits with every rule off (its network's or its head's)
and :math:`u_j` what knob :math:`j` adds at 1. The count knobs (``light_free_support``,
``light_free_crowding``) decide which events the evidence covers; they stay at the model's values.
:class:`RuleTerms` holds both for one or more windowings of a stream
(:meth:`edeflare.models.infer.ModelDeflarer.rule_terms`): a search over the knobs on
annotated recordings (``benchmarks/flare_targets.py``'s leave-one-out) then runs
no network.

Examples
--------
>>> import numpy as np
>>> halo = {("halo_shift",): {"halo_shift": np.array([[0.0, -1.0]])}}
>>> terms = RuleTerms((0,), np.array([[0.5, -1.0]]), halo)
>>> terms.logits({"halo_shift": 3.0}).tolist()
[0.5, -4.0]
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import ParameterError
from . import RULES, Rule, RuleSet, WindowContext, knob_fields

__all__ = ["RuleTerms", "knob_sets", "shift_knobs", "unit_shifts"]


def shift_knobs() -> tuple[str, ...]:
    """The rules' shift knobs (logit amounts, not the counts and thresholds that say which
    events a rule covers), in the rules' order.

    Examples
    --------
    >>> shift_knobs()
    ('ghost_shift', 'halo_shift', 'streak_shift', 'far_shift', 'light_free_shift', \
'scatter_shift')
    """
    fields = knob_fields().items()
    return tuple(name for name, (_, f) in fields if f.metadata["cli"].metavar == "LOGIT")


def _rule_shift_knobs() -> dict[str, tuple[str, ...]]:
    """Each rule's shift knobs, in its order."""
    shifts = set(shift_knobs())
    return {
        rule.name: tuple(f.name for f in dataclasses.fields(rule.params) if f.name in shifts)
        for rule in RULES.values()
    }


def knob_sets() -> list[tuple[str, ...]]:
    """Every set of one rule's shift knobs that can be on together (one term each).

    Examples
    --------
    >>> knob_sets()[-3:]
    [('light_free_shift',), ('scatter_shift',), ('light_free_shift', 'scatter_shift')]
    """
    return [
        on
        for own in _rule_shift_knobs().values()
        for r in range(1, len(own) + 1)
        for on in itertools.combinations(own, r)
    ]


def _shift(rules: RuleSet, rule: Rule, ctx: WindowContext, knobs: dict[str, float]) -> np.ndarray:
    params = dataclasses.replace(rules.params[rule.name], **knobs)
    return np.broadcast_to(rule.shift(params, ctx), (ctx.events.size,)).astype(np.float64)


def unit_shifts(rules: RuleSet, ctx: WindowContext) -> dict[tuple[str, ...], dict[str, np.ndarray]]:
    """What each shift knob adds to the keep logits of the context's window at value 1
    (float32 per event), for each set of a rule's shift knobs that are on (a rule may
    cover other events when another of its knobs is on: the light-free shift spares a
    slow lamp's bloom only with a scatter shift), the count knobs at ``rules``' values.

    Within one such set a rule is linear in its shifts: the unit of a knob alone is the
    shift at 1; of knob ``j`` among others, the shift with ``j`` at 2 less the shift with
    ``j`` at 1, the set's other knobs at 1.
    """
    n = ctx.events.size
    kind = "lights" if ctx.has_lights else "light-free"
    own_of, sets = _rule_shift_knobs(), knob_sets()
    out: dict[tuple[str, ...], dict[str, np.ndarray]] = {}
    for rule in RULES.values():
        own = own_of[rule.name]
        for on in (on for on in sets if on[0] in own):
            units = {name: np.zeros(n, np.float32) for name in on}
            if rule.windows == kind:
                ones = {k: float(k in on) for k in own}
                at_one = _shift(rules, rule, ctx, ones)
                for name in on:  # alone, linear through 0: the shift at 1 is the unit
                    units[name][:] = (
                        at_one if len(on) == 1
                        else _shift(rules, rule, ctx, {**ones, name: 2.0}) - at_one
                    )  # fmt: skip
            out[on] = units
    return out


@dataclasses.dataclass(frozen=True)
class RuleTerms:
    """A stream's keep logits as the model's with every rule off plus each shift knob's term.

    Parameters
    ----------
    delays_us : tuple of int
        The windowings: windows start at multiples of the model's window minus each delay.
    base : numpy.ndarray
        ``(windowings, events)``: the keep logits with every rule off (the network's,
        or a keep head's).
    units : mapping
        For each set of one rule's shift knobs that are on (a tuple of names, in the
        rule's order): knob -> ``(windowings, events)``, what it adds at value 1 then.
    """

    delays_us: tuple[int, ...]
    base: np.ndarray
    units: Mapping[tuple[str, ...], Mapping[str, np.ndarray]]

    def logits(self, knobs: Mapping[str, float], views: Sequence[int] | None = None) -> np.ndarray:
        """The keep logits at these knob values (a knob left out: 0), the mean over the
        windowings ``views`` (default: all), as a mask model's views are averaged: the
        model's own up to float rounding (its rules add their shifts in float64)."""
        known = shift_knobs()
        unknown = set(knobs) - set(known)
        if unknown:
            raise ParameterError(
                f"unknown shift knob(s) {sorted(unknown)}; known: {', '.join(known)}"
            )
        rows = range(len(self.delays_us)) if views is None else list(views)
        # each rule's knobs that are on, in the rules' order (as they apply)
        sets = [tuple(k for k in own if knobs.get(k)) for own in _rule_shift_knobs().values()]
        total = np.zeros(self.base.shape[1], np.float32)
        for v in rows:
            lg = self.base[v].astype(np.float32, copy=True)
            for on in sets:
                for name in on:
                    lg += np.float32(knobs[name]) * self.units[on][name][v]
            total += lg
        return total / len(rows)
