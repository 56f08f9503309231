r"""The streaming frame loop that makes one input / ground-truth pair.

Every pair the simulator makes comes out of one loop, :func:`run_frames`: a
frame source yields ``(t_us, {video name -> (H, W) frame})`` and per-frame
*observers* see each frame in turn, with the previous one:

- :class:`EventRecorder` feeds one video (a named frame, or a function of the
  frames such as background + flare) to an event simulator and keeps its events;
- :class:`StreamSampler` samples a video at the events a recorder emitted in the
  frame interval, linearly in time between the two frames;
- :class:`EventSampler` samples a video at fixed events (e.g. the background's)
  as the frames pass them, holding the last frame after it.

Nothing but the current and the previous frame is kept, so a 640x480 sequence
of 600 frames never sits in memory. The users of the loop:

- :func:`simulate_pair` (here): the training pair of one
  :class:`~edeflare.sim.script.FlareScript` over one
  :class:`~edeflare.sim.background.Background`: the flare and light videos
  through one camera (:func:`~edeflare.sim.camera.sensor_pair`), both sampled at
  every background, flare and light event, then composed
  (:func:`~edeflare.sim.compose.compose_pair`, PNL-ES and its ablations) or,
  for ``variant="forward"``, the sums :math:`I_{bg} + I_f` and
  :math:`I_{bg} + I_{light}` simulated directly (Eq. 5-6);
- :func:`edeflare.sim.stage1.simulate_flare_events` (flare and light events only),
  :func:`edeflare.sim.compose.forward_pair` (the forward model on given frames),
  :func:`edeflare.sim.optics_scene.simulate_optics_pair` (the optics test pairs) and
  :meth:`edeflare.sim.background.SyntheticBackground.draw` (a synthetic street's events).

Examples
--------
>>> from edeflare.sim.background import SceneConfig, SyntheticBackground
>>> from edeflare.sim.script import FlareScript
>>> script = FlareScript(duration_us=5_000, fps=2000.0)
>>> bg = SyntheticBackground(SceneConfig(fps=1000.0)).draw(5_000, (32, 24), script.sensor, rng=1)
>>> pair = simulate_pair(script, bg, (32, 24), rng=0)
>>> sorted(pair.streams), int(pair.input["t"].max()) < 5_000
(['background', 'flare', 'gt', 'input', 'light'], True)
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numba
import numpy as np

from .._interrupt import check_interrupt
from ..events import EVENT_DTYPE, SensorSize, check_sensor_size
from ._validation import SimError, check_choice
from .camera import camera_simulator, sensor_pair
from .compose import VARIANTS, Components, CountIntensity, compose_pair
from .dvs import IdealSimulator, VoltmeterSimulator
from .render import Renderer
from .script import FlareScript

if TYPE_CHECKING:  # pragma: no cover - background.py runs its own frames through this loop
    from .background import Background

__all__ = [
    "PAIR_VARIANTS",
    "WEIGHTS",
    "EventRecorder",
    "EventSampler",
    "FrameObserver",
    "FrameRecorder",
    "SimulatedPair",
    "StageTimer",
    "StreamSampler",
    "run_frames",
    "simulate_pair",
]

Frames = Mapping[str, np.ndarray]
"""The frames of one instant: video name -> ``(H, W)`` intensity frame."""
Simulator = VoltmeterSimulator | IdealSimulator

WEIGHTS = ("intensity", "accumulation", "counts")
"""PNL-ES intensities: rendered videos (and the scene or the accumulation estimate for the
background), the accumulation estimate for the background even when synthetic, or the
authors' whole-window event counts for all three streams."""
PAIR_VARIANTS = (*VARIANTS, "forward")
"""Variants of :func:`simulate_pair`: the composition variants and the full forward model."""


