"""A lamp's lit surroundings: illumination that flickers with the lamp, flare in the input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from edeflare.data.eflare import FlareConfig, draw_inputs
from edeflare.data.recipe import Recipe
from edeflare.errors import ParameterError
from edeflare.sim._validation import SimError
from edeflare.sim.background import SceneConfig
from edeflare.sim.pair import simulate_pair
from edeflare.sim.script import FlareScript, Flicker, Trajectory
from edeflare.sim.surround import LitSurround, SurroundConfig

SIZE = (48, 36)


def _script(**changes):
    return FlareScript(duration_us=20_000, fps=4000.0, **changes)


def test_illumination_falls_as_cos_cubed_and_flickers_with_the_lamp():
    script = _script(flicker=Flicker(100.0, "square", 0.6))  # 1 then 0.4 each half period
    lit = LitSurround(gain=4.0, radius_px=5.0)
    cx, cy = script.position_px(0, SIZE)
    assert (cx, cy) == (24.0, 18.0)
    on = lit.illumination(script, 1_000, SIZE)
    off = lit.illumination(script, 6_000, SIZE)
    steady = lit.illumination(script, 6_000, SIZE, steady=True)
    assert on.shape == (36, 48)
    assert on[18, 24] == pytest.approx(1 + 4.0)  # at the foot: 1 + gain
    assert off[18, 24] == pytest.approx(1 + 4.0 * 0.4)
    assert steady[18, 24] == pytest.approx(1 + 4.0 * 0.7)  # the mean factor, 1 - 0.6 / 2
    # at the lamp's distance from the wall: (1 + 1) ** -1.5 of the foot's
    assert on[18, 29] - 1 == pytest.approx(4.0 * 2**-1.5)
    assert on[18 + 3, 24 + 4] - 1 == pytest.approx(4.0 * 2**-1.5)
    assert on.min() > 1.0 and on[0, 0] < 1.1  # the far corner: the ambient alone, nearly
    # without flicker the observed and the flare-free illumination are the same
    still = _script()
    assert np.array_equal(
        lit.illumination(still, 3_000, SIZE), lit.illumination(still, 3_000, SIZE, steady=True)
    )


def test_a_script_round_trips_with_and_without_lit_surroundings():
    plain = _script()
    assert "surround" not in plain.to_dict()  # older scripts read and write the same
    lit = dataclasses.replace(plain, surround=LitSurround(2.5, 12.0))
    assert lit.to_dict()["surround"] == {"gain": 2.5, "radius_px": 12.0}
    assert FlareScript.from_json(lit.to_json()) == lit
    with pytest.raises(SimError, match="lit surround"):
        FlareScript.from_dict({**lit.to_dict(), "surround": {"gain": 1.0}})
    with pytest.raises(SimError, match="radius_px"):
        LitSurround(1.0, 0.0)


def test_the_config_draws_in_proportion_and_is_left_out_of_the_recipe_while_off():
    assert "surround" not in FlareConfig().to_dict()  # recipes keep their digests
    on = FlareConfig.from_dict({"variant": "forward", "surround": {"probability": 0.5}})
    assert on.to_dict()["surround"] == {"probability": 0.5, "gain": [0.5, 20.0],
                                        "radius": [1.0, 3.0]}  # fmt: skip
    assert FlareConfig.from_dict(on.to_dict()) == on
    rng = np.random.default_rng(0)
    script = _script()  # light radius 4 px
    drawn = [on.surround.draw(script, rng) for _ in range(2000)]
    lit = [d for d in drawn if d is not None]
    assert 0.45 < len(lit) / 2000 < 0.55
    gains = np.array([d.gain for d in lit])
    radii = np.array([d.radius_px for d in lit])
    assert 0.5 <= gains.min() and gains.max() <= 20.0 and 4.0 <= radii.min() <= radii.max() <= 12
    # log-uniform: the median gain near the geometric mean sqrt(0.5 * 20) = 3.16
    assert 2.6 < np.median(gains) < 3.8
    bad_configs = [({"probability": 2}, "probability"), ({"gain": (0, 1)}, "gain"),
                   ({"radius": (3, 1)}, "radius"), ({"glow": 1}, "glow.*surround")]  # fmt: skip
    for bad, match in bad_configs:
        with pytest.raises(ParameterError, match=match):
            SurroundConfig.from_dict(bad)


def test_a_recipe_with_lit_surroundings_needs_the_forward_model():
    with pytest.raises(ParameterError, match="needs variant='forward'"):
        physical = {"variant": "physical", "surround": {"probability": 1}}
        Recipe(sensor_size=SIZE, duration_us=20_000, config=FlareConfig.from_dict(physical))
    recipe = Recipe(sensor_size=SIZE, duration_us=20_000, scene=SceneConfig(fps=1000.0),
                    config=FlareConfig.from_dict({"variant": "forward",
                                                  "surround": {"probability": 1.0}}))  # fmt: skip
    inputs = draw_inputs(recipe, 0)
    assert isinstance(inputs.script.surround, LitSurround)
    # its own seed stream: the script's other draws are the plain recipe's
    plain = draw_inputs(recipe.replace(config=FlareConfig(variant="forward")), 0)
    assert dataclasses.replace(inputs.script, surround=None) == plain.script
    with pytest.raises(SimError, match="needs variant='forward'"):
        simulate_pair(inputs.script, inputs.background, SIZE, variant="physical")


def test_the_flickering_surroundings_fire_in_the_input_only():
    """A still camera and light, a lamp flickering at 100 Hz: its lit surroundings fire at
    each half period in the observed stream, not in the flare-free twin."""
    size = (96, 72)
    recipe = Recipe(sensor_size=size, duration_us=20_000, seed=4,
                    scene=SceneConfig(fps=1000.0, pan_px_per_s=(0.0, 0.0), zoom_per_s=(0, 0),
                                      shake_px=(0.0, 0.0), noise_rate_hz=(0.0, 0.0)),
                    config=FlareConfig(variant="forward"))  # fmt: skip
    inputs = draw_inputs(recipe, 0)
    script = dataclasses.replace(
        inputs.script,
        trajectory=Trajectory((0.5, 0.5), 0.0, 0.0),
        flicker=Flicker(100.0, "square", 0.8),
        light=dataclasses.replace(inputs.script.light, radius_px=2.0, exposure=2.0),
    )
    lit = dataclasses.replace(script, surround=LitSurround(gain=8.0, radius_px=6.0))
    pairs = [simulate_pair(s, inputs.background, size, variant="forward",
                           forward_seed=inputs.forward_seed) for s in (script, lit)]  # fmt: skip
    plain, lamp = pairs
    extra = lamp.input.size - plain.input.size
    assert extra > 2000  # the surroundings, at each edge of the square flicker
    # the flare-free twins differ by the steady light's effect on the sensor only
    assert abs(lamp.gt.size - plain.gt.size) < 0.1 * extra

    cx, cy = script.position_px(0, size)

    def near(events, r):
        return int((np.hypot(events["x"] - cx, events["y"] - cy) < r).sum())

    # around the lamp, falling with distance: nearly all within 4 of its distances
    assert near(lamp.input, 24) - near(plain.input, 24) > 0.9 * extra
    inner = (near(lamp.input, 6) - near(plain.input, 6)) / (np.pi * 6**2)
    ring = (
        near(lamp.input, 24) - near(lamp.input, 18) - near(plain.input, 24) + near(plain.input, 18)
    ) / (np.pi * (24**2 - 18**2))
    assert inner > 3 * ring > 0


def test_the_lit_recipe_round_trips_and_its_surround_enters_the_digest():
    from edeflare.data.recipe import RECIPES

    for _, part in RECIPES["eflare-lit"].parts:
        assert part.config.surround.probability == 1.0 and part.config.variant == "forward"
        assert Recipe.from_dict(part.to_dict()) == part
        off = part.replace(config=dataclasses.replace(part.config, surround=SurroundConfig()))
        assert off.sha256() != part.sha256()
        assert "surround" not in off.to_dict() and "surround" in part.to_dict()
