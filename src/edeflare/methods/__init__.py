"""De-flaring methods behind one registry, and streaming de-flaring of files.

Every method, learned or classical, is a callable
``method(events, sensor_size, *, rng=None) -> events`` made by name:

>>> import edeflare
>>> edeflare.list_methods()  # doctest: +NORMALIZE_WHITESPACE
['dv-bafilter', 'dv-fastdecay', 'dv-knoise', 'efr', 'model', 'pfd-a', 'pfd-b', 'raw',
 'voxel']
>>> pfd_b = edeflare.create_method("pfd-b", window_us=25_000)

============  =========================================================================
``model``     a trained E-DeflareNet (:mod:`edeflare.models`), the bundled one by default
``raw``       identity (the input, copied): the "no de-flaring" reference
``voxel``     Voxel Transform: 20 ms windows, encode 8 bins, decode (seeded); the
              paper's "null network" control
``efr``       EFR linear comb filter (:mod:`edeflare.baselines.efr`), paper settings
``pfd-a``     PFD with ``score_select = 1`` (:mod:`edeflare.baselines.pfd`)
``pfd-b``     PFD with ``score_select = 0``
``dv-*``      dv-processing's noise filters (:mod:`edeflare.baselines.dv`, the ``dv``
              extra): ``dv-fastdecay``, ``dv-bafilter``, ``dv-knoise``, their defaults
============  =========================================================================

The package's modules each hold one job: :mod:`~edeflare.methods.base` the
interface and the registry, :mod:`~edeflare.methods.streaming` files streamed
window by window (:func:`deflare_file`), :mod:`~edeflare.methods.batch` many
files into a folder, parallel, sharded and resumable (:func:`deflare_files`), and
one module per family of methods
(:mod:`~edeflare.methods.classical`, :mod:`~edeflare.methods.filters`,
:mod:`~edeflare.methods.model`). New methods join with :func:`register_method`
(a factory whose keyword parameters are the method's parameters;
:func:`create_method` rejects any other name).
"""

from __future__ import annotations

from . import classical, filters, model  # noqa: F401  (registers the methods)
from .base import (
    METHODS,
    Method,
    Streamer,
    create_method,
    deflare,
    list_methods,
    method_parameters,
    register_method,
)
from .batch import BatchReport, FileResult, deflare_files
from .classical import VoxelParams
from .model import ModelParams
from .streaming import DeflareStats, StreamRun, deflare_file
from .windows import WindowStreamer

__all__ = [
    "METHODS",
    "BatchReport",
    "DeflareStats",
    "FileResult",
    "Method",
    "ModelParams",
    "StreamRun",
    "Streamer",
    "VoxelParams",
    "WindowStreamer",
    "create_method",
    "deflare",
    "deflare_file",
    "deflare_files",
    "list_methods",
    "method_parameters",
    "register_method",
]
