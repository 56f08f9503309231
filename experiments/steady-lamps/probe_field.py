"""How many events per pixel and second the steady parts' field gives, and from what.

Measures only (the probe behind ``simulate.py --quiet``): (1) the dark parts' scene drawn
alone at 640x480 for 100 ms through a warm DVS-Voltmeter, panning as in the dark parts and
held still (no pan, shake, zoom or scene noise), with DVS346's constants and with its leak
(k4, k5) or its diffusion (k3, k6) set to 0; (2) three test sequences (indices 24-26) of
the bright part at 640x480 with a still camera, a quieter noise, and DVS-Voltmeter or the
ideal sensor: each stream's events per pixel and second.

Run: python experiments/steady-lamps/probe_field.py
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import simulate as S

from edeflare.data.generate import generate_sequence
from edeflare.sim.background import SyntheticBackground
from edeflare.sim.dvs import DVS346_K, VoltmeterParams
from edeflare.sim.script import SensorSpec

SIZE, SPAN_US = (640, 480), 100_000
PIXEL_SECONDS = SIZE[0] * SIZE[1] * SPAN_US * 1e-6
STILL = {"pan_px_per_s": (0.0, 0.0), "shake_px": (0.0, 0.0), "zoom_per_s": (0.0, 0.0)}


def main() -> None:
    """Print both tables."""
    dark = S.DARK_PARTS["steady-dark-640"].scene
    scenes = {
        "dark, panning": dark,
        "dark, still": dataclasses.replace(dark, **STILL, noise_rate_hz=(0.0, 0.0)),
    }
    k = DVS346_K
    constants = {
        "DVS346": k,
        "leak off (k4 = k5 = 0)": (*k[:3], 0.0, 0.0, k[5]),
        "diffusion off (k3 = k6 = 0)": (*k[:2], 0.0, *k[3:5], 0.0),
    }
    print("scene alone, warm DVS-Voltmeter: events per pixel and second")
    for c_name, kk in constants.items():
        spec = SensorSpec(voltmeter=VoltmeterParams(k=kk), warm_start=True)
        for s_name, scene in scenes.items():
            events = SyntheticBackground(scene).draw(SPAN_US, SIZE, spec, rng=0).events
            print(f"  {c_name:28s} {s_name:14s} {events.size / PIXEL_SECONDS:.3f}")

    bright = S.BRIGHT_PARTS["steady-bright-640"]
    sensing = S._QUIET_SENSING
    print("bright part, still camera, quieter noise: each stream's events per pixel and second")
    for sensor in ("voltmeter", "ideal"):
        script = dataclasses.replace(bright.config.script, sensor_model=sensor)
        config = dataclasses.replace(bright.config, sensing=sensing, script=script)
        recipe = dataclasses.replace(bright, scene=S._QUIET_SCENE, config=config)
        for index in (24, 25, 26):
            streams = generate_sequence(recipe, index).streams
            rates = {k: round(v.size / (recipe.duration_us * 1e-6 * SIZE[0] * SIZE[1]), 3)
                     for k, v in streams.items()}  # fmt: skip
            print(f"  {sensor:9s} sequence {index}: {rates}")


if __name__ == "__main__":
    main()