class StageTimer:
    """Seconds spent per stage: ``with timer("render"): ...`` adds to ``timer.seconds``.

    Examples
    --------
    >>> timer = StageTimer(("render", "simulate"))
    >>> with timer("render"):
    ...     pass
    >>> sorted(timer.seconds)
    ['render', 'simulate']
    """

    def __init__(self, stages: Sequence[str]) -> None:
        self.seconds = dict.fromkeys(stages, 0.0)
        self._stage: str | None = None
        self._t0 = 0.0

    def __call__(self, stage: str) -> StageTimer:
        self._stage = stage
        return self

    def __enter__(self) -> None:
        self._t0 = time.perf_counter()

    def __exit__(self, *exc: object) -> None:
        if self._stage is not None:
            self.seconds[self._stage] = (
                self.seconds.get(self._stage, 0.0) + time.perf_counter() - self._t0
            )


class FrameObserver(Protocol):
    """What :func:`run_frames` calls at every frame (``stage`` names its timer stage)."""

    stage: str

    def frame(self, t_us: int, frames: Frames, prev: tuple[int, Frames] | None) -> None:
        """See the frames at ``t_us`` (and the previous instant's, None at the first)."""

    def end(self, last: tuple[int, Frames] | None) -> None:
        """The stream ended; ``last`` is the last instant (None: there were no frames)."""


def run_frames(
    frames: Iterable[tuple[int, Frames]],
    observers: Sequence[FrameObserver],
    *,
    timer: StageTimer | None = None,
) -> tuple[int, Frames] | None:
    """Stream ``frames`` through ``observers`` (in order, per frame); return the last instant.

    Producing a frame is timed as ``"render"``, each observer under its own ``stage``.

    Examples
    --------
    >>> from edeflare.sim.dvs import IdealParams, IdealSimulator
    >>> rec = EventRecorder(IdealSimulator((1, 1), IdealParams(c_on=0.5)), "v")
    >>> video = [(0, {"v": np.ones((1, 1))}), (1000, {"v": np.full((1, 1), 9.0)})]
    >>> last = run_frames(video, [rec])
    >>> last[0], rec.events().size
    (1000, 3)
    """
    timer = timer or StageTimer(())
    it: Iterator[tuple[int, Frames]] = iter(frames)
    prev: tuple[int, Frames] | None = None
    while True:
        with timer("render"):
            item = next(it, None)
        if item is None:
            break
        t_us, current = item
        check_interrupt()  # a Ctrl-C a finaliser swallowed stops the run here
        for obs in observers:
            with timer(obs.stage):
                obs.frame(t_us, current, prev)
        prev = (t_us, current)
    for obs in observers:
        with timer(obs.stage):
            obs.end(prev)
    return prev


def _concat(parts: list[np.ndarray], empty: np.ndarray) -> np.ndarray:
    return np.concatenate(parts) if parts else empty


class EventRecorder:
    """Feed one video to an event simulator, frame by frame; keep the events.

    Parameters
    ----------
    simulator : VoltmeterSimulator or IdealSimulator
    video : str or callable
        The frame's name, or a function of the frames (e.g. a sum of videos).
    """

    stage = "simulate"

    def __init__(self, simulator: Simulator, video: str | Callable[[Frames], np.ndarray]) -> None:
        self.simulator = simulator
        self.video = video
        self.chunks: list[np.ndarray] = []
        self.last = np.empty(0, dtype=EVENT_DTYPE)

    def frame(self, t_us: int, frames: Frames, prev: tuple[int, Frames] | None) -> None:
        """Simulate the interval up to ``t_us``; ``last`` holds its events."""
        image = frames[self.video] if isinstance(self.video, str) else self.video(frames)
        self.last = self.simulator.feed(image, t_us)
        self.chunks.append(self.last)

    def end(self, last: tuple[int, Frames] | None) -> None:
        """Nothing to finish."""

    def events(self, end_us: int | None = None) -> np.ndarray:
        """All events so far, sorted; cut to ``t < end_us`` when given."""
        events = _concat(self.chunks, np.empty(0, dtype=EVENT_DTYPE))
        if end_us is not None:
            events = events[: int(np.searchsorted(events["t"], end_us))]
        return events


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _interpolate(t, x, y, t0, t1, prev, cur, out):  # pragma: no cover - compiled
    """``out[i]``: the intensity at event ``i``, linear between ``prev`` (t0) and ``cur`` (t1)."""
    span = max(t1 - t0, 1)
    for i in range(t.size):
        frac = min(max((t[i] - t0) / span, 0.0), 1.0)
        a = np.float64(prev[y[i], x[i]])
        out[i] = a + frac * (np.float64(cur[y[i], x[i]]) - a)


