"""Recipes: common fields plus the kind's config, with the format-1 dicts and digests kept."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from edeflare.cli import main
from edeflare.data.dsec_flare import DsecFlareConfig
from edeflare.data.eflare import FlareConfig
from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES, Mix, Recipe
from edeflare.errors import ParameterError
from edeflare.sim.background import NightStreet
from edeflare.sim.optics_scene import OpticsSceneConfig
from edeflare.sim.script import ScriptConfig

# Digests recorded at dc60cee, before the recipe was split into common fields and the
# kind's config: datasets made then must still resume (their files store these).
DIGESTS_BEFORE_THE_SPLIT = {
    "dsec-flare": "c8a659c1befbdba42ebfab7c4b2534a72a3f96b1203b25718ba22a507fd4eeda",
    "eflare-2.7k": "835283772cee62c53407fed94284db15f5276c157fe5387f5587d8d19c63b714",
    "eflare-mini": "2810cf3cd796a0abaede6caa1f99007e9e2e12f31a60356b6a5515da0024bda4",
    "eflare-r-sim": "3b3ab7daeceeef5903a7de172fd2e27eab1c4feccc81cf038b837f4232574d4b",
    "eflare-r-sim-mini": "b758921262a863ab7eb4fdc20535c7fb25be155416caaa60141c3bd9b484a0f5",
}
# eflare-night changed on purpose after the split (hot pixels to remove, 2026-11-25); its
# digest then (d00bcb15...) is the old recipe's. Pinned so that it changes only on purpose.
DIGESTS_SINCE = {
    "eflare-night": "3da4706a3e07b77dc7b655b4237a6c2e85f4208724c3d7197f126a0195c8b142",
    "eflare-night-sparse": "beff5735ac634792174a6b828af05bd7315012a4c5a2bd81cec4e5e47d155c6d",
    "eflare-day-street": "2c842cc3ea4f7f6285b9b623a46e2b2ddd62aebcf3b34818800d330665d937e0",
    "eflare-forward": "12bdd521da6bdd18d057d68b465c45750b08c7342970ad148e2ef8409fd9624c",
    "eflare-forward-hd": "d0e9e2c5ae9c5b389b677bd6c9690f9c8f2084189ab9a0af706da5c886df41d9",
}
# eflare-mix: its parts' recipes and the mix's own digest (over the parts' names and digests).
MIX_DIGEST = "c3b75faf4b0352936221fa5fefb1219bcdaa5dac45c1c00d50e3f20dca8c6836"
MIX_PARTS = {  # part: (recipe digest, sequences, test sequences, sensor size, seed)
    "night-346": ("9d76b0027eacc433e8859c3fc0ddfd8e3aa633cf234ef25ecffa8a48ccb0db7c",
                  60, 6, (346, 260), 201),
    "day-346": ("54a1376afa3a60dedb099b2daec34a80d9b30fbbf46388e7d4c9d630260946de",
                20, 2, (346, 260), 202),
    "dense-640": ("292f6dc73723c09572b15a85848565513ff2b85b5271ec338125da29e53ac004",
                  28, 3, (640, 480), 203),
    "dense-1280": ("07e94a551d39a0c3a2698c537f5526f525be0590e0c61c6964da5478e35129b0",
                   10, 1, (1280, 720), 204),
    "sparse-1280": ("32ed420157ac0ea3592e0f6b986432e6644e736e2f7ee8561396170cc62152a3",
                    10, 1, (1280, 720), 205),
}  # fmt: skip
# The recipe the `night` model's day data was first generated with, under the name
# "eflare-day-mix": eflare-day-street is that recipe, renamed. The name is stored in the
# files (their recipe and recipe_sha256 attributes), never drawn from: the events are
# the same.
DAY_MIX_DIGEST = "b611e449bf406db8b82393e3c8ad9e491d28cb21059040748497ccc8b1aab114"
FLAT_BEFORE_THE_SPLIT = {  # old flat dicts and their digests at dc60cee
    "beb8317d7f81eae1f72cbec6bb35a8ea0cd893ed86e8fa218429ef07143b33c2": {
        "variant": "forward",
        "sequences": 5,
        "test_sequences": 1,
        "flare7k": "/x/y/Flare7K",
        "components": False,
        "weights": "counts",
        "jitter_us": 10.0,
        "script": {"exposure": [1.0, 2.0]},
        "accumulation": {"base_level": 3},
    },
    "cfd5f195afdd2c9fc8752fdac068bca7ccf78b999f9643a2b2bad950e83329c7": {
        "background": "recorded",
        "background_files": ["/a/b.h5", "/a/c/d.h5"],
    },
    "43ea752107d2fd5672ad96b08c885540a90994ee1739e1ac1ed43d1e5beb38df": {
        "kind": "optics",
        "background": "recorded",
        "background_files": ["/a/b.h5"],
        "optics": {"psf_grid": 64},
    },
    "aa9c6fff514bff409dab159bc1d533b745f0f65b4df2c3fcb3da973b29ce059f": {
        "kind": "dsec",
        "dsec": {"root": "/data/dsec", "rectify": True},
    },
}


@pytest.mark.parametrize("name", sorted(DIGESTS_BEFORE_THE_SPLIT | DIGESTS_SINCE))
def test_named_recipes_keep_their_digests_and_round_trip(name):
    recipe = RECIPES[name]
    assert recipe.sha256() == (DIGESTS_BEFORE_THE_SPLIT | DIGESTS_SINCE)[name]
    assert Recipe.from_dict(recipe.to_dict()) == recipe


@pytest.mark.parametrize("digest", sorted(FLAT_BEFORE_THE_SPLIT))
def test_old_flat_dicts_read_to_the_same_digest(digest):
    recipe = Recipe.from_dict(FLAT_BEFORE_THE_SPLIT[digest])
    assert recipe.sha256() == digest
    assert Recipe.from_dict(recipe.to_dict()) == recipe


def test_each_kind_holds_its_own_config():
    assert isinstance(RECIPES["eflare-mini"].config, FlareConfig)
    assert isinstance(RECIPES["eflare-r-sim"].config, OpticsSceneConfig)
    assert isinstance(RECIPES["dsec-flare"].config, DsecFlareConfig)
    assert RECIPES["eflare-night"].config.sensing.enabled
    assert not RECIPES["eflare-mini"].config.sensing.enabled
    # the flare kind's keys sit beside the common ones; another kind's under its name
    assert RECIPES["eflare-mini"].to_dict()["variant"] == "physical"
    assert RECIPES["eflare-r-sim"].to_dict()["optics"]["psf_grid"] == OpticsSceneConfig().psf_grid
    with pytest.raises(ParameterError, match="config must be a OpticsSceneConfig"):
        Recipe(kind="optics", config=FlareConfig())


def test_replace_routes_each_key_to_where_it_lives():
    mini = RECIPES["eflare-mini"]
    r = mini.replace(seed=4, variant="simple", script=ScriptConfig(psf_grid=64))
    assert (r.seed, r.config.variant, r.config.script.psf_grid) == (4, "simple", 64)
    assert r.config.weights == mini.config.weights and r.sensor_size == mini.sensor_size
    assert mini.config.variant == "physical"  # frozen: the original is unchanged
    optics = RECIPES["eflare-r-sim-mini"].replace(optics=OpticsSceneConfig(psf_grid=64))
    assert optics.config.psf_grid == 64 and optics.kind == "optics"
    with pytest.raises(ParameterError, match=r"key\(s\) \['variant'\] for a 'optics'"):
        RECIPES["eflare-r-sim-mini"].replace(variant="simple")
    with pytest.raises(ParameterError, match=r"\['variantt'\].*valid keys: .*'variant'"):
        mini.replace(variantt="simple")


def test_the_flare_configs_checks_reach_the_recipe():
    with pytest.raises(ParameterError, match="variant must be one of"):
        Recipe.from_dict({"variant": "fancy"})
    with pytest.raises(ParameterError, match=r"variant='forward' .* needs the background"):
        Recipe.from_dict({"variant": "forward", "background": "recorded",
                          "background_files": ["a.h5"]})  # fmt: skip
    with pytest.raises(ParameterError, match="'variant' applies to 'flare' recipes"):
        Recipe.from_dict({"kind": "optics", "variant": "forward"})
    # an optics dict carries the flare kind's defaults (format 1): accepted as they are
    d = RECIPES["eflare-r-sim"].to_dict()
    assert d["variant"] == "physical" and Recipe.from_dict(d) == RECIPES["eflare-r-sim"]


def test_the_day_street_is_the_night_recipe_over_a_street_lit_as_by_day(tmp_path):
    day, night = RECIPES["eflare-day-street"], RECIPES["eflare-night"]
    assert (day.sequences, day.test_sequences, day.seed) == (72, 6, 101)
    assert day.replace(name="eflare-day-mix").sha256() == DAY_MIX_DIGEST
    # the night recipe's lights, flare script, sensing and hot pixels; only the street differs
    assert day.config == night.config and day.sensor_size == night.sensor_size
    assert day.replace(scene=night.scene, sequences=180, test_sequences=12, seed=0,
                       name="eflare-night") == night  # fmt: skip
    scene = day.scene
    assert scene.sky_level == (80.0, 200.0) and scene.building_level == (60.0, 200.0)
    assert scene.sky_level[0] > night.scene.sky_level[1]  # brighter than any night sky
    assert scene.lamps == (0, 2)


def test_the_day_street_generates(tmp_path):
    tiny = RECIPES["eflare-day-street"].replace(
        sequences=2, test_sequences=1, sensor_size=(48, 36), duration_us=20_000
    )
    report = generate_dataset(tiny, tmp_path, progress=False)
    assert report.manifest["complete"] and report.manifest["recipe"]["name"] == "eflare-day-street"
    with h5py.File(tmp_path / "train" / "seq_00000.h5") as f:
        assert f.attrs["recipe"] == "eflare-day-street"
        assert f.attrs["recipe_sha256"] == tiny.sha256()
        assert {"input", "gt", "gt_full"} <= set(f)  # keep-only targets of the sparse sensing


# ------------------------------------------------------------------- eflare-mix and forward


def test_the_mix_has_its_parts_in_order_with_their_digests():
    mix = RECIPES["eflare-mix"]
    assert isinstance(mix, Mix) and mix.sha256() == MIX_DIGEST
    assert mix.part_names == tuple(MIX_PARTS) and mix.sequences == 128
    for part, (digest, n, n_test, size, seed) in MIX_PARTS.items():
        r = mix.part(part)
        assert (r.sha256(), r.sequences, r.test_sequences, r.sensor_size, r.seed) == (
            digest,
            n,
            n_test,
            size,
            seed,
        ), part
        assert r.name == f"eflare-mix.{part}" and r.kind == "flare"
        assert Recipe.from_dict(r.to_dict()) == r
    seeds = [r.seed for _, r in mix.parts]
    others = {r.seed for name, r in RECIPES.items() if isinstance(r, Recipe)}
    assert len(set(seeds)) == len(seeds) and not set(seeds) & others


def test_the_mix_parts_are_the_recipes_they_name():
    mix, night, day = RECIPES["eflare-mix"], RECIPES["eflare-night"], RECIPES["eflare-day-street"]
    # night-346 and day-346 are eflare-night and eflare-day-street, other counts and seeds
    for part, recipe in (("night-346", night), ("day-346", day)):
        r = mix.part(part)
        same = {"sequences": recipe.sequences, "test_sequences": recipe.test_sequences}
        assert r.replace(name=recipe.name, seed=recipe.seed, **same) == recipe
    dense, dense_hd = mix.part("dense-640"), mix.part("dense-1280")
    for r in (dense, dense_hd):
        assert r.config.variant == "forward" and not r.config.components
        assert not r.config.sensing.enabled and r.background == "synthetic"
    assert dense.scene == night.scene
    assert dense.config.script == RECIPES["eflare-forward"].config.script
    assert dense_hd.config.script == RECIPES["eflare-forward-hd"].config.script
    # at 1280x720 the pixel ranges are x1.5 and the flare template is larger
    s, hd = dense.config.script, dense_hd.config.script
    assert hd.light_radius_px == (3.0, 15.0) and hd.ghost_radius_px == (6.0, 75.0)
    assert hd.travel_px == (0.0, 270.0) and (s.psf_grid, hd.psf_grid) == (512, 576)
    assert dense_hd.scene.pan_px_per_s == (3.0, 375.0)
    sparse = mix.part("sparse-1280")
    assert sparse.config.sensing == night.config.sensing and sparse.config.variant == "physical"
    assert sparse.config.script.light_radius_px == (4.5, 42.0)
    assert sparse.config.script.exposure == night.config.script.exposure


def test_dense_sources_are_10_to_the_1_5_to_10_to_the_5_times_the_street():
    """The mapping in recipe.py: S = exposure * peak / B with B the night street's median."""
    script = RECIPES["eflare-forward"].config.script
    assert script.exposure == (2.5, 8000.0)
    assert (script.star_probability, script.blade_probability) == (0.7, 0.6)
    assert (script.glare_probability, script.ghost_probability) == (0.8, 0.95)
    medians = [
        float(np.median(NightStreet((640, 480), RECIPES["eflare-forward"].scene, rng=s).frame(0)))
        for s in range(8)
    ]
    level = float(np.median(medians))
    assert 13.0 < level < 21.0
    peak = sum(script.peak) / 2
    low, high = (np.log10(e * peak / level) for e in script.exposure)
    assert abs(low - 1.5) < 0.15 and abs(high - 5.0) < 0.15


