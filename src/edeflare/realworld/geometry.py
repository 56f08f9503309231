"""Light sources (circles, polygons), glare zones, reference cleaning and light detection."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from ..errors import EventFileError, ParameterError
from ..events import SensorSize, check_events, check_sensor_size
from ._common import _count_map, _pixel_mask_of


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(f"{what}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ParameterError(f"{what}: {text!r} is not a finite number")
    return value


@dataclass(frozen=True)
class Circle:
    """A round light source: centre ``(cx, cy)`` and radius ``r`` in pixels.

    A pixel belongs to it when its centre ``(x, y)`` satisfies
    ``(x - cx)**2 + (y - cy)**2 <= r**2``.

    Examples
    --------
    >>> Circle(2, 1, 1).mask((5, 3)).astype(int).tolist()
    [[0, 0, 1, 0, 0], [0, 1, 1, 1, 0], [0, 0, 1, 0, 0]]
    >>> str(Circle(320, 240, 15))
    'circle:320,240,15'
    """

    cx: float
    cy: float
    r: float

    def __post_init__(self) -> None:
        for name in ("cx", "cy", "r"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ParameterError(f"circle {name} must be a number, got {value!r}")
            if not math.isfinite(float(value)):
                raise ParameterError(f"circle {name} must be finite, got {value!r}")
        if not self.r > 0:
            raise ParameterError(f"circle radius must be positive, got {self.r!r}")

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether the points ``(x, y)`` lie in the disc."""
        return (x - self.cx) ** 2 + (y - self.cy) ** 2 <= self.r**2

    def distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Euclidean distance from the points to the disc (0 inside)."""
        return np.maximum(0.0, np.hypot(x - self.cx, y - self.cy) - self.r)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)``."""
        return self.cx - self.r, self.cy - self.r, self.cx + self.r, self.cy + self.r

    def shifted(self, dx: float, dy: float) -> Circle:
        """The same circle moved by ``(dx, dy)`` (e.g. into crop coordinates)."""
        return Circle(self.cx + dx, self.cy + dy, self.r)

    def mask(self, sensor_size: SensorSize) -> np.ndarray:
        """``(H, W)`` bool: pixels of the sensor inside the circle."""
        return light_mask([self], sensor_size)

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "circle", "cx", "cy", "r"}``."""
        return {"type": "circle", "cx": float(self.cx), "cy": float(self.cy), "r": float(self.r)}

    def __str__(self) -> str:
        return "circle:" + ",".join(f"{float(v):g}" for v in (self.cx, self.cy, self.r))


@dataclass(frozen=True)
class Polygon:
    """A light source of any outline: vertices ``((x1, y1), (x2, y2), ...)`` in pixels.

    A pixel belongs to it when its centre is inside by the even-odd rule,
    with points on left and top edges inside and on right and bottom edges
    outside, so an axis-aligned rectangle with corners ``(x0, y0)`` and
    ``(x1, y1)`` holds the pixels ``x0 <= x < x1``, ``y0 <= y < y1``, like an
    array slice.

    Examples
    --------
    >>> Polygon(((1, 0), (3, 0), (3, 2), (1, 2))).mask((4, 3)).astype(int).tolist()
    [[0, 1, 1, 0], [0, 1, 1, 0], [0, 0, 0, 0]]
    """

    points: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        try:
            pts = tuple((float(x), float(y)) for x, y in self.points)
        except (TypeError, ValueError):
            raise ParameterError(
                f"polygon points must be (x, y) pairs, got {self.points!r}"
            ) from None
        if len(pts) < 3:
            raise ParameterError(f"a polygon needs at least 3 points, got {len(pts)}")
        if not all(math.isfinite(v) for pt in pts for v in pt):
            raise ParameterError("polygon points must be finite numbers")
        object.__setattr__(self, "points", pts)

    def _edges(self) -> Iterator[tuple[float, float, float, float]]:
        pts = self.points
        for i in range(len(pts)):
            (x1, y1), (x2, y2) = pts[i], pts[(i + 1) % len(pts)]
            yield x1, y1, x2, y2

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether the points lie inside (even-odd rule, half-open edges)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        inside = np.zeros(np.broadcast(x, y).shape, dtype=bool)
        for x1, y1, x2, y2 in self._edges():
            if y1 == y2:
                continue
            crosses = (y1 > y) != (y2 > y)
            x_at = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            inside ^= crosses & (x < x_at)
        return inside

    def distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Euclidean distance from the points to the polygon's area (0 inside)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        best = np.full(np.broadcast(x, y).shape, np.inf)
        for x1, y1, x2, y2 in self._edges():
            dx, dy = x2 - x1, y2 - y1
            length2 = dx * dx + dy * dy
            s = np.zeros_like(best) if length2 == 0 else ((x - x1) * dx + (y - y1) * dy) / length2
            s = np.clip(s, 0.0, 1.0)
            best = np.minimum(best, np.hypot(x - (x1 + s * dx), y - (y1 + s * dy)))
        return np.where(self.contains(x, y), 0.0, best)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)``."""
        xs, ys = zip(*self.points, strict=True)
        return min(xs), min(ys), max(xs), max(ys)

    def shifted(self, dx: float, dy: float) -> Polygon:
        """The same polygon moved by ``(dx, dy)``."""
        return Polygon(tuple((x + dx, y + dy) for x, y in self.points))

    def mask(self, sensor_size: SensorSize) -> np.ndarray:
        """``(H, W)`` bool: pixels of the sensor inside the polygon."""
        return light_mask([self], sensor_size)

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "polygon", "points": [[x, y], ...]}``."""
        return {"type": "polygon", "points": [[x, y] for x, y in self.points]}

    def __str__(self) -> str:
        return "polygon:" + ",".join(f"{v:g}" for pt in self.points for v in pt)


LightSource = Circle | Polygon
"""A light source's outline on the sensor."""

