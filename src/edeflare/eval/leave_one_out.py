"""Leave-one-out scoring on annotated real recordings: a setting chosen while looking at
some recordings is reported on the one it never saw.

A de-flarer's setting (a keep threshold, a rule's shift) chosen on the same annotated
recordings that report its scores says little about a recording nobody looked at.
:func:`leave_one_out` makes the honest version: for each recording it picks, among the
candidate settings, the one with the best mean combined score on the *other*
recordings, and reports that setting's score on the held-out one, beside the score the
best setting would have had in-sample (the optimism of tuning on what you report).
:func:`leave_one_out_search` does the same over several knobs at once (a model's rule
shifts and keep threshold), too many together to try every combination: a coordinate
ascent over a grid per knob chooses on the others.

Two inputs cut from one recording are not independent: a setting chosen on one has seen
the other. ``groups`` names each input's source recording, and holding an input out
leaves its whole group out of the choice (leave one recording out, not one file).

Examples
--------
Three recordings, two settings: each held-out recording gets the others' choice, which
is never its own best here (the optimism of tuning in-sample).

>>> table = {"a": {"lo": 0.9, "hi": 0.5}, "b": {"lo": 0.6, "hi": 0.8}, "c": {"lo": 0.5, "hi": 0.7}}
>>> rows = leave_one_out(lambda rec, name: table[rec][name], ["a", "b", "c"], ["lo", "hi"])
>>> [(r.recording, r.chosen, r.held_out, r.in_sample) for r in rows]
[('a', 'hi', 0.5, 0.9), ('b', 'lo', 0.6, 0.8), ('c', 'lo', 0.5, 0.7)]

If ``a`` and ``c`` are cut from one recording, ``c`` alone chooses for ``b``, and ``b``
alone for each of them:

>>> rows = leave_one_out(lambda rec, name: table[rec][name], ["a", "b", "c"], ["lo", "hi"],
...                      groups={"a": "one", "c": "one"})
>>> [(r.recording, r.chosen, r.held_out) for r in rows]
[('a', 'hi', 0.5), ('b', 'lo', 0.6), ('c', 'hi', 0.7)]

Two knobs searched together, the scores of the three recordings at each setting:

>>> def scores(s):
...     return [1 - abs(s["x"] - 1) / 4 - s["y"] / 10, 1 - abs(s["x"] - 2) / 4, 0.5 + s["y"] / 10]
>>> rows = leave_one_out_search(scores, ["a", "b", "c"], {"x": [0, 1, 2], "y": [0, 1]})
>>> [(r.recording, r.chosen, r.held_out) for r in rows]
[('a', {'x': 2, 'y': 1}, 0.65), ('b', {'x': 1, 'y': 0}, 0.75), ('c', {'x': 1, 'y': 0}, 0.5)]
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Hashable, Mapping, Sequence
from typing import Any

__all__ = ["HeldOut", "leave_one_out", "leave_one_out_search", "others_of"]


@dataclasses.dataclass(frozen=True)
class HeldOut:
    """One recording held out: the setting the others chose, its score here, and the
    best score of any setting here (what tuning on this recording would report)."""

    recording: str
    chosen: Any
    held_out: float
    in_sample: float
    in_sample_setting: Any

    @property
    def optimism(self) -> float:
        """How much tuning on this recording would overstate its score."""
        return self.in_sample - self.held_out


def others_of(
    recordings: Sequence[str], groups: Mapping[str, Hashable] | None = None
) -> dict[str, list[str]]:
    """What chooses for each held-out input: every input not of its source recording.

    ``groups`` maps an input to its source recording (an input left out: its own). At
    least one input must be left to choose for each.

    Examples
    --------
    >>> others_of(["gen3", "night", "window"], {"window": "night"})
    {'gen3': ['night', 'window'], 'night': ['gen3'], 'window': ['gen3']}
    """
    groups = dict(groups or {})
    unknown = sorted(set(groups) - set(recordings))
    if unknown:
        raise ValueError(f"groups name input(s) not among the recordings: {unknown}")
    source = {r: groups.get(r, r) for r in recordings}
    out = {held: [r for r in recordings if source[r] != source[held]] for held in recordings}
    alone = [held for held, rest in out.items() if not rest]
    if alone:
        raise ValueError(f"nothing left to choose for {alone}: every input is of one recording")
    return out


def leave_one_out(
    score: Callable[[str, Hashable], float],
    recordings: Sequence[str],
    settings: Sequence[Hashable],
    groups: Mapping[str, Hashable] | None = None,
) -> list[HeldOut]:
    """Hold each recording out in turn; choose the setting on the rest (see the module).

    Parameters
    ----------
    score : callable
        ``score(recording, setting)``: the combined score (higher is better; NaN: not
        scored). Each pair is asked once.
    recordings : sequence of str
        At least two.
    settings : sequence
        The candidates (ties go to the first).
    groups : mapping, optional
        Each input's source recording, where several are cut from one (:func:`others_of`).
    """
    if len(recordings) < 2:
        raise ValueError("leave-one-out needs at least two recordings")
    if not settings:
        raise ValueError("no settings to choose from")
    choosers = others_of(recordings, groups)
    table = {(r, s): float(score(r, s)) for r in recordings for s in settings}

    def mean(recs: Sequence[str], s: Hashable) -> float:
        return _mean([table[r, s] for r in recs])

    rows = []
    for held in recordings:
        others = choosers[held]
        chosen = max(settings, key=lambda s: mean(others, s))
        best = max(settings, key=lambda s: mean([held], s))
        rows.append(HeldOut(held, chosen, table[held, chosen], table[held, best], best))
    return rows


def _mean(values: Sequence[float]) -> float:
    """The mean of the scored values (NaN: not scored); -inf where none is."""
    scored = [v for v in values if not math.isnan(v)]
    return sum(scored) / len(scored) if scored else -math.inf


def leave_one_out_search(
    scores: Callable[[dict[str, Any]], Sequence[float]],
    recordings: Sequence[str],
    grid: Mapping[str, Sequence[Any]],
    starts: Sequence[Mapping[str, Any]] = (),
    groups: Mapping[str, Hashable] | None = None,
) -> list[HeldOut]:
    """Hold each recording out in turn; choose every knob on the rest by coordinate ascent.

    From each start, each knob in turn moves to its grid value with the best mean score
    on the recordings at hand (a strictly better one only) until no knob moves; the best
    end point of the starts is the choice. The held-out recording is scored there, and
    the search on it alone gives the in-sample best.

    Parameters
    ----------
    scores : callable
        ``scores({knob: value})``: the score of every recording at that setting, in the
        order of ``recordings`` (higher is better; NaN: not scored). Asked once per
        setting.
    recordings : sequence of str
        At least two.
    grid : mapping
        Each knob's candidate values (none empty).
    starts : sequence of mapping, optional
        Settings to ascend from (a knob left out: its first grid value; default: one
        start, every knob at its first value). A start's value need not be on the grid.
    groups : mapping, optional
        Each input's source recording, where several are cut from one (:func:`others_of`).

    Returns
    -------
    list of HeldOut
        ``chosen`` and ``in_sample_setting`` are ``{knob: value}`` dicts.
    """
    if len(recordings) < 2:
        raise ValueError("leave-one-out needs at least two recordings")
    choosers = others_of(recordings, groups)
    column = {r: j for j, r in enumerate(recordings)}
    names = list(grid)
    axes = [list(grid[n]) for n in names]
    if not axes or any(not a for a in axes):
        raise ValueError("every knob needs at least one grid value")
    unknown = {k for s in starts for k in s} - set(names)
    if unknown:
        raise ValueError(f"start names knob(s) not on the grid: {sorted(unknown)}")
    points = [tuple(s.get(n, a[0]) for n, a in zip(names, axes, strict=True)) for s in starts] or [
        tuple(a[0] for a in axes)
    ]

    @functools.cache
    def at(point: tuple[Any, ...]) -> tuple[float, ...]:
        values = tuple(float(v) for v in scores(dict(zip(names, point, strict=True))))
        if len(values) != len(recordings):
            raise ValueError(f"scores gave {len(values)} values for {len(recordings)} recordings")
        return values

    def search(cols: list[int]) -> tuple[tuple[Any, ...], float]:
        def mean(point: tuple[Any, ...]) -> float:
            return _mean([at(point)[c] for c in cols])

        ends = []
        for point in points:
            best = mean(point)
            moved = True
            while moved:
                moved = False
                for j, values in enumerate(axes):
                    for v in values:
                        trial = (*point[:j], v, *point[j + 1 :])
                        s = mean(trial)
                        if s > best + 1e-9:
                            point, best, moved = trial, s, True
            ends.append((point, best))
        return max(ends, key=lambda e: e[1])  # ties: the first start's

    rows = []
    for i, held in enumerate(recordings):
        chosen, _ = search([column[r] for r in choosers[held]])
        own, own_score = search([i])
        setting, best = (dict(zip(names, p, strict=True)) for p in (chosen, own))
        rows.append(HeldOut(held, setting, at(chosen)[i], own_score, best))
    return rows
