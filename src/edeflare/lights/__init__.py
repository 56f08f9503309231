"""Light sources: one type, one JSON form and one detector for the whole toolkit.

- :class:`LightSource` (a disc, a polygon, a moving disc or a piecewise constant
  one) and :class:`Lights` (a recording's sources and the regions around them),
  read and written by :func:`load_lights` / :func:`save_lights`;
  :class:`Circle` / :class:`Polygon` are a fixed source's outline
  (:attr:`LightSource.shape`);
- :func:`detect_light_source` (the brightest compact regions of the event
  density), :func:`detect_lights` (the same, window by window) and
  :func:`track_lights` (followed from window to window, a radius from the rings
  around each: what the scorer uses without an annotation);
  :func:`measure_regions` / :func:`flare_reach`: how far each source's halo and
  ghost reach, from the radial event rate around it; :func:`light_response`: how
  long a moving light's pixels keep firing after it has passed;
- :func:`window_lights`: the cells of a window that hold a light, the cheap test
  a mask model's rules (:mod:`edeflare.rules`) make in every window;
  :func:`light_test_summary`: in how many windows of a recording it finds one.

The scorer (:mod:`edeflare.eval.score`), the real-capture pairing
(:mod:`edeflare.realworld`) and the model's rules all use these.

Examples
--------
>>> from edeflare.lights import LightSource, parse_lights
>>> (lamp,) = parse_lights(["circle:320,240,15"])
>>> lamp == LightSource.circle(320, 240, 15)
True
"""

from __future__ import annotations

from .cells import window_lights
from .detect import count_map_of, detect_light_source, detect_lights, light_radius, track_lights
from .reach import FlareReach, flare_reach, measure_regions
from .response import LightResponse, light_response
from .shapes import Circle, Polygon, Shape, light_mask, parse_light
from .source import Lights, LightSource, bundled_lights, load_lights, parse_lights, save_lights
from .summary import LightTestSummary, light_test_summary

__all__ = [
    "Circle",
    "FlareReach",
    "LightResponse",
    "LightSource",
    "LightTestSummary",
    "Lights",
    "Polygon",
    "Shape",
    "bundled_lights",
    "count_map_of",
    "detect_light_source",
    "detect_lights",
    "flare_reach",
    "light_mask",
    "light_radius",
    "light_response",
    "light_test_summary",
    "load_lights",
    "measure_regions",
    "parse_light",
    "parse_lights",
    "save_lights",
    "track_lights",
    "window_lights",
]
