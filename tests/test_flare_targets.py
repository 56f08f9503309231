"""benchmarks/flare_targets.py: the eflare-forward and eflare-mini targets' code paths on
small simulated sets."""

from __future__ import annotations

import argparse

import pytest

from conftest import load_benchmark
from edeflare.data.generate import RECIPES, generate_dataset
from edeflare.eval.metrics import METRICS


@pytest.fixture
def flare_targets(monkeypatch):
    return load_benchmark(monkeypatch, "flare_targets")


def test_the_eflare_forward_target_scores_every_method(flare_targets, tmp_path):
    pytest.importorskip("dv_processing")  # the dv-processing baselines
    small = RECIPES["eflare-forward"].replace(
        sequences=2, test_sequences=2, sensor_size=(64, 48), duration_us=40_000
    )
    generate_dataset(small, tmp_path / "eflare-forward", progress=False)
    rows, verdicts = flare_targets.forward_set(argparse.Namespace(data=tmp_path, model=None))
    means = {r.pop("method"): r for r in rows}
    assert list(means) == ["raw", *flare_targets.BASELINES, "model", "keep-only oracle"]
    wins, chamfer = verdicts
    assert wins["requirement"] == ">= 7 of 8" and chamfer["requirement"] == "<= 0.60"
    beaten = [
        m
        for m in METRICS
        if all(
            flare_targets._better(m, means["model"][m], v[m])
            for row, v in means.items()
            if row not in ("model", "keep-only oracle")
        )
    ]
    assert wins["measured"] == len(beaten) and (wins["met"] == "yes") == (len(beaten) >= 7)
    assert all(m in wins["note"] for m in METRICS if m not in beaten)
    ratio = means["model"]["chamfer"] / means["raw"]["chamfer"]
    assert chamfer["measured"] == round(ratio, 4) and (chamfer["met"] == "yes") == (ratio <= 0.6)
    oracle = means["keep-only oracle"]["chamfer"] / means["raw"]["chamfer"]
    assert chamfer["note"] == f"keep-only oracle {oracle:.3f}" and oracle < 1.0


def test_the_mini_target_shows_what_deleting_can_reach(flare_targets, tmp_path, monkeypatch):
    small = RECIPES["eflare-mini"].replace(
        sequences=2, test_sequences=2, sensor_size=(64, 48), duration_us=40_000
    )
    generate_dataset(small, tmp_path / "mini", progress=False)
    files = sorted((tmp_path / "mini" / "test").glob("*.h5"))
    monkeypatch.setattr(flare_targets, "_dataset", lambda *a, **k: files)
    rows, verdicts = flare_targets.mini_split(argparse.Namespace(data=tmp_path, model=None))
    means = {r.pop("method"): r for r in rows}
    assert list(means) == ["raw", "model", "eflare", "keep-only oracle"]
    per_metric, reach, speed = verdicts[:8], verdicts[8], verdicts[9]
    for verdict, m in zip(per_metric, METRICS, strict=True):
        oracle_worse = flare_targets._better(m, means["eflare"][m], means["keep-only oracle"][m])
        assert verdict["note"] == f"keep-only oracle {means['keep-only oracle'][m]:.4f}" + (
            ", worse" if oracle_worse else ""
        )
        met = not flare_targets._better(m, means["eflare"][m], means["model"][m])
        assert verdict["met"] == ("yes" if met else "NO")
    assert reach["measured"] == sum(", worse" not in v["note"] for v in per_metric)
    assert speed["target"].startswith("speed")


def test_the_annotated_set_takes_the_night_recording_only_when_it_is_faerys(
    flare_targets, tmp_path, capsys
):
    args = argparse.Namespace(real=tmp_path / "real", faery=None)
    assert flare_targets.annotated(args) == []  # nothing there: each skipped, said so
    assert capsys.readouterr().out.count("skipped") == len(flare_targets.RECORDINGS)
    (tmp_path / "faery").mkdir()
    (tmp_path / "faery" / "evt3.raw").write_bytes(b"% not the recording\n")
    args.faery = tmp_path / "faery"
    with pytest.raises(SystemExit, match=r"evt3\.raw: not faery 0\.7\.1's evt3\.raw"):
        flare_targets.annotated(args)


def test_the_leave_one_out_chooses_every_knob_on_the_other_recordings(
    flare_targets, real_data, tmp_path, monkeypatch
):
    """Two real recordings: the DAVIS lamps (a light) and the DAVIS street (none). Held out,
    each is scored at the setting the other chose: the street alone asks to keep the most."""
    import reference_window

    monkeypatch.setattr(reference_window, "PICTURE", tmp_path / "absent.png")
    monkeypatch.setattr(flare_targets, "RECORDINGS", ("davis346_flicker_lamps.aedat4",))
    monkeypatch.setattr(flare_targets, "NO_LIGHT", ("davis346_street_cars.aedat4",))
    args = argparse.Namespace(real=real_data, faery=None, model=None)
    rows, verdicts = flare_targets.leave_one_out_set(args)
    lamps, street = rows
    assert (lamps["recording"], lamps["light"], street["light"]) == (
        "davis346_flicker_lamps", "yes", "no",
    )  # fmt: skip
    assert lamps["card"] == pytest.approx(0.8715, abs=1e-4)  # the card's, four phases
    assert street["card"] == pytest.approx(0.9832, abs=1e-4)  # the share it keeps
    # the street chose for the lamps: the lowest threshold keeps the most of it
    assert lamps["threshold of the others"] == 0.2
    assert lamps["held out (every knob)"] < lamps["card"]
    assert lamps["best in-sample"] >= lamps["card"]
    assert street["held out (every knob)"] <= street["best in-sample"]
    names = [v["target"] for v in verdicts]
    assert names == [
        "davis346_flicker_lamps: flare removed, every knob held out",
        "davis346_flicker_lamps: light kept, every knob held out",
        "davis346_flicker_lamps: scene kept, every knob held out",
        "davis346_street_cars: kept, every knob held out",
    ]
    assert verdicts[0]["measured"] == pytest.approx(lamps["flare removed"], abs=1e-4)


def test_the_reference_window_is_held_out_with_the_recording_it_is_cut_from(flare_targets):
    names = ["prophesee_gen3_rotating_light", "night_recording", "reference_window", "evt2"]
    assert flare_targets.same_recording(names) == {"reference_window": "night_recording"}
    assert flare_targets.same_recording(names[:1] + names[2:]) == {}  # without --faery