_LIGHT_SYNTAX = "circle:CX,CY,R or polygon:X1,Y1,X2,Y2,X3,Y3,... (pixels)"


def parse_light(text: str) -> LightSource:
    """Parse ``circle:CX,CY,R`` or ``polygon:X1,Y1,X2,Y2,...`` (pixel coordinates).

    Raises
    ------
    ParameterError
        Naming the string and the expected syntax.

    Examples
    --------
    >>> parse_light("circle:320,240,15")
    Circle(cx=320.0, cy=240.0, r=15.0)
    >>> parse_light("polygon:0,0,4,0,4,2").points
    ((0.0, 0.0), (4.0, 0.0), (4.0, 2.0))
    """
    kind, sep, rest = str(text).strip().partition(":")
    kind = kind.strip().lower()
    if not sep or kind not in ("circle", "polygon"):
        raise ParameterError(f"light {text!r}: expected {_LIGHT_SYNTAX}")
    parts = [s.strip() for s in rest.split(",")]
    if parts == [""]:
        parts = []
    values = [_number(s, f"light {text!r}") for s in parts]
    try:
        if kind == "circle":
            if len(values) != 3:
                raise ParameterError(f"a circle needs 3 numbers CX,CY,R, got {len(values)}")
            return Circle(*values)
        if len(values) % 2 or len(values) < 6:
            raise ParameterError(
                f"a polygon needs an even number (>= 6) of coordinates, got {len(values)}"
            )
        return Polygon(tuple(zip(values[::2], values[1::2], strict=True)))
    except ParameterError as exc:
        raise ParameterError(f"light {text!r}: {exc}; expected {_LIGHT_SYNTAX}") from None


def _light_from_json(item: Any) -> LightSource:
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


