"""The scene around a lamp, lit by it: surfaces whose brightness flickers with the lamp.

A lamp lights the surfaces around it as well as shining into the lens. On a matte wall at
distance :math:`h` from a point lamp, the illuminance at distance :math:`d` from the foot of
the lamp falls as :math:`\\cos^3`:

.. math:: E(d) = E_0 \\left(1 + (d / h)^2\\right)^{-3/2}

When the lamp flickers (mains lamps at twice the mains frequency), so does that light:
the textured surfaces around it fire at 100 or 120 Hz, events a flare-free twin under
steady light would not have. They are flare (the paper's flicker), spread over the scene's
own texture rather than the lens's smooth halo.

The forward model (``simulate_pair(variant="forward")``) multiplies the scene's video by
the illumination: observed :math:`I_{bg} (1 + g\\,\\phi\\,f(t))`, flare-free
:math:`I_{bg} (1 + g\\,\\phi\\,\\bar f)`, with :math:`g` the lamp's illuminance at its foot
in units of the ambient, :math:`\\phi` the falloff above centred on the light, :math:`f`
the lamp's flicker factor (:meth:`~edeflare.sim.script.FlareScript.intensity`) and
:math:`\\bar f` its mean over a period (:math:`1 - \\text{depth}/2`). Both twins have the
same mean brightness, so the scene's motion fires in both alike; a lamp that does not
flicker lights its surroundings steadily and adds no flare.

Examples
--------
>>> from edeflare.sim.script import FlareScript, Flicker
>>> script = FlareScript(duration_us=10_000, flicker=Flicker(100.0, "square", 1.0))
>>> lit = LitSurround(gain=3.0, radius_px=4.0)
>>> on, off = (lit.illumination(script, t, (32, 24)) for t in (1_000, 6_000))
>>> steady = lit.illumination(script, 1_000, (32, 24), steady=True)
>>> round(float(on.max()), 3), round(float(off.max()), 3), round(float(steady.max()), 3)
(4.0, 1.0, 2.5)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validation as _v
from ..errors import ParameterError
from ._validation import SimError, check_range

__all__ = ["LitSurround", "SurroundConfig"]


@dataclass(frozen=True)
class LitSurround:
    """One lamp's lit surroundings (see the module docstring).

    Parameters
    ----------
    gain : float
        The lamp's illuminance at its foot, in units of the ambient light (>= 0).
    radius_px : float
        The lamp's distance from the surfaces it lights, in pixels (> 0): the falloff's
        scale.
    """

    gain: float = 1.0
    radius_px: float = 40.0

    def __post_init__(self) -> None:
        check_range("gain", self.gain, 0)
        check_range("radius_px", self.radius_px, 0, lo_open=True)

    def illumination(
        self, script: Any, t_us: float, sensor_size: tuple[int, int], *, steady: bool = False
    ) -> np.ndarray:
        """The scene's illumination at ``t_us``, ``(height, width)``, in units of the ambient
        (1 far from the lamp); ``steady``: the flare-free twin's, the flicker's mean."""
        flicker = _mean_flicker(script) if steady else float(script.intensity(t_us))
        return 1.0 + (self.gain * flicker) * self._falloff(script, t_us, sensor_size)

    def illuminations(
        self, script: Any, t_us: float, sensor_size: tuple[int, int]
    ) -> tuple[np.ndarray, np.ndarray]:
        """The observed and the steady illumination at ``t_us`` (:meth:`illumination`'s two),
        the falloff computed once."""
        falloff = self._falloff(script, t_us, sensor_size)
        now, mean = float(script.intensity(t_us)), _mean_flicker(script)
        return 1.0 + (self.gain * now) * falloff, 1.0 + (self.gain * mean) * falloff

    def _falloff(self, script: Any, t_us: float, sensor_size: tuple[int, int]) -> np.ndarray:
        """``(1 + (d / h)^2)^(-3/2)`` around the light's position at ``t_us``."""
        width, height = sensor_size
        cx, cy = script.position_px(t_us, sensor_size)
        yy, xx = np.ogrid[:height, :width]
        r2 = ((xx - cx) ** 2 + (yy - cy) ** 2) / self.radius_px**2
        return (1.0 + r2) ** -1.5

    def to_dict(self) -> dict[str, float]:
        """A JSON-ready dict."""
        return {"gain": float(self.gain), "radius_px": float(self.radius_px)}


@dataclass(frozen=True)
class SurroundConfig:
    """How often a sequence's lamp lights its surroundings, and how strongly.

    Parameters
    ----------
    probability : float
        The share of sequences with lit surroundings (0: the stage is off).
    gain : (low, high)
        :attr:`LitSurround.gain`, drawn log-uniformly.
    radius : (low, high)
        :attr:`LitSurround.radius_px` in units of the light's radius, drawn uniformly.

    Examples
    --------
    >>> from edeflare.sim.script import FlareScript
    >>> c = SurroundConfig(probability=1.0, gain=(2.0, 2.0), radius=(3.0, 3.0))
    >>> c.draw(FlareScript(), np.random.default_rng(0))
    LitSurround(gain=2.0, radius_px=12.0)
    >>> SurroundConfig().draw(FlareScript(), np.random.default_rng(0)) is None
    True
    """

    probability: float = 0.0
    gain: tuple[float, float] = (0.5, 20.0)
    radius: tuple[float, float] = (1.0, 3.0)

    def __post_init__(self) -> None:
        _v.check_range("surround probability", self.probability, 0, 1)
        for name in ("gain", "radius"):
            lo, hi = _v.check_interval(f"surround {name}", getattr(self, name), (0.0, 1.0))
            if lo <= 0:
                raise ParameterError(f"surround {name} must have low > 0, got {(lo, hi)}")
            object.__setattr__(self, name, (lo, hi))

    @property
    def enabled(self) -> bool:
        """Whether any sequence gets lit surroundings."""
        return self.probability > 0

    def draw(self, script: Any, rng: np.random.Generator) -> LitSurround | None:
        """One sequence's lit surroundings (``None``: not lit), scaled to its light."""
        if not self.enabled or rng.random() >= self.probability:
            return None
        lo, hi = self.gain
        gain = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
        radius = float(rng.uniform(*self.radius)) * script.light.radius_px
        return LitSurround(gain, radius)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SurroundConfig:
        """Build from a mapping; unknown keys are an error."""
        return _v.dataclass_from_dict(cls, data, "surround")

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (:meth:`from_dict` round-trips it)."""
        return {"probability": float(self.probability), "gain": list(self.gain),
                "radius": list(self.radius)}  # fmt: skip


def _mean_flicker(script: Any) -> float:
    """The lamp's flicker factor averaged over a period (1 without flicker)."""
    return 1.0 if script.flicker is None else 1.0 - script.flicker.depth / 2


def surround_from_dict(data: Any) -> LitSurround:
    """A :class:`LitSurround` from :meth:`LitSurround.to_dict`'s form."""
    if not isinstance(data, Mapping) or set(data) != {"gain", "radius_px"}:
        raise SimError(f"a lit surround must be {{'gain', 'radius_px'}}, got {data!r}")
    return LitSurround(float(data["gain"]), float(data["radius_px"]))
