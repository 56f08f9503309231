"""A light source, a recording's set of them, and their one JSON form.

A :class:`LightSource` is a disc, a polygon, a moving disc (``track``) or a
piecewise constant one (``steps``, what detection finds window by window);
:class:`Lights` holds a recording's sources and the sizes of the regions around
them (:mod:`edeflare.eval.score` scores flare in those regions; the real-capture
pairing, :mod:`edeflare.realworld`, cleans the glare around them).
:func:`load_lights` reads the JSON form (and the older layout of paired
captures' lights), :func:`save_lights` writes it.

Examples
--------
>>> lights = Lights((LightSource.circle(10, 5, 3),), halo_factor=6.0)
>>> lights.to_dict()["sources"]
[{'circle': [10.0, 5.0, 3.0]}]
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import AnnotationError, ParameterError
from ..events import SensorSize, check_sensor_size
from ..io._atomic import atomic_path
from .shapes import Circle, Polygon, Shape, parse_light

__all__ = [
    "LightSource",
    "Lights",
    "bundled_lights",
    "load_lights",
    "parse_lights",
    "save_lights",
]


@dataclasses.dataclass(frozen=True, eq=False)
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

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LightSource):
            return NotImplemented
        return (
            self.kind == other.kind
            and np.array_equal(self.table, other.table, equal_nan=True)
            and self.to_dict() == other.to_dict()
        )

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def from_shape(cls, shape: Shape, **options: Any) -> LightSource:
        """A fixed source of a :class:`Circle` or :class:`Polygon` outline.

        Examples
        --------
        >>> LightSource.from_shape(Circle(3, 4, 2)).shape
        Circle(cx=3.0, cy=4.0, r=2.0)
        """
        if isinstance(shape, Circle):
            return cls.circle(shape.cx, shape.cy, shape.r, **options)
        if isinstance(shape, Polygon):
            return cls.polygon(shape.points, **options)
        raise ParameterError(f"a light's shape must be a Circle or a Polygon, got {shape!r}")

    @property
    def shape(self) -> Shape:
        """A fixed source's outline (a moving one has none: ParameterError)."""
        if self.kind == "circle":
            return Circle(*(float(v) for v in self.table[0, 1:]))
        if self.kind == "polygon":
            return Polygon(self.points)
        raise ParameterError(f"a {self.kind} light source moves: it has no one outline")

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

    The older layout of paired captures' lights still loads: a list (or
    ``{"lights": [...]}``) of ``{"type": "circle", "cx": .., "cy": .., "r": ..}``,
    ``{"type": "polygon", "points": [[x, y], ...]}`` or strings as for
    :func:`~edeflare.lights.parse_light`, each a fixed source.

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
    size = None if sensor_size is None else check_sensor_size(sensor_size)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise AnnotationError(path, "no such file") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise AnnotationError(path, f"is not a JSON file of light sources ({exc})") from None
    if isinstance(data, list) or (isinstance(data, dict) and set(data) == {"lights"}):
        return _lights_of_shapes(path, data if isinstance(data, list) else data["lights"], size)
    if not isinstance(data, dict) or "sources" not in data:
        raise AnnotationError(path, 'must hold an object {"sources": [...], ...}')
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise AnnotationError(path, f"unknown keys {sorted(unknown)}; valid: {sorted(_TOP_KEYS)}")
    if not isinstance(data["sources"], list) or not data["sources"]:
        raise AnnotationError(path, "'sources' must be a non-empty list")
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


def _shape_from_json(item: Any) -> Shape:
    if isinstance(item, str):
        return parse_light(item)
    if not isinstance(item, dict):
        raise ParameterError(f"a light must be an object or a string, got {item!r}")
    kind = item.get("type")
    if kind == "circle":
        unknown = set(item) - {"type", "cx", "cy", "r"}
        if unknown or not {"cx", "cy", "r"} <= set(item):
            raise ParameterError(f"a circle needs exactly cx, cy, r; got {sorted(item)}")
        return Circle(item["cx"], item["cy"], item["r"])
    if kind == "polygon":
        if set(item) != {"type", "points"}:
            raise ParameterError(f"a polygon needs exactly points; got {sorted(item)}")
        return Polygon(tuple(tuple(pt) for pt in item["points"]))
    raise ParameterError(f"light type must be 'circle' or 'polygon', got {kind!r}")


def _lights_of_shapes(path: Path, items: Any, size: SensorSize | None) -> Lights:
    """The older layout of paired captures' lights: a list of shapes, each a fixed source."""
    if not isinstance(items, list) or not items:
        raise AnnotationError(path, 'must hold a non-empty list of lights (or {"lights": [...]})')
    sources = []
    for i, item in enumerate(items):
        try:
            source = LightSource.from_shape(_shape_from_json(item))
            if size is not None:
                _check_on_sensor(source, size)
        except ParameterError as exc:
            raise AnnotationError(path, f"light {i}: {exc}") from None
        sources.append(source)
    return Lights(tuple(sources))


def save_lights(path: str | os.PathLike[str], lights: Lights, **provenance: Any) -> None:
    """Write ``lights`` as the JSON :func:`load_lights` reads, atomically.

    ``provenance``: ``sensor_size``, ``recording``, ``date``, ``method``, ``checks``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "lights.json"
    >>> lights = Lights((LightSource.circle(10, 5, 3, name="lamp"),))
    >>> save_lights(p, lights, sensor_size=[20, 10])
    >>> load_lights(p, (20, 10)) == lights
    True
    """
    unknown = set(provenance) - _TOP_KEYS
    if unknown:
        raise ParameterError(f"unknown provenance keys {sorted(unknown)}")
    data = {**provenance, **lights.to_dict()}
    with atomic_path(path) as tmp:
        Path(tmp).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


def parse_lights(specs: Iterable[str]) -> list[LightSource]:
    """Sources from strings (:func:`~edeflare.lights.parse_light`) and ``*.json`` files.

    Examples
    --------
    >>> [str(s.shape) for s in parse_lights(["circle:5,5,2", "polygon:0,0,2,0,2,2"])]
    ['circle:5,5,2', 'polygon:0,0,2,0,2,2']
    """
    lights: list[LightSource] = []
    for spec in specs:
        spec = str(spec)
        if spec.lower().endswith(".json") and not spec.lower().startswith(("circle:", "polygon:")):
            lights.extend(load_lights(spec).sources)
        else:
            lights.append(LightSource.from_shape(parse_light(spec)))
    return lights