def load_lights(path: str | os.PathLike[str]) -> list[LightSource]:
    """Read light sources from JSON: a list (or ``{"lights": [...]}``) of shapes.

    Each shape is ``{"type": "circle", "cx": .., "cy": .., "r": ..}``,
    ``{"type": "polygon", "points": [[x, y], ...]}`` or a string as for
    :func:`parse_light`.

    Raises
    ------
    EventFileError
        Naming the file: missing, not JSON, or a shape it cannot read.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "lights.json"
    >>> _ = p.write_text('[{"type": "circle", "cx": 10, "cy": 5, "r": 3}, "circle:1,1,1"]')
    >>> [str(s) for s in load_lights(p)]
    ['circle:10,5,3', 'circle:1,1,1']
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise EventFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise EventFileError(path, f"is not a JSON file of light sources ({exc})") from None
    if isinstance(data, dict) and set(data) == {"lights"}:
        data = data["lights"]
    if not isinstance(data, list):
        raise EventFileError(path, 'must hold a list of lights (or {"lights": [...]})')
    lights = []
    for i, item in enumerate(data):
        try:
            lights.append(_light_from_json(item))
        except ParameterError as exc:
            raise EventFileError(path, f"light {i}: {exc}") from None
    return lights


def parse_lights(specs: Iterable[str]) -> list[LightSource]:
    """Shapes from strings (:func:`parse_light`) and ``*.json`` files (:func:`load_lights`).

    Examples
    --------
    >>> [str(s) for s in parse_lights(["circle:5,5,2", "polygon:0,0,2,0,2,2"])]
    ['circle:5,5,2', 'polygon:0,0,2,0,2,2']
    """
    lights: list[LightSource] = []
    for spec in specs:
        spec = str(spec)
        if spec.lower().endswith(".json") and not spec.lower().startswith(("circle:", "polygon:")):
            lights.extend(load_lights(spec))
        else:
            lights.append(parse_light(spec))
    return lights


def _window(
    shape: LightSource, margin: float, sensor_size: SensorSize
) -> tuple[slice, slice, np.ndarray, np.ndarray] | None:
    """Rows/columns of the sensor within ``margin`` of a shape's bounds, and their pixel grid."""
    width, height = sensor_size
    x0, y0, x1, y1 = shape.bounds()
    c0, c1 = max(0, math.floor(x0 - margin)), min(width, math.ceil(x1 + margin) + 1)
    r0, r1 = max(0, math.floor(y0 - margin)), min(height, math.ceil(y1 + margin) + 1)
    if c0 >= c1 or r0 >= r1:
        return None
    yy, xx = np.mgrid[r0:r1, c0:c1]
    return slice(r0, r1), slice(c0, c1), xx.astype(np.float64), yy.astype(np.float64)


def light_mask(lights: Sequence[LightSource], sensor_size: SensorSize) -> np.ndarray:
    """``(H, W)`` bool: pixels whose centre lies inside any of the light sources.

    Examples
    --------
    >>> square = Polygon(((0, 0), (2, 0), (2, 1), (0, 1)))  # pixels (0, 0) and (1, 0)
    >>> int(light_mask([Circle(5, 5, 2), square], (10, 10)).sum())
    15
    """
    width, height = check_sensor_size(sensor_size)
    mask = np.zeros((height, width), dtype=bool)
    for shape in lights:
        win = _window(shape, 0.0, (width, height))
        if win is not None:
            rows, cols, xx, yy = win
            mask[rows, cols] |= shape.contains(xx, yy)
    return mask


def glare_mask(
    lights: Sequence[LightSource], sensor_size: SensorSize, glare_radius_px: float
) -> np.ndarray:
    """``(H, W)`` bool: the glare zone, within ``glare_radius_px`` of a source but inside none.

    A pixel is in the zone when the Euclidean distance from its centre to the
    nearest light source's area (disc or polygon) is at most
    ``glare_radius_px``, and its centre is inside no source. For a circle
    ``(cx, cy, r)`` this is the ring ``r < d <= r + glare_radius_px`` around
    the centre. A radius of 0 gives an empty zone.

    Examples
    --------
    >>> m = glare_mask([Circle(3, 3, 1)], (7, 7), 1)
    >>> for row in m.astype(int)[1:6]:
    ...     print(*row)
    0 0 0 1 0 0 0
    0 0 1 0 1 0 0
    0 1 0 0 0 1 0
    0 0 1 0 1 0 0
    0 0 0 1 0 0 0
    """
    width, height = check_sensor_size(sensor_size)
    radius = float(glare_radius_px)
    if not math.isfinite(radius) or radius < 0:
        raise ParameterError(f"glare_radius_px must be a finite number >= 0, got {glare_radius_px}")
    zone = np.zeros((height, width), dtype=bool)
    if radius == 0:
        return zone
    for shape in lights:
        win = _window(shape, radius, (width, height))
        if win is not None:
            rows, cols, xx, yy = win
            zone[rows, cols] |= shape.distance(xx, yy) <= radius
    return zone & ~light_mask(lights, (width, height))


