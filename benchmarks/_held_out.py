"""A real recording's scores at any rule knobs and keep threshold, without rerunning a model.

:meth:`edeflare.models.infer.ModelDeflarer.rule_terms` splits a mask model's keep logits
into its own (every rule off) and each rule shift's term, in the windowings of every
window phase ``score_recording(phases=...)`` runs (the recording delayed by ``k * window
/ phases``, each phase the mean of the model's two views). :class:`TermsRecording` then
scores any knobs and threshold from them, as the product would (checked:
``tests/test_held_out_terms.py`` and the card's row of ``flare_targets.py``), so that a
leave-one-out search over every knob (``flare_targets.py``) runs the network once per
recording.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from edeflare.eval.phases import TERMS, measure_phases, phase_views
from edeflare.eval.score import classify_events
from edeflare.lights import Lights
from edeflare.models.infer import ModelDeflarer
from edeflare.models.two_view import check_phase_shift

__all__ = ["TERMS", "TermsRecording", "measure_phases", "phase_views"]


class TermsRecording:
    """One recording's rule terms at every window phase, and its regions where annotated.

    Parameters
    ----------
    name : str
    deflarer : ModelDeflarer
        The model (torch runtime).
    events, sensor_size
        The recording.
    lights : Lights, optional
        Its annotation; without one the score is the share of events kept.
    phases : int
        As ``score_recording``'s.
    """

    def __init__(
        self,
        name: str,
        deflarer: ModelDeflarer,
        events: np.ndarray,
        sensor_size: tuple[int, int],
        lights: Lights | None = None,
        phases: int = 4,
    ) -> None:
        shift = check_phase_shift(None, deflarer.card, deflarer.weights)
        delays, self.views = phase_views(deflarer.window_us, shift, phases)
        self.name, self.lit = name, lights is not None
        self.terms = deflarer.rule_terms(events, sensor_size, delays)
        self.regions = None
        if lights is not None:
            r = classify_events(events, lights, sensor_size)
            back = r.background if lights.score_background else None
            self.regions = (r.flare, r.light, back)

    def measure(self, knobs: Mapping[str, float], thresholds: Sequence[float]) -> np.ndarray:
        """``(thresholds, 4)``: flare removed, light kept, scene kept and the combined
        score, each the mean over the phases (NaN where not scored); without an
        annotation the share kept stands in the combined column."""
        phases = [self.terms.logits(knobs, views=v) for v in self.views]
        return measure_phases(phases, self.regions, thresholds)
