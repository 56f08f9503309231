"""The one frame loop and simulate_pair: what the dataset generator's flare kind makes."""

from __future__ import annotations

import numpy as np
import pytest

from edeflare.data.eflare import draw_inputs
from edeflare.data.generate import generate_sequence
from edeflare.data.recipe import Recipe
from edeflare.events import make_events
from edeflare.sim._validation import SimError
from edeflare.sim.background import SceneConfig
from edeflare.sim.dvs import IdealParams, IdealSimulator
from edeflare.sim.pair import EventRecorder, EventSampler, StreamSampler, run_frames, simulate_pair

RECIPE = Recipe(
    sequences=2,
    test_sequences=1,
    sensor_size=(32, 24),
    duration_us=20_000,
    scene=SceneConfig(fps=1000.0),
)


@pytest.mark.parametrize("variant", ["physical", "forward"])
def test_simulate_pair_is_the_generators_flare_sequence(variant):

    recipe = RECIPE.replace(variant=variant)
    inputs = draw_inputs(recipe, 1)
    pair = simulate_pair(
        inputs.script,
        inputs.background,
        recipe.sensor_size,
        variant=variant,
        rng=inputs.compose_seed,
        forward_seed=inputs.forward_seed,
    )
    made = generate_sequence(recipe, 1)
    assert list(made.streams) == list(pair.streams)
    for name, events in pair.streams.items():
        assert np.array_equal(events, made.streams[name]), name


def test_samplers_interpolate_between_frames_and_hold_the_last():
    frames = [(0, {"v": np.zeros((1, 2))}), (1000, {"v": np.full((1, 2), 10.0)})]
    fixed = make_events([0, 500, 1000, 5000], [0, 1, 0, 1], [0, 0, 0, 0], [1, 1, 1, 1])
    sampler = EventSampler(fixed, "v")
    rec = EventRecorder(IdealSimulator((2, 1), IdealParams(c_on=0.5)), "v")
    stream = StreamSampler(rec, "v")
    run_frames(frames, [sampler, rec, stream])
    assert sampler.values.tolist() == [0.0, 5.0, 10.0, 10.0]
    assert stream.values().size == rec.events().size > 0


def test_bad_options_name_the_argument():
    inputs = draw_inputs(RECIPE, 0)
    with pytest.raises(SimError, match="variant"):
        simulate_pair(inputs.script, inputs.background, (32, 24), variant="nope")
    with pytest.raises(SimError, match="weights"):
        simulate_pair(inputs.script, inputs.background, (32, 24), weights="nope")
