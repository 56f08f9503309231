"""Simulated pairs of steady lamps: lights that do not flicker, under a slowly drifting camera.

Two parts, 640x480 (24 training and 3 test sequences) and 1280x720 (8 and 1), each a
dataset of its own under OUT: `eflare-night-sparse`'s lights, flare, sparse night streets
and sensing stage (ghosts at their own rate), with the lights steady (no flicker) and slow
(at most 10 px in 100 ms; 15 at 1280x720), the sensors started warm
(`ScriptConfig(warm_start=True)`), and the scattered light surviving the sensing stage
at 5-50 % (log-uniform) times (2 r / d) rather than `eflare-night-sparse`'s 0.3-20 % times
(2 r / d)^2. Every one of these ranges was set after the night recording (faery's
`evt3.raw`) was measured (experiments/light-test): that recording is no evidence for them.

Two more parts (``--dark``: `steady-dark-640`, 24 and 3; `steady-dark-1280`, 8 and 1) put
the same lamps over a dark field that they dominate: the street's pan, shake, zoom and
texture cut to a night sky's (pan 0.2-3 px/s, shake up to 0.1 px, contrast 0.01-0.05, no
lamps of its own, its noise 0.01-0.1 events per pixel and second) and the sensing stage's
background activity to 0.02-0.5 events per pixel and second (0.1-5). Set after
relative-rates' gap_hot.py measured the night recording's windows: that recording is no
evidence for them either.

Two more (``--bright``: `steady-bright-640`, `steady-bright-1280`, the dark parts' sizes)
have the dark parts' field with more of the scattered light surviving: 30-100 % times
(2 r / d)^0.5. Set after the dark parts were measured.

Two more (``--quiet``: `steady-quiet-640`, `steady-quiet-1280`, the same sizes) have the
bright parts' lamps and survival over a field as quiet as they can make it: a still camera
(pan 0-0.5 px/s, shake up to 0.05 px, no zoom), the scene's noise 0.005-0.05 and the
sensing stage's background activity 0.01-0.1 events per pixel and second, and the ideal
log sensor (thresholds 0.15-0.35, no leak) in place of DVS-Voltmeter, whose leak alone
fires a still dark field at about 0.2 events per pixel and second once warm. Set after
the bright parts were measured and after a probe of three simulated sequences; the night
recording is no evidence for them.

Run: python experiments/steady-lamps/simulate.py OUT [--dark | --bright | --quiet]
(resumes; 2 workers)
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from edeflare.data import recipe as R
from edeflare.data.generate import generate_dataset

_HD = 1.5
_SENSING = dataclasses.replace(R._SPARSE_NIGHT_SENSING, survival=(0.05, 0.5), falloff=1.0)
_SCRIPT = dataclasses.replace(
    R._SPARSE_NIGHT_SCRIPT, no_flicker_probability=1.0, travel_px=(0.0, 10.0), warm_start=True
)
_SCRIPT_HD = dataclasses.replace(
    _SCRIPT,
    light_radius_px=tuple(v * _HD for v in _SCRIPT.light_radius_px),
    ghost_radius_px=tuple(v * _HD for v in _SCRIPT.ghost_radius_px),
    travel_px=(0.0, 15.0),
)


def _hd(scene: R.SceneConfig) -> R.SceneConfig:
    """``scene`` at 1280x720: its pan and shake in pixels x1.5."""
    return dataclasses.replace(
        scene,
        pan_px_per_s=tuple(v * _HD for v in scene.pan_px_per_s),
        shake_px=tuple(v * _HD for v in scene.shake_px),
    )


_SCENE_HD = _hd(R._SPARSE_NIGHT_SCENE)
_DARK_SCENE = dataclasses.replace(
    R._SPARSE_NIGHT_SCENE, pan_px_per_s=(0.2, 3.0), shake_px=(0.0, 0.1), zoom_per_s=(0.0, 0.02),
    texture_contrast=(0.01, 0.05), lamps=(0, 0), noise_rate_hz=(0.01, 0.1),
)  # fmt: skip
_DARK_SCENE_HD = _hd(_DARK_SCENE)
_DARK_SENSING = dataclasses.replace(_SENSING, noise_rate=(0.02, 0.5))
_BRIGHT_SENSING = dataclasses.replace(_DARK_SENSING, survival=(0.3, 1.0), falloff=0.5)
PARTS = {
    "steady-640": R.Recipe(
        name="steady-lamps.steady-640", sequences=27, test_sequences=3, sensor_size=(640, 480),
        seed=401, scene=R._SPARSE_NIGHT_SCENE,
        config=R.FlareConfig(script=_SCRIPT, sensing=_SENSING),
    ),
    "steady-1280": R.Recipe(
        name="steady-lamps.steady-1280", sequences=9, test_sequences=1, sensor_size=(1280, 720),
        seed=402, scene=_SCENE_HD,
        config=R.FlareConfig(script=_SCRIPT_HD, sensing=_SENSING, components=True),
    ),
}  # fmt: skip
DARK_PARTS = {
    "steady-dark-640": R.Recipe(
        name="steady-lamps.steady-dark-640", sequences=27, test_sequences=3,
        sensor_size=(640, 480), seed=403, scene=_DARK_SCENE,
        config=R.FlareConfig(script=_SCRIPT, sensing=_DARK_SENSING),
    ),
    "steady-dark-1280": R.Recipe(
        name="steady-lamps.steady-dark-1280", sequences=9, test_sequences=1,
        sensor_size=(1280, 720), seed=404, scene=_DARK_SCENE_HD,
        config=R.FlareConfig(script=_SCRIPT_HD, sensing=_DARK_SENSING, components=True),
    ),
}  # fmt: skip

BRIGHT_PARTS = {
    name.replace("dark", "bright"): dataclasses.replace(
        recipe, name=recipe.name.replace("dark", "bright"), seed=recipe.seed + 2,
        config=dataclasses.replace(recipe.config, sensing=_BRIGHT_SENSING),
    )
    for name, recipe in DARK_PARTS.items()
}  # fmt: skip

_QUIET_SCENE = dataclasses.replace(
    _DARK_SCENE, pan_px_per_s=(0.0, 0.5), shake_px=(0.0, 0.05), zoom_per_s=(0.0, 0.0),
    noise_rate_hz=(0.005, 0.05),
)  # fmt: skip
_QUIET_SENSING = dataclasses.replace(_BRIGHT_SENSING, noise_rate=(0.01, 0.1))
QUIET_PARTS = {
    name.replace("dark", "quiet"): dataclasses.replace(
        recipe, name=recipe.name.replace("dark", "quiet"), seed=recipe.seed + 4,
        scene=_QUIET_SCENE if recipe.sensor_size == (640, 480) else _hd(_QUIET_SCENE),
        config=dataclasses.replace(
            recipe.config, sensing=_QUIET_SENSING,
            script=dataclasses.replace(recipe.config.script, sensor_model="ideal"),
        ),
    )
    for name, recipe in DARK_PARTS.items()
}  # fmt: skip


def main() -> None:
    out = Path(sys.argv[1])
    variant = sys.argv[2] if len(sys.argv) > 2 else ""
    parts = {"": PARTS, "--dark": DARK_PARTS, "--bright": BRIGHT_PARTS, "--quiet": QUIET_PARTS}
    parts = parts[variant]
    for name, recipe in parts.items():
        generate_dataset(recipe, out / name, workers=2, progress=False)
        print(f"{name}: done", flush=True)


if __name__ == "__main__":
    main()
