import sys

from edeflare.eval.score import score_recording
from edeflare.io import read_events
from edeflare.methods import create_method

R = "../shared/data/real/"
A = "src/edeflare/assets/lights/"
for w in sys.argv[1:]:
    line = [w.split("/")[-1]]
    for f, a in (
        ("davis346_flicker_lamps.aedat4", "davis346_flicker_lamps.json"),
        ("prophesee_gen3_rotating_light.raw", "prophesee_gen3_rotating_light.json"),
    ):
        r = score_recording(
            R + f, ["model"], lights=A + a, method_params={"model": {"weights": w}}
        ).rows[0]
        line.append(
            f"{f[:5]} fr {r.flare_removed:.3f} lk {r.light_kept:.3f} "
            f"bk {r.background_kept:.3f} c {r.combined:.3f}"
        )
    for f in (
        "davis346_street_cars.aedat4",
        "davis346_lowlight_cradle.aedat4",
        "prophesee_gen41_street.raw",
    ):
        ev, size = read_events(R + f)
        out = create_method("model", weights=w)(ev, size, rng=0)
        line.append(f"{f[:12]} kept {out.size / ev.size:.3f}")
    print(" | ".join(line), flush=True)
