"""The physics-driven simulator, stage 1: flare optics, flare videos and event simulators.

- :mod:`~edeflare.sim.optics`: pupil functions -> clean / perturbed PSF pair (Fourier optics).
- :mod:`~edeflare.sim.flare`: light source, scattering flare, glare, reflective ghosts,
  Flare7K++ assets.
- :mod:`~edeflare.sim.script`: :class:`FlareScript`, every random choice of one sample.
- :mod:`~edeflare.sim.render`: the flare video and the light video of a script, streamed.
- :mod:`~edeflare.sim.dvs`: streaming, seeded event simulators fed frame by frame
  (DVS-Voltmeter, the ideal log-intensity model).
- :mod:`~edeflare.sim.camera`: simulators of one camera (one sensor draw, a random
  stream per video).
- :mod:`~edeflare.sim.stage1`: both videos of a script through one sensor: flare and
  light events.
- :mod:`~edeflare.sim.pair`: the one streaming frame loop (:func:`run_frames` and its
  per-frame observers) and :func:`simulate_pair`, one input / ground-truth pair of a
  script over a background.

Examples
--------
>>> from edeflare.sim import FlareScript, simulate_flare_events
>>> ev = simulate_flare_events(FlareScript(duration_us=1000, fps=2000.0), (32, 24))
>>> ev.flare.dtype.names
('t', 'x', 'y', 'p')
"""

from __future__ import annotations

from ._validation import SimError
from .dvs import (
    DVS240_K,
    DVS346_K,
    IdealParams,
    IdealSimulator,
    VoltmeterParams,
    VoltmeterSimulator,
    draw_thresholds,
    make_simulator,
    simulate_frames,
)
from .flare import GhostSpec, GlareSpec, find_flare7k_pairs, light_source, scattering_flare
from .optics import PSFConfig, PSFPair, psf_pair
from .pair import SimulatedPair, run_frames, simulate_pair
from .render import Renderer, flare7k_names, render
from .script import FlareScript, ScriptConfig, draw_script
from .stage1 import FlareEvents, sensor_pair, simulate_flare_events

__all__ = [
    "DVS240_K",
    "DVS346_K",
    "FlareEvents",
    "FlareScript",
    "GhostSpec",
    "GlareSpec",
    "IdealParams",
    "IdealSimulator",
    "PSFConfig",
    "PSFPair",
    "Renderer",
    "ScriptConfig",
    "SimError",
    "SimulatedPair",
    "VoltmeterParams",
    "VoltmeterSimulator",
    "draw_script",
    "draw_thresholds",
    "find_flare7k_pairs",
    "flare7k_names",
    "light_source",
    "make_simulator",
    "psf_pair",
    "render",
    "run_frames",
    "scattering_flare",
    "sensor_pair",
    "simulate_flare_events",
    "simulate_frames",
    "simulate_pair",
]
