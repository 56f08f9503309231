"""The physics-driven simulator, stage 1: flare optics, flare videos and event simulators.

- :mod:`~edeflare.sim.dvs`: streaming, seeded event simulators fed frame by frame
  (DVS-Voltmeter, the ideal log-intensity model).
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

__all__ = [
    "DVS240_K",
    "DVS346_K",
    "IdealParams",
    "IdealSimulator",
    "SimError",
    "VoltmeterParams",
    "VoltmeterSimulator",
    "draw_thresholds",
    "make_simulator",
    "simulate_frames",
]
