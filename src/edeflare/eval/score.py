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

Light sources come from a JSON annotation (:func:`load_lights`) or are
detected window by window (:func:`detect_lights`, the brightest compact
regions of the event density, :func:`edeflare.realworld.detect_light_source`).

Examples
--------
>>> from edeflare.events import make_events
>>> ev = make_events([0, 1, 2, 3], [10, 15, 30, 49], [10, 10, 10, 39], [1, 1, 1, 1])
>>> lights = Lights((LightSource.circle(10, 10, 2),), halo_factor=6.0, ghost_factor=1.0)
>>> classify_events(ev, lights, (60, 50)).labels.tolist()  # light, halo, background, ghost
['light', 'halo', 'background', 'ghost']
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import AnnotationError, EventFileError, ParameterError
from ..events import SensorSize, check_events, check_sensor_size, window_start_for

__all__ = [
    "LightSource",
    "Lights",
    "MethodScore",
    "Regions",
    "ScoreReport",
    "bundled_lights",
    "classify_events",
    "combined_score",
    "detect_lights",
    "load_lights",
    "score_events",
    "score_recording",
]

REGIONS = ("light", "halo", "ghost", "flare", "background")
_LABELS = np.array(["background", "light", "rim", "halo", "ghost", "halo+ghost"])