def test_the_forward_test_sets_are_all_test_and_never_trained_on(tmp_path):
    training = {name: r for name, r in RECIPES.items() if isinstance(r, Recipe)}
    for mix in (m for m in RECIPES.values() if isinstance(m, Mix)):
        training |= {f"{mix.name}/{p}": r for p, r in mix.parts}
    sets = (("eflare-forward", (640, 480), 12), ("eflare-forward-hd", (1280, 720), 4))
    for name, size, n in sets:
        r = training.pop(name)
        assert (r.kind, r.config.variant, r.sensor_size) == ("flare", "forward", size)
        assert r.sequences == r.test_sequences == n
        assert {r.split_of(i) for i in range(n)} == {"test"}
        assert r.scene.lamps == RECIPES["eflare-night"].scene.lamps  # a night street
    test_sets = {RECIPES["eflare-forward"], RECIPES["eflare-forward-hd"]}
    for name, r in training.items():
        assert r.seed not in {t.seed for t in test_sets}, name
    assert not test_sets & {r for _, r in RECIPES["eflare-mix"].parts}
    # with ground truth: a small eflare-forward writes input and gt, all in test/ (also
    # when the command line asks for fewer sequences)
    argv = ["simulate", str(tmp_path), "--recipe", "eflare-forward", "--sequences", "2"]
    assert main([*argv, "--sensor-size", "48x36", "--duration-ms", "20", "--no-progress"]) == 0
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert [f["file"] for f in manifest["files"]] == ["test/seq_00000.h5", "test/seq_00001.h5"]
    assert manifest["recipe"]["test_sequences"] == 2 and not (tmp_path / "train").exists()
    with h5py.File(tmp_path / "test" / "seq_00000.h5") as f:
        assert f.attrs["variant"] == "forward" and f.attrs["recipe"] == "eflare-forward"
        assert {"input", "gt", "flare", "light", "background"} <= set(f)


