"""Leave-one-out choice of a setting on annotated recordings."""

from __future__ import annotations

import math

import pytest

from edeflare.eval.leave_one_out import leave_one_out


def test_each_recording_is_scored_with_the_setting_the_others_chose():
    table = {
        "gen3": {0.3: 0.95, 0.5: 0.97, 0.7: 0.90},
        "davis": {0.3: 0.80, 0.5: 0.85, 0.7: 0.88},
        "window": {0.3: 0.70, 0.5: 0.92, 0.7: 0.93},
    }
    asked = []

    def score(rec, thr):
        asked.append((rec, thr))
        return table[rec][thr]

    rows = leave_one_out(score, list(table), [0.3, 0.5, 0.7])
    assert len(asked) == 9 == len(set(asked))  # each pair once
    by = {r.recording: r for r in rows}
    # gen3 out: davis + window mean 0.75 / 0.885 / 0.905 -> 0.7, where gen3 has 0.90
    assert (by["gen3"].chosen, by["gen3"].held_out, by["gen3"].in_sample) == (0.7, 0.90, 0.97)
    assert by["gen3"].optimism == pytest.approx(0.07)
    # davis out: gen3 + window 0.825 / 0.945 / 0.915 -> 0.5, davis 0.85 (its best 0.88 at 0.7)
    davis = by["davis"]
    assert (davis.chosen, davis.held_out, davis.in_sample_setting) == (0.5, 0.85, 0.7)
    # window out: gen3 + davis 0.875 / 0.91 / 0.89 -> 0.5
    assert (by["window"].chosen, by["window"].held_out) == (0.5, 0.92)


def test_an_unscored_pair_is_left_out_of_the_choice_and_ties_go_to_the_first():
    table = {"a": {1: math.nan, 2: 0.5}, "b": {1: 0.6, 2: 0.6}, "c": {1: 0.4, 2: 0.4}}
    rows = leave_one_out(lambda r, s: table[r][s], ["a", "b", "c"], [1, 2])
    # a out: 0.5 / 0.5, a tie; b out: 0.4 (a's NaN skipped) / 0.45; c out: 0.6 / 0.55
    assert [r.chosen for r in rows] == [1, 2, 1]


def test_fewer_than_two_recordings_or_no_setting_is_refused():
    with pytest.raises(ValueError, match="at least two recordings"):
        leave_one_out(lambda r, s: 1.0, ["a"], [1])
    with pytest.raises(ValueError, match="no settings"):
        leave_one_out(lambda r, s: 1.0, ["a", "b"], [])