def _sample_frames(
    events: np.ndarray, t0: int, t1: int, prev: np.ndarray, cur: np.ndarray
) -> np.ndarray:
    out = np.empty(events.size, dtype=np.float64)
    _interpolate(events["t"], events["x"], events["y"], t0, t1, prev, cur, out)
    return out


def _interval(
    t_us: int, frames: Frames, prev: tuple[int, Frames] | None, video: str
) -> tuple[int, np.ndarray]:
    """The previous instant's time and frame (the current ones at the first frame)."""
    return (prev[0], prev[1][video]) if prev is not None else (t_us, frames[video])


class StreamSampler:
    """A video's intensity at the events a recorder emits, linear between frames."""

    stage = "compose"

    def __init__(self, recorder: EventRecorder, video: str) -> None:
        self.recorder = recorder
        self.video = video
        self.parts: list[np.ndarray] = []

    def frame(self, t_us: int, frames: Frames, prev: tuple[int, Frames] | None) -> None:
        """Sample the recorder's events of this interval."""
        t0, f0 = _interval(t_us, frames, prev, self.video)
        self.parts.append(_sample_frames(self.recorder.last, t0, t_us, f0, frames[self.video]))

    def end(self, last: tuple[int, Frames] | None) -> None:
        """Nothing to finish."""

    def values(self, n: int | None = None) -> np.ndarray:
        """The samples, in the recorder's event order (the first ``n``)."""
        return _concat(self.parts, np.empty(0))[:n]


class EventSampler:
    """A video's intensity at fixed events, linear between the frames around each event.

    Events after the last frame get the last frame's values (held).
    """

    stage = "compose"

    def __init__(self, events: np.ndarray, video: str) -> None:
        self.events = events
        self.video = video
        self._t = np.ascontiguousarray(events["t"])
        self.values = np.zeros(events.size)
        self._done = 0

    def frame(self, t_us: int, frames: Frames, prev: tuple[int, Frames] | None) -> None:
        """Sample the events up to ``t_us``."""
        hi = int(np.searchsorted(self._t, t_us, side="right"))
        t0, f0 = _interval(t_us, frames, prev, self.video)
        sel = self.events[self._done : hi]
        self.values[self._done : hi] = _sample_frames(sel, t0, t_us, f0, frames[self.video])
        self._done = hi

    def end(self, last: tuple[int, Frames] | None) -> None:
        """Hold the last frame for the events after it."""
        if last is not None and self._done < self.events.size:
            sel = self.events[self._done :]
            self.values[self._done :] = last[1][self.video][sel["y"], sel["x"]]


class FrameRecorder:
    """A video's frames at given instants, linear in time between the frames around each.

    Instants after the last frame get the last frame (held); the result,
    :attr:`images`, is float32 ``(len(times_us), H, W)``. The simulator keeps
    only two frames at a time, so this is how a pair's ground-truth images
    (the clean scene at each window's end) are kept.

    Examples
    --------
    >>> rec = FrameRecorder([500, 2000], "v")
    >>> video = [(0, {"v": np.zeros((1, 1))}), (1000, {"v": np.full((1, 1), 4.0)})]
    >>> _ = run_frames(video, [rec])
    >>> rec.images[:, 0, 0].tolist()
    [2.0, 4.0]
    """

    stage = "compose"

    def __init__(self, times_us: Sequence[int] | np.ndarray, video: str) -> None:
        self.times_us = np.asarray(times_us, dtype=np.int64)
        if self.times_us.ndim != 1 or (np.diff(self.times_us) < 0).any():
            raise SimError("frame times must be a sorted 1-D sequence")
        self.video = video
        self._parts: list[np.ndarray] = []
        self._done = 0

    def frame(self, t_us: int, frames: Frames, prev: tuple[int, Frames] | None) -> None:
        """Interpolate the instants up to ``t_us``."""
        hi = int(np.searchsorted(self.times_us, t_us, side="right"))
        current = np.asarray(frames[self.video], dtype=np.float64)
        t0, f0 = _interval(t_us, frames, prev, self.video)
        for t in self.times_us[self._done : hi].tolist():
            w = 1.0 if t_us == t0 else (t - t0) / (t_us - t0)
            self._parts.append(((1.0 - w) * f0 + w * current).astype(np.float32))
        self._done = hi

    def end(self, last: tuple[int, Frames] | None) -> None:
        """Hold the last frame for the instants after it."""
        if last is None:
            return
        held = np.asarray(last[1][self.video], dtype=np.float32)
        self._parts.extend(held.copy() for _ in range(self.times_us.size - self._done))
        self._done = self.times_us.size

    @property
    def images(self) -> np.ndarray:
        """float32 ``(T, H, W)``: the video at each instant recorded so far."""
        return np.stack(self._parts) if self._parts else np.zeros((0, 0, 0), np.float32)


