"""The ablation (Table 3): configurations, equal scenes across variants, resume, the table."""

from __future__ import annotations

import json

import numpy as np
import pytest

from edeflare.ablate import ABLATIONS, VARIANT_ROWS, AblationConfig, run_ablation
from edeflare.cli import main
from edeflare.data.generate import generate_sequence
from edeflare.errors import ParameterError
from edeflare.io.dsec import DsecReader

# Two variants, two training sequences, three iterations: the pipeline in a few seconds.
QUICK = ABLATIONS["small"].replace(iterations=3, sequences=2, variants=("no-light", "physical"))


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("ablation")
    lines: list[str] = []
    result = run_ablation(QUICK, out, progress=False, log=lines.append)
    return out, result, lines


def test_configurations_train_equal_budgets_on_every_variant():
    assert list(VARIANT_ROWS) == [
        "simple",
        "simple+random",
        "physical+random",
        "no-light",
        "physical",
    ]
    for cfg in ABLATIONS.values():
        assert cfg.variants == tuple(VARIANT_ROWS)
        recipes = [cfg.recipe_for(v) for v in cfg.variants]
        assert [r.config.variant for r in recipes] == list(VARIANT_ROWS)
        # everything but the composition (and the name) is shared
        for r in recipes:
            assert (r.seed, r.sequences, r.sensor_size, r.duration_us) == (
                cfg.train_recipe.seed,
                cfg.train_recipe.sequences,
                cfg.train_recipe.sensor_size,
                cfg.train_recipe.duration_us,
            )
        # tested on the optics-based pairs (another simulator, as real captures are)
        assert cfg.test_recipe.kind == "optics" and cfg.train_recipe.kind == "flare"
        assert cfg.test_recipe.sensor_size == cfg.train_recipe.sensor_size
    assert ABLATIONS["cpu"].test_recipe.name == "eflare-r-sim-mini"
    assert ABLATIONS["paper"].test_recipe.name == "eflare-r-sim"
    assert ABLATIONS["paper"].training.iterations == 40_000
    assert ABLATIONS["paper"].training.preset == "unet3d.paper"


def test_variants_share_scenes_and_differ_in_composition():
    cfg = ABLATIONS["small"]
    simple = generate_sequence(cfg.recipe_for("simple"), 0)
    full = generate_sequence(cfg.recipe_for("physical"), 0)
    no_light = generate_sequence(cfg.recipe_for("no-light"), 0)
    for k in ("flare", "light", "background"):  # the same scene under every variant
        np.testing.assert_array_equal(simple.streams[k], full.streams[k])
    # PNL-ES suppresses events that the plain merge keeps; no-light drops the source from gt
    assert len(full.streams["input"]) < len(simple.streams["input"])
    assert len(no_light.streams["gt"]) < len(full.streams["gt"])


def test_bad_configurations_are_refused():
    base = ABLATIONS["small"]
    with pytest.raises(ParameterError, match="unknown variant"):
        base.replace(variants=("physical", "magic"))
    with pytest.raises(ParameterError, match="must include 'physical'"):
        base.replace(variants=("simple",))
    with pytest.raises(ParameterError, match="repeated"):
        base.replace(variants=("physical", "physical"))
    with pytest.raises(ParameterError, match="iterations must be an int >= 1"):
        base.replace(iterations=0)
    with pytest.raises(ParameterError, match="sequences must be an int >= 1"):
        base.replace(sequences=0)
    with pytest.raises(ParameterError, match="no test sequences"):
        AblationConfig("x", base.train_recipe, base.train_recipe, base.training)


def test_quick_ablation_writes_the_table_with_full_as_reference(quick_run):
    out, result, lines = quick_run
    assert list(result.table.values) == ["raw", "No Light", "Full"]
    assert result.table.reference == "Full"
    for variant in QUICK.variants:
        assert (out / "runs" / variant / "model.safetensors").is_file()
        assert len(list((out / "data" / variant / "train").glob("*.h5"))) == 2
    assert len(list((out / "test" / "test").glob("*.h5"))) == 3
    # the improvement row is Full against the only other row
    values = result.table.values
    full, other = values["Full"]["mse"], values["No Light"]["mse"]
    assert result.table.improvement["mse"] == pytest.approx(100 * (other - full) / other)
    md = (out / "table.md").read_text()
    assert "| raw (input) |" in md and "| Full |" in md and "Improvement (%)" in md
    payload = json.loads((out / "table.json").read_text())
    assert payload["config"]["variants"] == ["no-light", "physical"]
    assert payload["values"]["Full"]["mse"] == pytest.approx(full)
    assert (out / "table.csv").read_text().startswith("method,chamfer")
    assert any("[no-light] training" in line for line in lines)


def test_no_light_ground_truth_has_fewer_events_than_full(quick_run):
    out, _, _ = quick_run
    counts = {}
    for variant in QUICK.variants:
        path = sorted((out / "data" / variant / "train").glob("*.h5"))[0]
        with DsecReader(path, group="gt/events") as reader:
            counts[variant] = len(reader.read())
    assert counts["no-light"] < counts["physical"]


def test_rerun_resumes_without_retraining_and_gives_the_same_table(quick_run):
    out, result, _ = quick_run
    logs = {v: (out / "runs" / v / "train_log.csv").read_text() for v in QUICK.variants}
    again = run_ablation(QUICK, out, progress=False)
    for v in QUICK.variants:
        assert (out / "runs" / v / "train_log.csv").read_text() == logs[v]
    assert again.table.values == result.table.values


def test_rerun_with_another_configuration_is_refused(quick_run):
    out, _, _ = quick_run
    with pytest.raises(ParameterError, match=r"ablation\.json.*other values of \['training'\]"):
        run_ablation(QUICK.replace(iterations=4), out, progress=False)


def test_cli_rejects_unknown_configuration(tmp_path, capsys):
    assert main(["ablate", str(tmp_path / "a"), "--config", "huge"]) == 1
    assert "unknown ablation 'huge'" in capsys.readouterr().err
    assert not (tmp_path / "a").exists()


@pytest.mark.slow
def test_cli_small_ablation_runs_every_variant(tmp_path, capsys):
    out = tmp_path / "abl"
    assert main(["ablate", str(out), "--config", "small"]) == 0
    text = capsys.readouterr().out
    for label in VARIANT_ROWS.values():
        assert f"| {label} |" in text
    assert json.loads((out / "table.json").read_text())["raw"] == "raw"
