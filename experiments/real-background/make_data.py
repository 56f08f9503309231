"""Flare over real recorded scenes: the paper's anchoring (Sec. 3.2), for the context head.

Builds eflare-night's sparse scattered flare, sensing and hot pixels (PNL-ES), over real
event recordings that no evaluation reads: two indoor 320x240 recordings of people from
aermanager 0.3.0's source distribution on the package registry (test/data/class1/test.aedat4
and test/data/class2/data_sample.aedat4, 2.05 s in all), each sequence a random 100 ms of
them. The scene alone is stored (every event kept). A seed no other recipe uses.

eflare-mix's dense flare fused by PNL-ES was drawn too and left out: in its first sequences
the spikes covered the frame at 20-55 events per pixel in 20 ms and hid the recorded scene
(the forward model, which would compress them, needs the scene as a video).

    python experiments/real-background/make_data.py BACKGROUND_DIR OUT
"""

from __future__ import annotations

import sys
from pathlib import Path

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES, Mix

FILES = ("aermanager_test.aedat4", "aermanager_data_sample.aedat4")


def real_background_mix(background_dir: Path) -> Mix:
    files = tuple(str(background_dir / name) for name in FILES)
    recorded = {"background": "recorded", "background_files": files, "sensor_size": (320, 240)}
    night = RECIPES["eflare-night"].replace(
        name="real-bg.night-320", sequences=60, test_sequences=6, seed=218, **recorded
    )
    return Mix("real-bg", (("night-320", night),))


if __name__ == "__main__":
    generate_dataset(real_background_mix(Path(sys.argv[1])), sys.argv[2], workers=1)