@dataclass(frozen=True)
class SimulatedPair:
    """One simulated sample.

    Attributes
    ----------
    input, gt : numpy.ndarray
        The flare-corrupted stream and its ground truth, times in ``[0, duration)``.
    flare, light, background : numpy.ndarray
        The pure streams.
    components : Components
        The pure streams and their intensities at each other's events, as weighted
        (to recompose with other variants or draws).
    """

    input: np.ndarray
    gt: np.ndarray
    flare: np.ndarray
    light: np.ndarray
    background: np.ndarray
    components: Components

    @property
    def streams(self) -> dict[str, np.ndarray]:
        """``{"input", "gt", "flare", "light", "background"} -> events``."""
        return {
            "input": self.input,
            "gt": self.gt,
            "flare": self.flare,
            "light": self.light,
            "background": self.background,
        }


def _script_frames(
    renderer: Renderer,
    background_video: Callable[[float], np.ndarray] | None,
    size: SensorSize,
) -> Iterator[tuple[int, Frames]]:
    """Each frame's videos; with a background, the scene as observed (``"lit"``: under the
    light's flickering illumination where it lights its surroundings) and flare-free
    (``"steady"``)."""
    script = renderer.script
    for t_us, flare, light in renderer:
        frames = {"flare": flare, "light": light}
        if background_video is not None:
            bg = background_video(t_us).astype(np.float64)
            frames["background"] = frames["lit"] = frames["steady"] = bg
            if script.surround is not None:
                lit, steady = script.surround.illuminations(script, t_us, size)
                frames["lit"], frames["steady"] = bg * lit, bg * steady
        yield t_us, frames


