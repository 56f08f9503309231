"""Leave-one-out choice of a setting on annotated recordings."""

from __future__ import annotations

import math

import pytest

from edeflare.eval.leave_one_out import leave_one_out, leave_one_out_search


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


def test_search_moves_every_knob_on_the_others_and_asks_each_setting_once():
    # score(rec, x, y): a peak at each recording's own (x, y)
    peaks = {"gen3": (2, 0), "davis": (2, 1), "window": (1, 1)}
    asked = []

    def scores(s):
        asked.append((s["x"], s["y"]))
        return [1 - abs(s["x"] - px) / 4 - abs(s["y"] - py) / 8 for px, py in peaks.values()]

    rows = leave_one_out_search(scores, list(peaks), {"x": [0, 1, 2], "y": [0, 1]})
    assert len(asked) == len(set(asked)) <= 6
    by = {r.recording: r for r in rows}
    # gen3 out: davis + window, x=1 and x=2 tie on x (0.75 + 1.0 / 2 either way), y=1 best
    # for both: ascent from (0, 0): x -> 1 (first of the tie), then y -> 1
    assert by["gen3"].chosen == {"x": 1, "y": 1}
    assert by["gen3"].held_out == pytest.approx(1 - 1 / 4 - 1 / 8)
    assert by["gen3"].in_sample == 1.0 and by["gen3"].in_sample_setting == {"x": 2, "y": 0}
    # davis out: gen3 (2, 0) + window (1, 1): x=1 and x=2 tie again, y ties -> stays 0
    assert by["davis"].chosen == {"x": 1, "y": 0}
    assert by["davis"].held_out == pytest.approx(1 - 1 / 4 - 1 / 8)
    # window out: gen3 + davis both at x=2, y tie -> 0
    assert by["window"].chosen == {"x": 2, "y": 0}
    assert by["window"].optimism == pytest.approx(1 - (1 - 1 / 4 - 1 / 8))


def test_search_takes_the_best_start_and_a_start_may_lie_off_the_grid():
    # one knob with two local peaks: ascent from 0 stops at 1 (2 is worse), from 4 reaches 4
    curve = {0: 0.1, 1: 0.5, 2: 0.2, 3: 0.6, 4: 0.9, 0.5: 0.0}
    table = {"a": curve, "b": curve}

    def scores(s):
        return [table["a"][s["k"]], table["b"][s["k"]]]

    one = leave_one_out_search(scores, ["a", "b"], {"k": [0, 1, 2, 3, 4]}, [{"k": 0}])
    assert [r.chosen for r in one] == [{"k": 4}] * 2  # one move to the best grid value
    off = leave_one_out_search(scores, ["a", "b"], {"k": [0, 4]}, [{"k": 0.5}, {"k": 0}])
    assert off[0].chosen == {"k": 4} and off[0].held_out == 0.9


def test_search_leaves_unscored_recordings_out_and_refuses_bad_arguments():
    def scores(s):
        return [math.nan, 0.2 + s["k"], 0.9 - s["k"]]

    rows = leave_one_out_search(scores, ["a", "b", "c"], {"k": [0.0, 0.5]})
    assert rows[0].chosen == {"k": 0.0}  # b + c: 1.1 at either, first kept
    assert math.isnan(rows[0].held_out)
    assert rows[1].chosen == {"k": 0.0} and rows[2].chosen == {"k": 0.5}  # a's NaN skipped
    with pytest.raises(ValueError, match="at least two recordings"):
        leave_one_out_search(scores, ["a"], {"k": [0]})
    with pytest.raises(ValueError, match="at least one grid value"):
        leave_one_out_search(scores, ["a", "b"], {"k": []})
    with pytest.raises(ValueError, match="not on the grid: \\['z'\\]"):
        leave_one_out_search(scores, ["a", "b"], {"k": [0]}, [{"z": 1}])
    with pytest.raises(ValueError, match="gave 3 values for 2 recordings"):
        leave_one_out_search(scores, ["a", "b"], {"k": [0]})


def test_inputs_of_one_recording_are_held_out_together():
    # "window" is cut from "night": neither may choose for the other
    table = {
        "gen3": {0.3: 0.95, 0.7: 0.80},
        "night": {0.3: 0.60, 0.7: 0.90},
        "window": {0.3: 0.50, 0.7: 0.99},
    }
    groups = {"window": "night"}
    rows = leave_one_out(lambda r, s: table[r][s], list(table), [0.3, 0.7], groups)
    by = {r.recording: r for r in rows}
    # night out: gen3 alone chooses 0.3 (ungrouped, window's 0.99 would pull it to 0.7)
    assert (by["night"].chosen, by["night"].held_out) == (0.3, 0.60)
    assert (by["window"].chosen, by["window"].held_out) == (0.3, 0.50)
    # gen3 out: night + window 0.55 / 0.945 -> 0.7
    assert (by["gen3"].chosen, by["gen3"].held_out) == (0.7, 0.80)
    ungrouped = {r.recording: r.chosen for r in leave_one_out(
        lambda r, s: table[r][s], list(table), [0.3, 0.7])}  # fmt: skip
    assert ungrouped["night"] == 0.7  # gen3 0.875 / window+gen3 0.895: the window chose

    def scores(s):
        return [table[r][s["keep"]] for r in table]

    searched = {r.recording: r for r in leave_one_out_search(
        scores, list(table), {"keep": [0.3, 0.7]}, groups=groups)}  # fmt: skip
    assert {k: r.chosen["keep"] for k, r in searched.items()} == {
        "gen3": 0.7, "night": 0.3, "window": 0.3}  # fmt: skip
    assert searched["night"].held_out == 0.60


def test_groups_naming_an_unknown_input_or_leaving_nothing_to_choose_are_refused():
    def score(r, s):
        return 1.0

    with pytest.raises(ValueError, match=r"not among the recordings: \['moon'\]"):
        leave_one_out(score, ["a", "b"], [1], {"moon": "a"})
    with pytest.raises(ValueError, match=r"nothing left to choose for \['a', 'b'\]"):
        leave_one_out(score, ["a", "b"], [1], {"a": "one", "b": "one"})
    with pytest.raises(ValueError, match="nothing left to choose"):
        leave_one_out_search(lambda s: [1.0, 1.0], ["a", "b"], {"k": [0]}, groups={"b": "a"})
