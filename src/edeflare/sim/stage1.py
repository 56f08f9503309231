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

from ..events import SensorSize
from .camera import sensor_pair
from .pair import EventRecorder, run_frames
from .render import Renderer
from .script import FlareScript

__all__ = ["FlareEvents", "sensor_pair", "simulate_flare_events"]


@dataclass(frozen=True)
class FlareEvents:
    """Events of the flare video (real lens) and of the light video (ideal lens)."""

    flare: np.ndarray
    light: np.ndarray
    sensor_size: tuple[int, int]


def simulate_flare_events(
    script: FlareScript,
    sensor_size: SensorSize = (640, 480),
    *,
    flare7k: str | os.PathLike[str] | None = None,
) -> FlareEvents:
    """Render ``script`` frame by frame and simulate both videos' events.

    The frames go through :func:`edeflare.sim.pair.run_frames` to two simulators
    of the script's camera (:func:`~edeflare.sim.camera.sensor_pair`).

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
    flare, light = EventRecorder(sim_flare, "flare"), EventRecorder(sim_light, "light")
    frames = ((t_us, {"flare": f, "light": lt}) for t_us, f, lt in renderer)
    run_frames(frames, [flare, light])
    return FlareEvents(flare.events(), light.events(), renderer.sensor_size)
