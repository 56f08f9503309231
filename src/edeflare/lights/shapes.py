"""The outline of a light source on the sensor: a circle or a polygon, in pixels."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..events import SensorSize, check_sensor_size

__all__ = ["Circle", "Polygon", "Shape", "light_mask", "parse_light"]


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


Shape = Circle | Polygon
"""A light source's outline on the sensor."""

_LIGHT_SYNTAX = "circle:CX,CY,R or polygon:X1,Y1,X2,Y2,X3,Y3,... (pixels)"


def parse_light(text: str) -> Shape:
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


def _window(
    shape: Shape, margin: float, sensor_size: SensorSize
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


def light_mask(lights: Sequence[Shape], sensor_size: SensorSize) -> np.ndarray:
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
