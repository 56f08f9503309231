"""Does the simulator make a steady lamp's flare? Ring rates, real and simulated.

1. The scattered light's rate in rings around the light, over the light's own rate
   (`edeflare.eval.flare_stats.flare_statistics`), on the Gen3 light, the DAVIS lamps
   and the night recording: the sparse-sensing stage (`edeflare.sim.sensing`) was fitted
   to the first two.
2. Four 100 ms sequences at 640x480 of `eflare-night-sparse`'s lights, flare and sensing
   with the lights steady (no flicker) and slow (at most 10 px in a sequence), simulated
   from a cold and from a warm start (`ScriptConfig.warm_start`): the light test's verdicts
   and the light's rate (light_free.py), and the flare stream's events before and after
   the sensing stage.

Run: python experiments/light-test/steady.py FAERY_DATA OUT   (OUT: where the sequences go;
writes results/steady.json)
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from light_free import REAL, ROOT, sim_rows  # noqa: E402

from edeflare.data import recipe as recipes  # noqa: E402
from edeflare.data.generate import generate_dataset  # noqa: E402
from edeflare.eval.flare_stats import RING_EDGES, flare_statistics  # noqa: E402
from edeflare.io import read_events  # noqa: E402
from edeflare.io.sequence import read_sequence  # noqa: E402
from edeflare.lights import bundled_lights, load_lights  # noqa: E402
from edeflare.models.head_training import _component, keep_labels  # noqa: E402


def steady_recipe(warm: bool) -> recipes.Recipe:
    script = dataclasses.replace(
        recipes._SPARSE_NIGHT_SCRIPT,
        no_flicker_probability=1.0,
        travel_px=(0.0, 10.0),
        warm_start=warm,
    )
    return dataclasses.replace(
        recipes._NIGHT_RECIPE,
        name=f"steady-{'warm' if warm else 'cold'}",
        sequences=4,
        test_sequences=4,
        seed=999,
        sensor_size=(640, 480),
        scene=recipes._SPARSE_NIGHT_SCENE,
        config=recipes.FlareConfig(script=script, sensing=recipes._SPARSE_NIGHT_SENSING),
    )


def ring_rates(faery: Path) -> dict:
    rings = [f"{a}-{b} r" for a, b in itertools.pairwise(RING_EDGES)]
    out = {}
    for name, path, lights in (
        ("Gen3 rotating light", REAL / "prophesee_gen3_rotating_light.raw",
         bundled_lights("prophesee_gen3_rotating_light.raw")),
        ("DAVIS lamps", REAL / "davis346_flicker_lamps.aedat4",
         bundled_lights("davis346_flicker_lamps.aedat4")),
        ("night recording", faery / "evt3.raw",
         ROOT / "benchmarks" / "night_recording_lights.json"),
    ):  # fmt: skip
        events, size = read_events(path)
        s = flare_statistics(events, load_lights(lights, size), size)
        out[name] = dict(zip(rings, (round(float(v), 5) for v in s.radial), strict=True))
        print(name, out[name], flush=True)
    return out


def main() -> None:
    faery, out = Path(sys.argv[1]), Path(sys.argv[2])
    doc: dict = {"ring rates (light = 1)": ring_rates(faery), "steady lights": []}
    for warm in (False, True):
        folder = out / ("warm" if warm else "cold")
        generate_dataset(steady_recipe(warm), folder, workers=2, progress=False)
        (row,) = sim_rows([folder / "test"])
        before = after = 0
        for path in sorted((folder / "test").glob("*.h5")):
            inp, gt, *_ = read_sequence(path)
            flare = _component(path, "flare")
            before += flare.size
            after += int((keep_labels(inp, flare) & ~keep_labels(inp, gt)).sum())
        row.update({"start": "warm" if warm else "cold", "flare stream events": before,
                    "of them flare in the input": after})  # fmt: skip
        row["data"] = f"steady lights, {row['start']} start"
        doc["steady lights"].append(row)
        print(row, flush=True)
    path = HERE / "results" / "steady.json"
    path.write_text(json.dumps(doc, indent=1, default=float) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