def simulate_pair(
    script: FlareScript,
    background: Background,
    sensor_size: SensorSize,
    *,
    variant: str = "physical",
    weights: str = "intensity",
    jitter_us: float = 1000.0,
    independent_background: bool = False,
    flare7k: str | os.PathLike[str] | None = None,
    rng: np.random.Generator | np.random.SeedSequence | int | None = None,
    forward_seed: np.random.SeedSequence | int | None = None,
    timer: StageTimer | None = None,
) -> SimulatedPair:
    """Simulate one training pair: a script's flare over a background (see the module docstring).

    Parameters
    ----------
    script : FlareScript
        Its ``duration_us`` is the pair's span ``[0, duration)``.
    background : Background
        Drawn with the script's sensor (:meth:`SyntheticBackground.draw`,
        :meth:`RecordedBackground.draw`).
    sensor_size : (width, height)
    variant : str
        A composition variant (:data:`~edeflare.sim.compose.VARIANTS`) or
        ``"forward"`` (the full forward model; needs a background video).
    weights : {"intensity", "accumulation", "counts"}
        Where PNL-ES intensities come from (:data:`WEIGHTS`): ``"counts"`` uses
        whole-window event counts for all three streams, the others the
        rendered videos and the background's own intensity field.
    jitter_us : float
        Half-width of the ``+random`` variants' jitter.
    independent_background : bool
        Thin the background separately for input and ground truth.
    flare7k : path-like, optional
        A Flare7K++ folder, for scripts that use its images.
    rng : numpy.random.Generator, SeedSequence or int, optional
        The composition's draws.
    forward_seed : numpy.random.SeedSequence or int, optional
        Seeds the two simulators of the forward model (``variant="forward"``).
    timer : StageTimer, optional
        Adds seconds to ``render``, ``simulate`` and ``compose``.

    Returns
    -------
    SimulatedPair

    Examples
    --------
    >>> from edeflare.sim.background import SceneConfig, SyntheticBackground
    >>> script = FlareScript(duration_us=4_000, fps=2000.0)
    >>> bg = SyntheticBackground(SceneConfig(fps=1000.0)).draw(4_000, (32, 24), script.sensor)
    >>> a = simulate_pair(script, bg, (32, 24), variant="simple", rng=3)
    >>> b = simulate_pair(script, bg, (32, 24), variant="simple", rng=3)
    >>> bool(np.array_equal(a.input, b.input)), a.gt.size <= a.input.size
    (True, True)
    """
    size = check_sensor_size(sensor_size)
    check_choice("variant", variant, PAIR_VARIANTS)
    check_choice("weights", weights, WEIGHTS)
    forward = variant == "forward"
    if forward and background.video is None:
        raise SimError(
            "variant='forward' simulates I_bg + I_f and needs the background as a video "
            "(a synthetic background)"
        )
    if script.surround is not None and not forward:
        raise SimError(
            "a script with lit surroundings needs variant='forward' (the scene's video is lit)"
        )
    timer = timer or StageTimer(("render", "simulate", "compose"))
    duration = script.duration_us
    with timer("render"):
        renderer = Renderer(script, size, flare7k=flare7k)
    sim_f, sim_l = sensor_pair(script.sensor, size)
    rec_f, rec_l = EventRecorder(sim_f, "flare"), EventRecorder(sim_l, "light")
    observers: list[FrameObserver] = [rec_f, rec_l]
    if forward:
        if not isinstance(forward_seed, np.random.SeedSequence):
            forward_seed = np.random.SeedSequence(forward_seed)
        seq_ob, seq_gt = forward_seed.spawn(2)
        rec_ob = EventRecorder(
            camera_simulator(script.sensor, size, rng=np.random.default_rng(seq_ob)),
            lambda f: f["lit"] + f["flare"],
        )
        rec_gt = EventRecorder(
            camera_simulator(script.sensor, size, rng=np.random.default_rng(seq_gt)),
            lambda f: f["steady"] + f["light"],
        )
        observers += [rec_ob, rec_gt]
    bg = background.events
    bg_flare, bg_light = EventSampler(bg, "flare"), EventSampler(bg, "light")
    flare_flare, light_light = StreamSampler(rec_f, "flare"), StreamSampler(rec_l, "light")
    observers += [bg_flare, bg_light, flare_flare, light_light]
    run_frames(
        _script_frames(renderer, background.video if forward else None, size),
        observers,
        timer=timer,
    )

    with timer("compose"):
        streams: dict[str, np.ndarray] = {"background": bg}
        streams["flare"] = rec_f.events(duration)
        streams["light"] = rec_l.events(duration)
        if weights == "counts":
            fields = {name: CountIntensity(streams[name], size) for name in streams}
            components = Components.from_fields(streams, fields, 0, duration)
        else:
            bg_field = background.intensity
            intensity = {
                "background": {name: bg_field.sample(streams[name]) for name in streams},
                "flare": {
                    "background": bg_flare.values,
                    "flare": flare_flare.values(streams["flare"].size),
                },
                "light": {
                    "background": bg_light.values,
                    "light": light_light.values(streams["light"].size),
                },
            }
            components = Components(streams, intensity, 0, duration)
        if forward:
            ob, gt = rec_ob.events(duration), rec_gt.events(duration)
        else:
            ob, gt = compose_pair(
                components,
                variant,
                jitter_us=jitter_us,
                independent_background=independent_background,
                rng=np.random.default_rng(rng),
            )
    return SimulatedPair(
        ob, gt, streams["flare"], streams["light"], streams["background"], components
    )
