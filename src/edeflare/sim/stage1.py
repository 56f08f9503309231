"""Stage 1 of the simulator: the flare events and the light-source events of one script.

:func:`simulate_flare_events` streams the two videos of :func:`~edeflare.sim.render.render`
through two simulators built from the script's one sensor draw
(:func:`sensor_pair`): the same model and parameters, and for the ideal model
the same per-pixel thresholds (one camera); each video gets its own random
stream, spawned from the sensor seed (two recordings with that camera), so
the result is a pure function of the script.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..events import EVENT_DTYPE, SensorSize, check_sensor_size
from .dvs import IdealSimulator, VoltmeterSimulator, draw_thresholds
from .render import Renderer
from .script import FlareScript, SensorSpec

__all__ = ["FlareEvents", "sensor_pair", "simulate_flare_events"]


@dataclass(frozen=True)
class FlareEvents:
    """Events of the flare video (real lens) and of the light video (ideal lens)."""

    flare: np.ndarray
    light: np.ndarray
    sensor_size: tuple[int, int]


def sensor_pair(
    spec: SensorSpec, sensor_size: SensorSize
) -> tuple[VoltmeterSimulator | IdealSimulator, VoltmeterSimulator | IdealSimulator]:
    """Two simulators of one camera (``spec``), for the flare and the light video.

    Examples
    --------
    >>> a, b = sensor_pair(SensorSpec(model="ideal", seed=1), (4, 4))
    >>> bool((a._c_on == b._c_on).all())
    True
    """
    size = check_sensor_size(sensor_size)
    flare_seq, light_seq, camera_seq = np.random.SeedSequence(spec.seed).spawn(3)
    flare_rng = np.random.default_rng(flare_seq)
    light_rng = np.random.default_rng(light_seq)
    if spec.model == "voltmeter":
        return (
            VoltmeterSimulator(size, spec.voltmeter, rng=flare_rng),
            VoltmeterSimulator(size, spec.voltmeter, rng=light_rng),
        )
    thresholds = draw_thresholds(size, spec.ideal, rng=np.random.default_rng(camera_seq))
    return (
        IdealSimulator(size, spec.ideal, thresholds=thresholds, rng=flare_rng),
        IdealSimulator(size, spec.ideal, thresholds=thresholds, rng=light_rng),
    )


def simulate_flare_events(
    script: FlareScript,
    sensor_size: SensorSize = (640, 480),
    *,
    flare7k: str | os.PathLike[str] | None = None,
) -> FlareEvents:
    """Render ``script`` frame by frame and simulate both videos' events.

    Examples
    --------
    >>> from edeflare.sim.script import Flicker
    >>> s = FlareScript(duration_us=2000, fps=4000.0, flicker=Flicker(500.0, depth=1.0))
    >>> ev = simulate_flare_events(s, (48, 32))
    >>> ev.flare.size > ev.light.size > 0
    True
    """
    renderer = Renderer(script, sensor_size, flare7k=flare7k)
    sim_flare, sim_light = sensor_pair(script.sensor, renderer.sensor_size)
    flare_chunks, light_chunks = [], []
    for t_us, flare, light in renderer:
        flare_chunks.append(sim_flare.feed(flare, t_us))
        light_chunks.append(sim_light.feed(light, t_us))
    empty = np.empty(0, dtype=EVENT_DTYPE)
    return FlareEvents(
        np.concatenate(flare_chunks) if flare_chunks else empty,
        np.concatenate(light_chunks) if light_chunks else empty,
        renderer.sensor_size,
    )