@dataclasses.dataclass(frozen=True)
class LightSource:
    """One light source whose geometry may change in time.

    Build one with :meth:`circle`, :meth:`polygon`, :meth:`track` or
    (detection) :meth:`steps`. ``kind`` is one of those names; ``table``
    holds ``(t_us, cx, cy, r)`` rows (one row for a fixed circle; for
    ``steps`` each row holds from its time until the next row's, NaN where
    the source is absent), ``points`` a polygon's vertices.
    ``halo_outer_px`` / ``ghost_radius_px`` override the factors of
    :class:`Lights`; ``ghost=False`` gives the source no ghost region.
    ``response_us`` (moving sources) is how long the sensor's pixels keep
    firing after the source has left them: an event belongs to the light
    (and the rim and halo are measured from it) if it lies in any of the
    source's discs of the last ``response_us`` before it, not only the
    current one (:func:`classify_events`).

    Examples
    --------
    >>> s = LightSource.track([[0, 10, 10, 2], [100, 20, 10, 4]])
    >>> [v.tolist() for v in s.at(np.array([-5, 50, 500]))]  # held outside the track
    [[10.0, 15.0, 20.0], [10.0, 10.0, 10.0], [2.0, 3.0, 4.0]]
    """

    kind: str
    table: np.ndarray
    points: tuple[tuple[float, float], ...] = ()
    name: str = ""
    halo_outer_px: float | None = None
    ghost_radius_px: float | None = None
    ghost: bool = True
    response_us: float = 0.0

    @classmethod
    def circle(cls, cx: float, cy: float, r: float, **options: Any) -> LightSource:
        """A fixed disc: centre ``(cx, cy)``, radius ``r`` (pixels)."""
        return cls("circle", _rows([[0, cx, cy, r]], "circle"), **options)

    @classmethod
    def polygon(cls, points: Sequence[Sequence[float]], **options: Any) -> LightSource:
        """A fixed polygon (even-odd rule, as :class:`edeflare.realworld.Polygon`)."""
        from ..realworld.geometry import Polygon

        poly = Polygon(tuple(tuple(p) for p in points))  # validates
        xs, ys = np.array(poly.points).T
        area = 0.5 * abs(float(np.dot(xs, np.roll(ys, -1)) - np.dot(ys, np.roll(xs, -1))))
        if not area > 0:
            raise ParameterError("a polygon must enclose a positive area")
        r = math.sqrt(area / math.pi)
        return cls("polygon", _rows([[0, xs.mean(), ys.mean(), r]], "polygon"), poly.points,
                   **options)  # fmt: skip

    @classmethod
    def track(cls, rows: Sequence[Sequence[float]], **options: Any) -> LightSource:
        """A moving disc: ``[[t_us, cx, cy, r], ...]``, linear in time, held outside."""
        table = _rows(rows, "track")
        if np.any(np.diff(table[:, 0]) <= 0):
            raise ParameterError("track times must increase strictly")
        return cls("track", table, **options)

    @classmethod
    def steps(cls, rows: Sequence[Sequence[float]], **options: Any) -> LightSource:
        """Piecewise constant: row ``i`` holds from its time to row ``i + 1``'s (NaN: absent)."""
        table = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
        return cls("steps", table, **options)

    def at(self, t_us: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(cx, cy, r)`` at the times ``t_us`` (NaN where the source is absent)."""
        t = np.asarray(t_us, dtype=np.float64)
        tab = self.table
        if self.kind in ("circle", "polygon") or (len(tab) == 1 and self.kind != "steps"):
            return tuple(np.full(t.shape, tab[0, k]) for k in (1, 2, 3))  # type: ignore[return-value]
        if self.kind == "track":
            return tuple(np.interp(t, tab[:, 0], tab[:, k]) for k in (1, 2, 3))  # type: ignore[return-value]
        i = np.searchsorted(tab[:, 0], t, side="right") - 1
        ok = i >= 0
        out = []
        for k in (1, 2, 3):
            v = np.full(t.shape, np.nan)
            v[ok] = tab[i[ok], k]
            out.append(v)
        return tuple(out)  # type: ignore[return-value]

    def to_dict(self) -> dict[str, Any]:
        """The JSON form read by :func:`load_lights`."""
        tab = self.table
        if self.kind == "circle":
            d: dict[str, Any] = {"circle": [float(v) for v in tab[0, 1:]]}
        elif self.kind == "polygon":
            d = {"polygon": [list(p) for p in self.points]}
        else:
            d = {self.kind: [[int(r[0]), *(None if math.isnan(v) else float(v) for v in r[1:])]
                             for r in tab]}  # fmt: skip
        if self.name:
            d["name"] = self.name
        if self.halo_outer_px is not None:
            d["halo_outer_px"] = self.halo_outer_px
        if self.ghost_radius_px is not None:
            d["ghost_radius_px"] = self.ghost_radius_px
        if not self.ghost:
            d["ghost"] = False
        if self.response_us:
            d["response_us"] = self.response_us
        return d

    def distance(self, x: np.ndarray, y: np.ndarray, t_us: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(dist, cx, cy, r)``: each point's distance outside the source at its time.

        ``dist`` is 0 inside, ``inf`` where the source is absent; with a
        ``response_us``, the least distance outside the discs of the times
        ``t - response_us .. t`` (sampled in 32 steps). ``cx, cy, r`` are the
        disc at ``t`` (a polygon's: its equal-area disc).

        Examples
        --------
        >>> s = LightSource.track([[0, 0, 0, 2], [10, 10, 0, 2]], response_us=5)
        >>> o = np.zeros(2)
        >>> s.distance(np.array([5.0, 0.0]), o, np.array([10, 10]))[0].tolist()  # 5 px behind
        [0.0, 3.0]
        """
        cx, cy, r = self.at(t_us)
        present = np.isfinite(cx)
        if self.kind == "polygon":
            from ..realworld.geometry import Polygon

            return (Polygon(self.points).distance(x, y), cx, cy, r)
        dist = np.where(present, np.maximum(0.0, np.hypot(x - cx, y - cy) - r), np.inf)
        if self.response_us > 0 and self.kind in ("track", "steps"):
            t = np.asarray(t_us, dtype=np.float64)
            for k in range(1, 33):
                px, py, pr = self.at(t - self.response_us * k / 32)
                d = np.maximum(0.0, np.hypot(x - px, y - py) - pr)
                dist = np.fmin(dist, np.where(np.isfinite(px), d, np.inf))
        return (dist, cx, cy, r)


def _rows(rows: Any, what: str) -> np.ndarray:
    try:
        table = np.asarray(rows, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"a {what} needs numbers, got {rows!r}") from None
    if table.ndim != 2 or table.shape[1] != 4 or len(table) == 0:
        shape = "[x, y, r]" if what == "circle" else "[[t_us, x, y, r], ...]"
        raise ParameterError(f"a {what} must be {shape}, got {rows!r}")
    if not np.isfinite(table).all():
        raise ParameterError(f"a {what} needs finite numbers, got {rows!r}")
    if np.any(table[:, 3] <= 0):
        raise ParameterError(f"a {what}'s radius must be positive, got {rows!r}")
    return table


@dataclasses.dataclass(frozen=True)
class Lights:
    """The light sources of a recording and the region sizes around them.

    Parameters
    ----------
    sources : tuple of LightSource
    margin_px : float
        Rim between the source and its halo, counted nowhere.
    halo_factor : float
        The halo's outer radius as a multiple of the source radius.
    ghost_factor : float
        The ghost disc's radius as a multiple of the source radius.
    note : str
        Free text (how the annotation was made).
    score_background : bool
        False: the background is only sensor noise (a light in the dark); its
        ``background_kept`` is reported but not part of the combined score.

    Examples
    --------
    >>> Lights((LightSource.circle(5, 5, 2),)).halo_factor
    6.0
    """

    sources: tuple[LightSource, ...]
    margin_px: float = 2.0
    halo_factor: float = 6.0
    ghost_factor: float = 2.0
    note: str = ""
    score_background: bool = True

    def __post_init__(self) -> None:
        if not self.sources:
            raise ParameterError("no light sources")
        if not isinstance(self.score_background, bool):
            raise ParameterError(
                f"score_background must be true or false, got {self.score_background!r}"
            )
        for name in ("margin_px", "halo_factor", "ghost_factor"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ParameterError(f"{name} must be a finite number, got {v!r}")
            if v < 0 or (name == "halo_factor" and v <= 1):
                raise ParameterError(f"{name} out of range: {v!r}")

    def to_dict(self) -> dict[str, Any]:
        """The JSON form read by :func:`load_lights`."""
        return {
            "margin_px": self.margin_px,
            "halo_factor": self.halo_factor,
            "ghost_factor": self.ghost_factor,
            "note": self.note,
            "score_background": self.score_background,
            "sources": [s.to_dict() for s in self.sources],
        }


_SOURCE_KEYS = {"circle", "polygon", "track", "name", "halo_outer_px", "ghost_radius_px", "ghost",
                "response_us"}  # fmt: skip
_TOP_KEYS = {"sources", "margin_px", "halo_factor", "ghost_factor", "note", "sensor_size",
             "recording", "date", "method", "checks", "score_background"}  # fmt: skip


def _source_from_json(item: Any) -> LightSource:
    if not isinstance(item, dict):
        raise ParameterError(f"must be an object, got {item!r}")
    unknown = set(item) - _SOURCE_KEYS
    if unknown:
        raise ParameterError(f"unknown keys {sorted(unknown)}; valid: {sorted(_SOURCE_KEYS)}")
    shapes = [k for k in ("circle", "polygon", "track") if k in item]
    if len(shapes) != 1:
        raise ParameterError("needs exactly one of 'circle', 'polygon', 'track'")
    options: dict[str, Any] = {"name": str(item.get("name", ""))}
    if "response_us" in item:
        v = item["response_us"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < math.inf:
            raise ParameterError(f"response_us must be a number >= 0, got {v!r}")
        if "track" not in item:
            raise ParameterError("response_us applies to a track (a moving source) only")
        options["response_us"] = float(v)
    for key in ("halo_outer_px", "ghost_radius_px"):
        if key in item:
            v = item[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
                raise ParameterError(f"{key} must be a positive number, got {v!r}")
            options[key] = float(v)
    if "ghost" in item:
        if not isinstance(item["ghost"], bool):
            raise ParameterError(f"ghost must be true or false, got {item['ghost']!r}")
        options["ghost"] = item["ghost"]
    value = item[shapes[0]]
    if shapes[0] == "circle":
        if not isinstance(value, list) or len(value) != 3:
            raise ParameterError(f"a circle must be [x, y, r], got {value!r}")
        return LightSource.circle(*value, **options)
    if shapes[0] == "polygon":
        if not isinstance(value, list):
            raise ParameterError(f"a polygon must be [[x, y], ...], got {value!r}")
        return LightSource.polygon(value, **options)
    return LightSource.track(value, **options)


def _check_on_sensor(source: LightSource, sensor_size: SensorSize) -> None:
    width, height = sensor_size
    pts = np.array(source.points) if source.kind == "polygon" else source.table[:, 1:3]
    pts = pts[np.isfinite(pts).all(axis=1)]
    off = (pts[:, 0] < -0.5) | (pts[:, 0] > width - 0.5) | (pts[:, 1] < -0.5)
    off |= pts[:, 1] > height - 0.5
    if off.any():
        x, y = pts[np.argmax(off)]
        what = "a vertex" if source.kind == "polygon" else "its centre"
        raise ParameterError(f"{what} ({x:g}, {y:g}) lies off the {width}x{height} sensor")


def load_lights(path: str | os.PathLike[str], sensor_size: SensorSize | None = None) -> Lights:
    """Read a light-source annotation (JSON).

    The file holds ``{"sources": [...]}`` and optionally ``margin_px``,
    ``halo_factor``, ``ghost_factor``, ``note``, ``score_background``
    (false: the background is sensor noise, left out of the combined score),
    ``sensor_size`` ([W, H],
    checked against ``sensor_size``) and provenance (``recording``, ``date``,
    ``method``, ``checks``). Each source is one of ``{"circle": [x, y, r]}``,
    ``{"polygon": [[x, y], ...]}`` or ``{"track": [[t_us, x, y, r], ...]}``
    (linear in time, held before its first and after its last row), with
    optional ``name``, ``halo_outer_px``, ``ghost_radius_px``, ``ghost``
    (false: no ghost region) and, for a track, ``response_us`` (how long its
    pixels fire on after it has passed; see :class:`LightSource`). Pixel
    coordinates: pixel ``(x, y)`` has its centre at ``(x, y)``.

    Raises
    ------
    AnnotationError
        Naming the file: missing, not JSON, an unknown key, a bad shape, a
        centre or vertex off the sensor, a sensor size that differs.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "lights.json"
    >>> _ = p.write_text('{"sources": [{"circle": [10, 5, 3]}, {"track": [[0, 1, 1, 1]]}]}')
    >>> [s.kind for s in load_lights(p, (20, 10)).sources]
    ['circle', 'track']
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise AnnotationError(path, "no such file") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise AnnotationError(path, f"is not a JSON file of light sources ({exc})") from None
    if not isinstance(data, dict) or "sources" not in data:
        raise AnnotationError(path, 'must hold an object {"sources": [...], ...}')
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise AnnotationError(path, f"unknown keys {sorted(unknown)}; valid: {sorted(_TOP_KEYS)}")
    if not isinstance(data["sources"], list) or not data["sources"]:
        raise AnnotationError(path, "'sources' must be a non-empty list")
    size = None if sensor_size is None else check_sensor_size(sensor_size)
    if "sensor_size" in data:
        given = data["sensor_size"]
        if not (isinstance(given, list) and len(given) == 2):
            raise AnnotationError(path, f"sensor_size must be [width, height], got {given!r}")
        if size is not None and tuple(given) != size:
            raise AnnotationError(
                path, f"annotates a {given[0]}x{given[1]} sensor; the recording is "
                f"{size[0]}x{size[1]}"
            )  # fmt: skip
    sources = []
    for i, item in enumerate(data["sources"]):
        try:
            source = _source_from_json(item)
            if size is not None:
                _check_on_sensor(source, size)
        except ParameterError as exc:
            raise AnnotationError(path, f"source {i}: {exc}") from None
        sources.append(source)
    keys = ("margin_px", "halo_factor", "ghost_factor", "note", "score_background")
    options = {k: data[k] for k in keys if k in data}
    try:
        return Lights(tuple(sources), **options)
    except (ParameterError, TypeError) as exc:
        raise AnnotationError(path, str(exc)) from None


def bundled_lights(recording: str | os.PathLike[str] | None = None) -> Path | list[str]:
    """The annotation bundled for a real recording (by file name or stem), or their names.

    Annotations of the recordings in the project's real test set live in
    ``edeflare/assets/lights/`` (with a README on how they were made and checked).

    Examples
    --------
    >>> bundled_lights()
    ['davis346_flicker_lamps', 'prophesee_gen3_rotating_light']
    >>> bundled_lights("some/where/davis346_flicker_lamps.aedat4").name
    'davis346_flicker_lamps.json'
    """
    folder = Path(__file__).resolve().parents[1] / "assets" / "lights"
    names = sorted(p.stem for p in folder.glob("*.json"))
    if recording is None:
        return names
    stem = Path(recording).name.split(".")[0]
    if stem not in names:
        raise ParameterError(f"no bundled annotation for {stem!r}; bundled: {', '.join(names)}")
    return folder / f"{stem}.json"


def detect_lights(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int = 20_000,
    *,
    max_sources: int = 1,
    **options: Any,
) -> Lights:
    """Detect the light sources window by window: the brightest compact regions.

    Each aligned window of ``window_us`` goes through
    :func:`edeflare.realworld.detect_light_source` (``max_sources`` regions,
    brightest first); the ``k``-th detection of each window makes the
    ``k``-th source, constant within the window (:meth:`LightSource.steps`).
    ``options`` go to :class:`Lights` (``margin_px``, ``halo_factor``,
    ``ghost_factor``).

    Raises
    ------
    ParameterError
        No events, or no light found in any window.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[:5, :5]
    >>> n = xx.size * 10
    >>> ev = make_events(np.arange(n) * 10, np.tile(xx.ravel() + 20, 10),
    ...                  np.tile(yy.ravel() + 30, 10), np.ones(n, int))
    >>> src = detect_lights(ev, (64, 48), 1_000).sources[0]
    >>> src.kind, [round(float(v)) for v in src.table[0, 1:3]]
    ('steps', [22, 32])
    """
    from ..realworld import detect_light_source

    check_events(events, sensor_size)
    size = check_sensor_size(sensor_size)
    if events.size == 0:
        raise ParameterError("no events: no light source to detect")
    t = events["t"]
    start = window_start_for(int(t[0]), window_us)
    n_windows = (int(t[-1]) - start) // window_us + 1
    edges = np.searchsorted(t, start + window_us * np.arange(n_windows + 1), side="left")
    rows = np.full((max_sources, n_windows, 4), np.nan)
    rows[:, :, 0] = start + window_us * np.arange(n_windows)
    found = 0
    for w in range(n_windows):
        chunk = events[edges[w] : edges[w + 1]]
        if chunk.size == 0:
            continue
        try:
            circles = detect_light_source(chunk, size, max_sources=max_sources)
        except ParameterError:
            continue
        for k, c in enumerate(circles):
            rows[k, w, 1:] = (c.cx, c.cy, c.r)
            found += 1
    if not found:
        raise ParameterError(
            "no light source detected in any window; annotate the lights (--lights JSON)"
        )
    sources = tuple(
        LightSource.steps(rows[k], name=f"detected-{k}")
        for k in range(max_sources)
        if np.isfinite(rows[k, :, 1]).any()
    )
    return Lights(sources, note=f"detected per {window_us} us window", **options)


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
            from ..realworld.geometry import Polygon

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
        An annotation (:func:`load_lights`); None detects the lights per
        window (:func:`detect_lights`, ``max_sources`` of them).
    window_us : int
        Window of the count comparison and of detection.
    overrides : mapping, optional
        ``margin_px``, ``halo_factor``, ``ghost_factor`` replacing the
        annotation's.
    method_params : mapping, optional
        Method name -> parameters for :func:`edeflare.create_method`.
    rng : numpy.random.Generator or int, optional
        Seeds methods that draw.
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
            the_lights = detect_lights(events, size, window_us, max_sources=max_sources)
        except ParameterError as exc:
            raise EventFileError(recording, str(exc)) from None
        source = "detect"
    if overrides:
        try:
            the_lights = dataclasses.replace(the_lights, **dict(overrides))
        except TypeError as exc:
            raise ParameterError(str(exc)) from None
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
