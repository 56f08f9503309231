"""Leave-one-out scoring on annotated real recordings: a setting chosen while looking at
some recordings is reported on the one it never saw.

A de-flarer's setting (a keep threshold, a rule's shift) chosen on the same annotated
recordings that report its scores says little about a recording nobody looked at.
:func:`leave_one_out` makes the honest version: for each recording it picks, among the
candidate settings, the one with the best mean combined score on the *other*
recordings, and reports that setting's score on the held-out one, beside the score the
best setting would have had in-sample (the optimism of tuning on what you report).

Examples
--------
Three recordings, two settings: each held-out recording gets the others' choice, which
is never its own best here (the optimism of tuning in-sample).

>>> table = {"a": {"lo": 0.9, "hi": 0.5}, "b": {"lo": 0.6, "hi": 0.8}, "c": {"lo": 0.5, "hi": 0.7}}
>>> rows = leave_one_out(lambda rec, name: table[rec][name], ["a", "b", "c"], ["lo", "hi"])
>>> [(r.recording, r.chosen, r.held_out, r.in_sample) for r in rows]
[('a', 'hi', 0.5, 0.9), ('b', 'lo', 0.6, 0.8), ('c', 'lo', 0.5, 0.7)]
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Hashable, Sequence

__all__ = ["HeldOut", "leave_one_out"]


@dataclasses.dataclass(frozen=True)
class HeldOut:
    """One recording held out: the setting the others chose, its score here, and the
    best score of any setting here (what tuning on this recording would report)."""

    recording: str
    chosen: Hashable
    held_out: float
    in_sample: float
    in_sample_setting: Hashable

    @property
    def optimism(self) -> float:
        """How much tuning on this recording would overstate its score."""
        return self.in_sample - self.held_out


def leave_one_out(
    score: Callable[[str, Hashable], float],
    recordings: Sequence[str],
    settings: Sequence[Hashable],
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
    """
    if len(recordings) < 2:
        raise ValueError("leave-one-out needs at least two recordings")
    if not settings:
        raise ValueError("no settings to choose from")
    table = {(r, s): float(score(r, s)) for r in recordings for s in settings}

    def mean(recs: Sequence[str], s: Hashable) -> float:
        values = [table[r, s] for r in recs if not math.isnan(table[r, s])]
        return sum(values) / len(values) if values else -math.inf

    rows = []
    for held in recordings:
        others = [r for r in recordings if r != held]
        chosen = max(settings, key=lambda s: mean(others, s))
        best = max(settings, key=lambda s: mean([held], s))
        rows.append(HeldOut(held, chosen, table[held, chosen], table[held, best], best))
    return rows
