"""One camera, several recordings: event simulators that share a sensor draw.

A script's :class:`~edeflare.sim.script.SensorSpec` is one camera. Every video
of a sample (flare, light source, background, or the sums of the forward
model) goes through a simulator of that camera: the same model and parameters
and, for the ideal model, the same per-pixel thresholds (derived from
``spec.seed``), each with its own random stream (one recording each), and all
started cold or warm as ``spec.warm_start`` says (:mod:`edeflare.sim.dvs`).
"""

from __future__ import annotations

import numpy as np

from ..events import SensorSize, check_sensor_size
from ._validation import make_rng
from .dvs import IdealSimulator, VoltmeterSimulator, draw_thresholds, make_simulator
from .script import SensorSpec

__all__ = ["camera_simulator", "sensor_pair"]


def sensor_pair(
    spec: SensorSpec, sensor_size: SensorSize
) -> tuple[VoltmeterSimulator | IdealSimulator, VoltmeterSimulator | IdealSimulator]:
    """Two simulators of one camera (``spec``), for the flare and the light video.

    Their random streams are the first two children of ``SeedSequence(spec.seed)``;
    the third seeds the ideal model's per-pixel thresholds.

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
    warm = spec.warm_start
    if spec.model == "voltmeter":
        return (
            VoltmeterSimulator(size, spec.voltmeter, rng=flare_rng, warm_start=warm),
            VoltmeterSimulator(size, spec.voltmeter, rng=light_rng, warm_start=warm),
        )
    thresholds = draw_thresholds(size, spec.ideal, rng=np.random.default_rng(camera_seq))
    return (
        IdealSimulator(size, spec.ideal, thresholds=thresholds, rng=flare_rng, warm_start=warm),
        IdealSimulator(size, spec.ideal, thresholds=thresholds, rng=light_rng, warm_start=warm),
    )


def camera_simulator(
    spec: SensorSpec,
    sensor_size: SensorSize,
    *,
    rng: np.random.Generator | int | None = None,
) -> VoltmeterSimulator | IdealSimulator:
    """A simulator of the camera ``spec`` with its own random stream ``rng``.

    For the ideal model the per-pixel thresholds are the camera's (derived from
    ``spec.seed`` as :func:`sensor_pair` derives them), so the background sees
    the same pixels as the flare and light videos.

    Examples
    --------
    >>> sim = camera_simulator(SensorSpec(model="ideal", seed=1), (4, 4), rng=0)
    >>> bool((sim._c_on == sensor_pair(SensorSpec(model="ideal", seed=1), (4, 4))[0]._c_on).all())
    True
    """
    size = check_sensor_size(sensor_size)
    gen = make_rng(rng)
    if spec.model == "voltmeter":
        return make_simulator(
            "voltmeter", size, spec.voltmeter, rng=gen, warm_start=spec.warm_start
        )
    camera_seq = np.random.SeedSequence(spec.seed).spawn(3)[2]
    thresholds = draw_thresholds(size, spec.ideal, rng=np.random.default_rng(camera_seq))
    return make_simulator(
        "ideal", size, spec.ideal, thresholds=thresholds, rng=gen, warm_start=spec.warm_start
    )
