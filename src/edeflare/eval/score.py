"""Scoring de-flaring on real recordings without ground truth: regions around the lights.

A real recording has no flare-free twin, but its light sources are known
(annotated, or detected), and flare lies around them. Each input event is
put, with its own timestamp, in one region of each source's geometry at that
time (sources may move):

- **light**: inside the source (disc of radius ``r``, or polygon); for a
  source with a ``response_us`` (a moving light's pixels go on firing after
  it has passed, for as long as their photoreceptors take to settle), inside
  any of its discs of the last ``response_us``: the comet its disc sweeps;
- **rim**: within ``margin_px`` outside it; counted nowhere (the source's
  edge is neither clearly light nor clearly flare);
- **halo**: the annulus ``r + margin_px < d <= halo_factor * r`` (``d`` the
  distance from the centre; for a polygon, its distance to the polygon plus
  ``r``, the radius of the disc of equal area), or out to the source's own
  ``halo_outer_px``;
- **ghost**: the disc of radius ``ghost_factor * r`` (or ``ghost_radius_px``)
  around the source's reflection through the image centre, ``(W - 1 - cx,
  H - 1 - cy)``: where lens ghosts of a point source fall;
- **background**: everything else.

Light wins over every other region (of any source), halo and ghost over
background; an event in a halo and a ghost counts in both. For a method's
output the same regions are applied to the output events (again each at its
own time), and per region and per aligned window of ``window_us``

    kept = sum_w min(n_out[w], n_in[w]) / sum_w n_in[w]

which, for a method that only deletes events (every filter here), is exactly
the fraction of the region's input events it kept; a method that synthesises
events cannot make up for a loss in one window with additions in another.
The scores are

- ``halo_removed``, ``ghost_removed``: ``1 - kept`` in the halo, the ghosts;
- ``flare_removed``: ``1 - kept`` in halo and ghosts together;
- ``light_kept``, ``background_kept``: ``kept`` in the light, the background;
- ``combined``: the harmonic mean of ``flare_removed``, ``light_kept`` and
  ``background_kept``, ``3 / (1/a + 1/b + 1/c)`` (0 when any is 0): high only
  when a method removes the flare *and* keeps the light *and* keeps the rest
  of the scene, so neither "remove everything" nor "keep everything" scores.
  A term whose region holds no input event is left out (and reported as
  missing). An annotation of a scene with nothing outside the lights (a light
  in the dark) may set ``score_background: false``: its background is sensor
  noise, which a denoiser rightly removes, so ``background_kept`` is reported
  but left out of ``combined`` (the harmonic mean of the other two).

Light sources (:mod:`edeflare.lights`) come from a JSON annotation
(:func:`~edeflare.lights.load_lights`) or are detected window by window
(:func:`~edeflare.lights.detect_lights`, the brightest compact regions of the
event density).

Examples
--------
>>> from edeflare.events import make_events
>>> from edeflare.lights import Lights, LightSource
>>> ev = make_events([0, 1, 2, 3], [10, 15, 30, 49], [10, 10, 10, 39], [1, 1, 1, 1])
>>> lights = Lights((LightSource.circle(10, 10, 2),), halo_factor=6.0, ghost_factor=1.0)
>>> classify_events(ev, lights, (60, 50)).labels.tolist()  # light, halo, background, ghost
['light', 'halo', 'background', 'ghost']
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import EventFileError, ParameterError
from ..events import SensorSize, check_events, check_sensor_size, window_start_for
from ..lights import Lights, load_lights, measure_regions, track_lights

__all__ = [
    "MethodScore",
    "Regions",
    "ScoreReport",
    "classify_events",
    "combined_score",
    "score_events",
    "score_recording",
]

REGIONS = ("light", "halo", "ghost", "flare", "background")
DARK_SHARE = 0.01
"""Detected lights whose background holds at most this share of a recording's events are
lights in the dark: the background is sensor noise, reported but not scored (as the
annotation of the Prophesee Gen3 light says of its 0.6 %)."""
_LABELS = np.array(["background", "light", "rim", "halo", "ghost", "halo+ghost"])


@dataclasses.dataclass(frozen=True)
class Regions:
    """Per-event region membership (bool arrays of the events' length)."""

    light: np.ndarray
    rim: np.ndarray
    halo: np.ndarray
    ghost: np.ndarray
    background: np.ndarray

    @property
    def flare(self) -> np.ndarray:
        """Halo or ghost."""
        return self.halo | self.ghost

    @property
    def labels(self) -> np.ndarray:
        """One label per event: light, rim, halo, ghost, halo+ghost or background."""
        code = np.zeros(self.light.shape, dtype=np.int64)
        code[self.halo] = 3
        code[self.ghost & ~self.halo] = 4
        code[self.ghost & self.halo] = 5
        code[self.rim] = 2
        code[self.light] = 1
        return _LABELS[code]

    def mask(self, region: str) -> np.ndarray:
        """The membership of one of ``REGIONS``."""
        return self.flare if region == "flare" else getattr(self, region)


def classify_events(events: np.ndarray, lights: Lights, sensor_size: SensorSize) -> Regions:
    """Put each event, at its own time, in the regions of the lights (see the module docstring).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> from edeflare.lights import LightSource
    >>> src = LightSource.track([[0, 10, 10, 2], [100, 30, 10, 2]])
    >>> ev = make_events([0, 100], [18, 30], [10, 10], [1, 1])  # 8 px off, then on it
    >>> classify_events(ev, Lights((src,)), (64, 48)).labels.tolist()
    ['halo', 'light']
    """
    width, height = check_sensor_size(sensor_size)
    n = events.size
    x = events["x"].astype(np.float64)
    y = events["y"].astype(np.float64)
    t = events["t"]
    light = np.zeros(n, dtype=bool)
    near = np.zeros(n, dtype=bool)  # light or rim
    halo = np.zeros(n, dtype=bool)
    ghost = np.zeros(n, dtype=bool)
    for s in lights.sources:
        dist, cx, cy, r = s.distance(x, y, t)
        present = np.isfinite(cx)
        if s.kind == "polygon":
            from ..lights import Polygon

            inside = Polygon(s.points).contains(x, y)
        else:
            inside = dist <= 0.0
        outer = s.halo_outer_px if s.halo_outer_px is not None else lights.halo_factor * r
        light |= inside
        near |= present & (dist <= lights.margin_px)
        halo |= present & (dist > lights.margin_px) & (dist + r <= outer)
        if s.ghost:
            gr = s.ghost_radius_px if s.ghost_radius_px is not None else lights.ghost_factor * r
            ghost |= present & (np.hypot(x - (width - 1 - cx), y - (height - 1 - cy)) <= gr)
    rim = near & ~light
    halo &= ~near
    ghost &= ~near
    background = ~(near | halo | ghost)
    return Regions(light, rim, halo, ghost, background)


def combined_score(flare_removed: float, light_kept: float, background_kept: float) -> float:
    """Harmonic mean of the defined (not NaN) terms; 0 when any is 0, NaN when none is defined.

    Examples
    --------
    >>> round(combined_score(0.8, 0.9, 0.6), 4)  # 3 / (1/0.8 + 1/0.9 + 1/0.6)
    0.7448
    >>> combined_score(0.0, 1.0, 1.0), combined_score(float("nan"), 0.5, 0.5)
    (0.0, 0.5)
    """
    terms = [float(v) for v in (flare_removed, light_kept, background_kept) if not math.isnan(v)]
    if not terms:
        return math.nan
    if min(terms) <= 0:
        return 0.0
    return len(terms) / sum(1.0 / v for v in terms)


@dataclasses.dataclass(frozen=True)
class MethodScore:
    """The scores of one method on one recording (fractions in [0, 1]; NaN: empty region)."""

    method: str
    events_out: int
    halo_removed: float
    ghost_removed: float
    flare_removed: float
    light_kept: float
    background_kept: float
    combined: float
    seconds: float | None = None
    """Run time of the method (None for a given prediction file)."""
    rtf: float | None = None
    """Real-time factor: run time over the recording's span (below 1: faster than real time)."""
    combined_worst: float | None = None
    """Scored at several window phases (:func:`score_recording`'s ``phases``): the scores
    above are the means over the phases, this the lowest combined score of one phase."""

    def to_dict(self) -> dict[str, Any]:
        """Plain values (NaN as None)."""
        return {k: _plain(v) for k, v in dataclasses.asdict(self).items()}


def _plain(v: Any) -> Any:
    if isinstance(v, float) and math.isnan(v):
        return None
    return v


def _window_index(t: np.ndarray, start: int, window_us: int, n_windows: int) -> np.ndarray:
    return np.clip((t - start) // window_us, 0, n_windows - 1).astype(np.int64)


def _kept(n_in: np.ndarray, n_out: np.ndarray) -> float:
    total = int(n_in.sum())
    return math.nan if total == 0 else float(np.minimum(n_in, n_out).sum()) / total


def score_events(
    events: np.ndarray,
    outputs: Mapping[str, np.ndarray],
    lights: Lights,
    sensor_size: SensorSize,
    *,
    window_us: int = 20_000,
    seconds: Mapping[str, float] | None = None,
) -> list[MethodScore]:
    """Score de-flared versions of ``events`` on the regions of ``lights``.

    Parameters
    ----------
    events : numpy.ndarray
        The input recording (sorted events).
    outputs : mapping of str to numpy.ndarray
        Method name -> its output on ``events``.
    lights : Lights
    sensor_size : (width, height)
    window_us : int
        Windows over which counts are compared (see the module docstring).
    seconds : mapping of str to float, optional
        Run times, for the real-time factor.

    Returns
    -------
    list of MethodScore
        In the order of ``outputs``.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> from edeflare.lights import Lights, LightSource
    >>> ev = make_events([0, 1, 2, 3], [10, 15, 30, 49], [10, 10, 10, 39], [1, 1, 1, 1])
    >>> lights = Lights((LightSource.circle(10, 10, 2),), ghost_factor=1.0)
    >>> (s,) = score_events(ev, {"drop-halo": ev[[0, 2, 3]]}, lights, (60, 50))
    >>> s.halo_removed, s.ghost_removed, s.light_kept, s.background_kept
    (1.0, 0.0, 1.0, 1.0)
    >>> round(s.flare_removed, 3), round(s.combined, 3)  # 1 of 2 flare events; 3/(2+1+1)
    (0.5, 0.75)
    """
    check_events(events, sensor_size)
    size = check_sensor_size(sensor_size)
    if isinstance(window_us, bool) or not isinstance(window_us, (int, np.integer)) or window_us < 1:
        raise ParameterError(f"window_us must be a positive int, got {window_us!r}")
    if events.size == 0:
        raise ParameterError("no input events: nothing to score")
    start = window_start_for(int(events["t"][0]), int(window_us))
    n_windows = (int(events["t"][-1]) - start) // int(window_us) + 1
    span_s = max(1, int(events["t"][-1]) - int(events["t"][0])) / 1e6

    def counts(ev: np.ndarray) -> dict[str, np.ndarray]:
        regions = classify_events(ev, lights, size)
        w = _window_index(ev["t"], start, int(window_us), n_windows)
        return {r: np.bincount(w[regions.mask(r)], minlength=n_windows) for r in REGIONS}

    n_in = counts(events)
    scores = []
    for name, out in outputs.items():
        check_events(out, size)
        n_out = counts(out)
        kept = {r: _kept(n_in[r], n_out[r]) for r in REGIONS}
        flare_removed = 1.0 - kept["flare"]
        sec = None if seconds is None else seconds.get(name)
        scores.append(
            MethodScore(
                method=name,
                events_out=int(out.size),
                halo_removed=1.0 - kept["halo"],
                ghost_removed=1.0 - kept["ghost"],
                flare_removed=flare_removed,
                light_kept=kept["light"],
                background_kept=kept["background"],
                combined=combined_score(
                    flare_removed,
                    kept["light"],
                    kept["background"] if lights.score_background else math.nan,
                ),
                seconds=sec,
                rtf=None if sec is None else sec / span_s,
            )
        )
    return scores


@dataclasses.dataclass(frozen=True)
class ScoreReport:
    """What :func:`score_recording` measured: the regions' input counts and one row per method."""

    recording: str
    sensor_size: SensorSize
    span_us: int
    events_in: int
    region_events: dict[str, int]
    lights: Lights
    lights_from: str
    window_us: int
    rows: tuple[MethodScore, ...]
    phases: int = 1

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dictionary."""
        return {
            "recording": self.recording,
            "sensor_size": list(self.sensor_size),
            "span_us": self.span_us,
            "events_in": self.events_in,
            "region_events": self.region_events,
            "lights_from": self.lights_from,
            "lights": self.lights.to_dict() if self.lights_from == "detect" else None,
            "margin_px": self.lights.margin_px,
            "halo_factor": self.lights.halo_factor,
            "ghost_factor": self.lights.ghost_factor,
            "window_us": self.window_us,
            "phases": self.phases,
            "score_background": self.lights.score_background,
            "combined": "harmonic mean of flare_removed, light_kept"
            + (", background_kept" if self.lights.score_background else ""),
            "methods": [r.to_dict() for r in self.rows],
        }

    def to_markdown(self) -> str:
        """The table (percentages; ``-`` for an empty region or an unknown time)."""
        re = self.region_events
        lines = [
            f"Recording `{Path(self.recording).name}` ({self.sensor_size[0]}x"
            f"{self.sensor_size[1]}, {self.span_us / 1000:.0f} ms, {self.events_in:,} events; "
            f"lights: {self.lights_from}). Input events per region: light {re['light']:,}, "
            f"halo {re['halo']:,}, ghost {re['ghost']:,}, background {re['background']:,} "
            f"(rim {re['rim']:,} not scored)."
            + (
                ""
                if self.lights.score_background
                else " Background: sensor noise, not in the "
                "combined score (the harmonic mean of flare removed and light kept)."
            )
            + (
                ""
                if self.phases == 1
                else f" Methods run at {self.phases} window phases (the recording delayed "
                f"by multiples of {self.window_us // self.phases / 1000:g} ms): mean scores, "
                "and the worst phase's combined score."
            ),
            "",
            "| method | halo removed | ghost removed | flare removed | light kept "
            "| background kept | combined | "
            + ("worst phase | " if self.phases > 1 else "")
            + "events out | time (s) | RTF |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
            + ("---:|" if self.phases > 1 else ""),
        ]
        for r in self.rows:
            cells = [_pct(v) for v in (r.halo_removed, r.ghost_removed, r.flare_removed,
                                       r.light_kept, r.background_kept)]  # fmt: skip
            comb = "-" if math.isnan(r.combined) else f"{r.combined:.3f}"
            if self.phases > 1:
                worst = r.combined_worst
                comb += " | " + ("-" if worst is None or math.isnan(worst) else f"{worst:.3f}")
            sec = "-" if r.seconds is None else f"{r.seconds:.2f}"
            rtf = "-" if r.rtf is None else f"{r.rtf:.2f}"
            lines.append(
                f"| {r.method} | {' | '.join(cells)} | {comb} | {r.events_out:,} | {sec} | {rtf} |"
            )
        return "\n".join(lines) + "\n"


def _mean_over_phases(
    first: list[MethodScore], others: list[list[MethodScore]]
) -> list[MethodScore]:
    """Each row of ``first`` (phase 0, given files included) with its scores averaged over
    the phases of ``others`` (the methods run, in order) and its worst combined score."""
    terms = ("halo_removed", "ghost_removed", "flare_removed", "light_kept",
             "background_kept", "combined")  # fmt: skip
    rows = []
    for i, row in enumerate(first):
        if not others or i >= len(others[0]):  # a given file: one phase
            rows.append(row)
            continue
        all_rows = [row, *(o[i] for o in others)]
        mean = {t: float(np.mean([getattr(r, t) for r in all_rows])) for t in terms}
        combined = [r.combined for r in all_rows]
        worst = math.nan if any(math.isnan(c) for c in combined) else min(combined)
        rows.append(dataclasses.replace(row, **mean, combined_worst=worst))
    return rows


def _pct(v: float) -> str:
    return "-" if math.isnan(v) else f"{100 * v:.1f} %"


def score_recording(
    recording: str | os.PathLike[str],
    methods: Sequence[str] = ("raw",),
    preds: Mapping[str, str | os.PathLike[str]] | None = None,
    lights: str | os.PathLike[str] | Lights | None = None,
    *,
    window_us: int = 20_000,
    max_sources: int = 1,
    overrides: Mapping[str, float] | None = None,
    method_params: Mapping[str, Mapping[str, Any]] | None = None,
    rng: np.random.Generator | int | None = 0,
    phases: int = 1,
    measure: bool = True,
) -> ScoreReport:
    """Score methods (run now) and de-flared files on a real recording without ground truth.

    Parameters
    ----------
    recording : path-like
        Any readable event file.
    methods : sequence of str
        Registered methods to run on it (:func:`edeflare.list_methods`), timed.
    preds : mapping of str to path-like, optional
        Name -> a de-flared version of the recording (same sensor size).
    lights : path-like or Lights, optional
        An annotation (:func:`~edeflare.lights.load_lights`); None detects and
        follows the lights (:func:`~edeflare.lights.track_lights`, ``max_sources``
        of them; the background left out of the combined score where it holds at
        most :data:`DARK_SHARE` of the events).
    window_us : int
        Window of the count comparison and of detection.
    overrides : mapping, optional
        ``margin_px``, ``halo_factor``, ``ghost_factor`` replacing the
        annotation's.
    method_params : mapping, optional
        Method name -> parameters for :func:`edeflare.create_method`.
    rng : numpy.random.Generator or int, optional
        Seeds methods that draw.
    measure : bool
        With detected lights: measure how far each one's halo and ghost reach in
        the recording (:func:`~edeflare.lights.measure_regions`: the fixed factors
        the least halo, no ghost region where none shows); False: the fixed
        factors alone.
    phases : int
        Run each method on the recording delayed by ``k * window_us // phases``
        for ``k = 0 .. phases - 1`` (then undone) and report the mean scores,
        with the worst phase's combined score. A model decides per aligned
        window, and where a recording's windows start relative to what it
        shows (a lamp's 100 Hz flicker, a moving source) is chance: one phase
        can flatter or wrong it. Filters that see no windows score the same at
        every phase. Given files (``preds``) are scored once.

    Returns
    -------
    ScoreReport

    Raises
    ------
    EventFileError
        An unreadable or empty recording, a prediction of another sensor size
        (naming the file).
    AnnotationError
        A bad annotation (naming the file).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare import write_events
    >>> from edeflare.events import make_events
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> ev = make_events([0, 1, 2, 3], [10, 15, 30, 49], [10, 10, 10, 39], [1, 1, 1, 1])
    >>> write_events(folder / "rec.h5", ev, (60, 50))
    >>> _ = (folder / "lights.json").write_text('{"sources": [{"circle": [10, 10, 2]}]}')
    >>> report = score_recording(folder / "rec.h5", ["raw"], lights=folder / "lights.json")
    >>> report.rows[0].flare_removed, report.rows[0].light_kept, report.rows[0].combined
    (0.0, 1.0, 0.0)
    """
    from ..io import read_events
    from ..methods import create_method

    events, size = read_events(recording)
    if events.size == 0:
        raise EventFileError(recording, "no events: nothing to score")
    if isinstance(lights, Lights):
        the_lights, source = lights, "given"
    elif lights is not None:
        the_lights, source = load_lights(lights, size), os.fspath(lights)
    else:
        try:
            the_lights = track_lights(events, size, max_sources=max_sources)
        except ParameterError as exc:
            raise EventFileError(recording, str(exc)) from None
        source = "detect"
    if overrides:
        try:
            the_lights = dataclasses.replace(the_lights, **dict(overrides))
        except TypeError as exc:
            raise ParameterError(str(exc)) from None
    regions: Regions | None = None
    if source == "detect":
        if measure:
            # where the flare reaches, from the recording (the factors the least halo)
            the_lights = measure_regions(events, size, the_lights)
        regions = classify_events(events, the_lights, size)
        if regions.background.mean() <= DARK_SHARE:  # a light in the dark: noise around it
            # (the regions do not depend on score_background)
            the_lights = dataclasses.replace(the_lights, score_background=False)
    if isinstance(phases, bool) or not isinstance(phases, (int, np.integer)) or phases < 1:
        raise ParameterError(f"phases must be a positive int, got {phases!r}")
    if phases > window_us:
        raise ParameterError(f"phases ({phases}) must be at most window_us ({window_us})")
    made = {}
    for name in methods:
        if name in made:
            raise ParameterError(f"method {name!r} given twice")
        made[name] = create_method(name, **dict((method_params or {}).get(name, {})))
    # phase k -> method name -> output (each phase's outputs back on the recording's clock)
    by_phase: list[dict[str, np.ndarray]] = []
    seconds: dict[str, float] = {}
    for k in range(int(phases)):
        delay = k * int(window_us) // int(phases)
        delayed = events  # methods never change their input
        if delay:
            delayed = events.copy()
            delayed["t"] += delay
        outputs_k = {}
        for name, method in made.items():
            t0 = time.perf_counter()
            out = method(delayed, size, rng=rng)
            if k == 0:
                seconds[name] = time.perf_counter() - t0
            if delay:
                out["t"] -= delay
            outputs_k[name] = out
        by_phase.append(outputs_k)
    outputs = by_phase[0]
    for name, path in (preds or {}).items():
        if name in outputs:
            raise ParameterError(f"method name {name!r} given twice")
        pred, pred_size = read_events(path)
        if tuple(pred_size) != tuple(size):
            raise EventFileError(
                path, f"sensor size {pred_size[0]}x{pred_size[1]} differs from the "
                f"recording's {size[0]}x{size[1]} ({os.fspath(recording)})"
            )  # fmt: skip
        outputs[name] = pred
    rows = score_events(events, outputs, the_lights, size, window_us=window_us, seconds=seconds)
    if phases > 1:
        rows = _mean_over_phases(
            rows,
            [score_events(events, o, the_lights, size, window_us=window_us) for o in by_phase[1:]],
        )
    if regions is None:
        regions = classify_events(events, the_lights, size)
    counts = {r: int(regions.mask(r).sum()) for r in (*REGIONS, "rim")}
    return ScoreReport(
        recording=os.fspath(recording),
        sensor_size=size,
        span_us=int(events["t"][-1]) - int(events["t"][0]),
        events_in=int(events.size),
        region_events=counts,
        lights=the_lights,
        lights_from=source,
        window_us=int(window_us),
        rows=tuple(rows),
        phases=int(phases),
    )