def clean_reference(
    events: np.ndarray,
    sensor_size: SensorSize,
    lights: Sequence[LightSource],
    *,
    glare_radius_px: float = 40.0,
) -> np.ndarray:
    """Remove residual glare from a reference stream, keeping the light sources themselves.

    Events on pixels of the glare zone (:func:`glare_mask`) are removed;
    every other event is kept, in particular those on the sources' own
    pixels (the light is part of the scene) and those farther than
    ``glare_radius_px`` from every source.

    Parameters
    ----------
    events : numpy.ndarray
        The reference stream (not modified).
    sensor_size : (width, height)
    lights : sequence of Circle or Polygon
        Light sources in sensor pixel coordinates.
    glare_radius_px : float
        Width of the glare zone around each source (pixels).

    Returns
    -------
    numpy.ndarray
        A new stream without the glare zone's events.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 2], [5, 7, 9], [5, 5, 5], [1, 1, 1])
    >>> clean_reference(ev, (12, 12), [Circle(5, 5, 1)], glare_radius_px=2)["x"].tolist()
    [5, 9]
    """
    size = check_sensor_size(sensor_size)
    check_events(events, size)
    zone = glare_mask(lights, size, glare_radius_px)
    return events[~_pixel_mask_of(events, zone)]


def detect_light_source(
    data: np.ndarray,
    sensor_size: SensorSize | None = None,
    *,
    sigma_px: float = 2.0,
    level: float = 0.5,
    max_sources: int = 1,
    min_area_px: int = 4,
    margin_px: float = 1.0,
) -> list[Circle]:
    """Find the brightest compact region(s) of the event density: the light source(s).

    The per-pixel event counts are median-filtered (3x3, removing isolated hot
    pixels), smoothed with a Gaussian of ``sigma_px``, and thresholded at
    ``level`` times their maximum. Connected regions (8-connectivity) of at
    least ``min_area_px`` pixels are ranked by their peak density, and the
    first ``max_sources`` become circles: centre at the density-weighted
    centroid, radius ``sqrt(area / pi) + margin_px`` (the smoothing pulls the
    threshold contour inside the source's rim; the margin keeps the rim a
    source pixel rather than glare). Run it on the reference pass, where
    the source is not spread by the filter; sources need a radius of at least
    about 2 pixels to survive the median filter.

    Parameters
    ----------
    data : numpy.ndarray
        Events (with ``sensor_size``) or an ``(H, W)`` count map.
    sensor_size : (width, height), optional
    sigma_px : float
        Gaussian smoothing (pixels).
    level : float
        Threshold as a fraction of the smoothed maximum.
    max_sources : int
        How many regions to return at most.
    min_area_px : int
        Smallest region kept (pixels above the threshold).
    margin_px : float
        Added to each circle's equivalent radius.

    Returns
    -------
    list of Circle
        Brightest first.

    Raises
    ------
    ParameterError
        No events, or no region large enough.

    Examples
    --------
    >>> counts = np.zeros((40, 60)); yy, xx = np.mgrid[:40, :60]
    >>> counts[(xx - 30) ** 2 + (yy - 20) ** 2 <= 25] = 100.0
    >>> counts[3, 3] = 1e4  # a hot pixel
    >>> (c,) = detect_light_source(counts)
    >>> round(c.cx), round(c.cy), round(c.r)
    (30, 20, 6)
    """
    counts = _count_map(data, sensor_size)
    if not 0 < level < 1:
        raise ParameterError(f"level must lie in (0, 1), got {level}")
    if int(max_sources) < 1:
        raise ParameterError(f"max_sources must be >= 1, got {max_sources}")
    smooth = ndimage.median_filter(counts, size=3, mode="nearest")
    if sigma_px > 0:
        smooth = ndimage.gaussian_filter(smooth, float(sigma_px), mode="nearest")
    peak = float(smooth.max()) if smooth.size else 0.0
    if peak <= 0:
        raise ParameterError("no events (after removing isolated pixels): no light source found")
    labels, n = ndimage.label(smooth >= level * peak, structure=np.ones((3, 3), dtype=bool))
    index = np.arange(1, n + 1)
    area = np.asarray(ndimage.sum_labels(np.ones_like(smooth), labels, index))
    peaks = np.asarray(ndimage.maximum(smooth, labels, index))
    order = [int(i) for i in np.argsort(-peaks, kind="stable") if area[i] >= min_area_px]
    if not order:
        raise ParameterError(
            f"no bright region of at least {min_area_px} pixels; give the light as circle:CX,CY,R"
        )
    lights = []
    for i in order[: int(max_sources)]:
        cy, cx = ndimage.center_of_mass(smooth, labels, i + 1)
        radius = math.sqrt(area[i] / math.pi) + max(0.0, float(margin_px))
        lights.append(Circle(float(cx), float(cy), radius))
    return lights
