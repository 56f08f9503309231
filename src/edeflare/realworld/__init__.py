r"""Real paired captures (E-Flare-R): alignment, reference cleaning, noise, crop and slicing.

The paper's real-world benchmark (Sec. 3.3, Appendix A.3) records every scene
twice with a static camera: an *observation* pass with a flare-making filter
(e.g. a six-point star filter) in front of the lens, and a *reference* pass
without it. There is no hardware trigger between the passes; a strobe light in
the scene is the common clock. This module turns such a pair of recordings
(any readable format) into a paired benchmark in the layout of simulated
datasets (:mod:`edeflare.data.pairs`), one step per function:

1. **Temporal alignment.** :func:`polarity_signature` bins a stream into ON
   and OFF counts; its ON fraction over time is the strobe's signature (every
   switch-on is a burst of ON events, every switch-off a burst of OFF events),
   and it is insensitive to the filter multiplying the event counts.
   :func:`estimate_offset` cross-correlates the two signatures (Pearson
   correlation over the overlap at each lag, coarse bins over the search
   range), refines in fine bins around the peak with a parabolic fit, and
   returns an :class:`Alignment`: the offset (``t_reference = t_observation +
   offset_us``), the peak correlation, the best correlation at any clearly
   different lag, and a confidence that falls to 0 when these are equal (a
   periodic strobe searched over more than half its period is ambiguous).
2. **Reference cleaning.** Light sources (:mod:`edeflare.lights`: fixed
   ones, a disc or a polygon) are parsed from ``circle:CX,CY,R`` /
   ``polygon:X1,Y1,...`` (:func:`~edeflare.lights.parse_lights`), read from
   JSON (:func:`~edeflare.lights.load_lights`) or found as the brightest
   compact region of the event-density map
   (:func:`~edeflare.lights.detect_light_source`). :func:`clean_reference`
   removes the events of the glare zone (:func:`glare_mask`: within
   ``glare_radius_px`` of a source but outside every source) and keeps the
   sources themselves.
3. **Noise injection.** :func:`estimate_background_rate` measures the
   sensor's background activity (events per second per pixel, and its ON
   fraction) in the quiet regions of the observation; :func:`inject_noise`
   adds Poisson noise at that rate to the cleaned reference, by default only
   where cleaning removed everything, so the ground truth is not unnaturally
   clean there.
4. **Crop and slicing.** :func:`pair_recordings` runs the whole pipeline
   streaming (two passes over each file, memory bounded by one window), crops
   the sensor centre (640x480 by default) and writes one sequence file per
   aligned window (100 ms by default) plus ``manifest.json`` and a plot of the
   signatures before and after alignment. ``edeflare pair`` is its command
   line.

Output layout (``OUT`` may collect many scenes, one ``edeflare pair`` run each)::

    OUT/test/NAME_0000.h5        sequence files: groups input + gt, attrs t_start_us/t_end_us
    OUT/test/input/NAME_0000.h5  the observation window alone (for edeflare deflare/evaluate)
    OUT/test/gt/NAME_0000.h5     the ground truth alone
    OUT/alignment/NAME.png       signatures before / after alignment, correlation curve
    OUT/manifest.json            per scene: files, offset, confidence, lights, noise; written last

``edeflare benchmark OUT/test`` and ``edeflare evaluate --gt OUT/test/gt
--pred raw=OUT/test/input`` read it unchanged.
"""

from __future__ import annotations

from ._common import LOW_CONFIDENCE, PairingError
from ._common import MANIFEST_FORMAT as MANIFEST_FORMAT  # public, not in __all__
from .align import Alignment, estimate_offset
from .geometry import clean_reference, glare_mask
from .noise import NoiseEstimate, draw_noise, estimate_background_rate, inject_noise
from .pipeline import PairConfig, PairReport, pair_recordings
from .plot import plot_alignment
from .signature import RecordingScan, Signature, polarity_signature, scan_recording

__all__ = [
    "LOW_CONFIDENCE",
    "Alignment",
    "NoiseEstimate",
    "PairConfig",
    "PairReport",
    "PairingError",
    "RecordingScan",
    "Signature",
    "clean_reference",
    "draw_noise",
    "estimate_background_rate",
    "estimate_offset",
    "glare_mask",
    "inject_noise",
    "pair_recordings",
    "plot_alignment",
    "polarity_signature",
    "scan_recording",
]
