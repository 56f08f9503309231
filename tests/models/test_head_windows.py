"""``train-head --windows``: an expert fitted only on the windows it will judge."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import write_left_flare_pairs
from edeflare.cli import main
from edeflare.errors import EdeflareError, ParameterError
from edeflare.models import create_model
from edeflare.models.head_training import HeadTrainingConfig, rows_in_windows, train_head
from edeflare.models.weights import ModelCard, read_card, save_model

FEATURES = ("net_logit", "light_free", "rate_8", "polarity")


def _context_rows():
    """Rows of four windows (two with a light found: light_free 0), each window's cells
    holding its own index, as :func:`collect_features` gives them with a context."""
    window = np.array([0, 0, 1, 2, 2, 2, 3])
    free = np.array([0.0, 1.0, 0.0, 1.0])[window]  # windows 1 and 3 have no light found
    x = np.stack([np.arange(7.0), free, np.zeros(7), np.ones(7)], 1)
    data = {
        "x": x,
        "y": np.array([True, False, True, True, False, True, False]),
        "light": np.zeros(7, bool),
        "source": np.array([0, 0, 0, 1, 1, 1, -2]),
        "window": window.astype(np.int32),
        "cell": np.arange(7, dtype=np.int32),
        "sizes": np.array([[8, 8], [16, 8], [8, 8], [16, 8]], np.int32),
    }
    data.update({f"cells_{i:06d}": np.full((2, 1, 1), i, np.float16) for i in range(4)})
    return data


def test_rows_of_lit_and_unlit_windows_keep_their_rows_cells_and_sizes():
    data = _context_rows()
    lit = rows_in_windows(data, FEATURES, "lit")  # windows 0 and 2
    assert lit["x"][:, 0].tolist() == [0.0, 1.0, 3.0, 4.0, 5.0]
    assert lit["window"].tolist() == [0, 0, 1, 1, 1]  # renumbered in order
    assert lit["sizes"].tolist() == [[8, 8], [8, 8]]
    assert [float(lit[f"cells_{j:06d}"][0, 0, 0]) for j in range(2)] == [0.0, 2.0]
    assert "cells_000002" not in lit
    assert lit["cell"].tolist() == [0, 1, 3, 4, 5]
    unlit = rows_in_windows(data, FEATURES, "unlit")  # windows 1 and 3
    assert unlit["x"][:, 0].tolist() == [2.0, 6.0]
    assert unlit["window"].tolist() == [0, 1] and unlit["source"].tolist() == [0, -2]
    assert unlit["sizes"].tolist() == [[16, 8], [16, 8]]
    assert [float(unlit[f"cells_{j:06d}"][0, 0, 0]) for j in range(2)] == [1.0, 3.0]
    # together they are every row, once
    assert lit["y"].size + unlit["y"].size == data["y"].size
    assert rows_in_windows(data, FEATURES, "all") is data
    with pytest.raises(ParameterError, match="windows must be one of all, lit, unlit, got 'dark'"):
        rows_in_windows(data, FEATURES, "dark")


def test_a_window_set_needs_the_light_free_feature_and_a_known_name():
    with pytest.raises(ParameterError, match="windows='lit' reads the rows' light_free feature"):
        HeadTrainingConfig(features=("net_logit",), windows="lit")
    with pytest.raises(ParameterError, match="windows must be one of all, lit, unlit"):
        HeadTrainingConfig(features=FEATURES, windows="bright")
    assert HeadTrainingConfig(features=("net_logit",)).windows == "all"


def test_an_unlit_expert_learns_the_rows_all_would_and_a_lit_one_finds_none(tmp_path, rng):
    write_left_flare_pairs(tmp_path / "data", rng, 2)  # no light found in any window
    base = tmp_path / "base.safetensors"
    save_model(base, create_model("mask.lite"), ModelCard(preset="mask.lite"))
    config = HeadTrainingConfig(features=FEATURES, hidden=(4,), epochs=2, per_window=300)
    every = train_head([tmp_path / "data"], base, tmp_path / "run", config, progress=False)
    cached = sorted(p.name for p in (tmp_path / "run").glob("features-*.npz"))
    unlit_config = dataclasses.replace(config, windows="unlit")
    unlit = train_head([tmp_path / "data"], base, tmp_path / "run", unlit_config, progress=False)
    # no window has a light: the unlit expert's rows are every row, read from the same cache
    assert sorted(p.name for p in (tmp_path / "run").glob("features-*.npz")) == cached
    assert unlit["train_events"] == every["train_events"] > 0
    assert unlit["threshold_table"] == every["threshold_table"]
    assert unlit["chosen_on"].endswith(", in the windows where the light test finds no light")
    assert unlit["config"]["windows"] == "unlit"
    card = read_card(tmp_path / "run" / "model.safetensors")
    assert "fitted on the windows where the light test finds no light" in card.notes
    lit_config = dataclasses.replace(config, windows="lit")
    with pytest.raises(EdeflareError, match="no training rows in the windows where the light "
                       "test finds a light"):  # fmt: skip
        train_head([tmp_path / "data"], base, tmp_path / "run", lit_config, progress=False)
    # the unlit expert's weights were not touched by the refused run
    assert read_card(tmp_path / "run" / "model.safetensors").notes == card.notes


def test_the_cli_refuses_windows_without_the_light_free_feature(tmp_path, capsys):
    code = main(["train-head", str(tmp_path), "--out", str(tmp_path / "run"), "--windows", "lit",
                 "--features", "net_logit,polarity"])  # fmt: skip
    assert code != 0
    assert "light_free" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