def test_eflare_near_holds_near_objects_in_every_part_and_seeds_of_its_own():
    mix = RECIPES["eflare-near"]
    assert isinstance(mix, Mix)
    parts = dict(mix.parts)
    assert list(parts) == ["near-346", "near-640", "near-night-640", "near-1280"]
    assert [(r.sequences, r.test_sequences, r.sensor_size) for r in parts.values()] == [
        (16, 2, (346, 260)), (16, 2, (640, 480)), (10, 1, (640, 480)), (7, 1, (1280, 720)),
    ]  # fmt: skip
    assert all(r.scene.near_objects == (1, 2) for r in parts.values())
    assert parts["near-1280"].scene.near_speed_px_per_s == (450.0, 4500.0)
    assert all(r.config.components for r in parts.values())  # the scene alone stored
    others = [
        r.seed
        for name in RECIPES.names()
        if name != "eflare-near"
        for r in (dict(RECIPES[name].parts).values() if isinstance(RECIPES[name], Mix)
                  else [RECIPES[name]])
    ]  # fmt: skip
    assert not {r.seed for r in parts.values()} & set(others)
    assert "near_objects" in parts["near-640"].to_dict()["scene"]
    assert mix.sha256() == "235bad6bfab27381d65d50dc1a85176b4506bb73eaef476e995a2d0b539f0e86"
