"""The sixth question's rule for a run against `learned`: one table, each row judged.

Run: python experiments/relative-rates/rule_s.py RUNS NAME
(reads RUNS/score_NAME.json, RUNS/probe_NAME.json and RUNS/forward_NAME.md, as written by
full_steady.sh; `learned`'s four-phase rows are the near-objects study's learned.json).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
_LEARNED = _HERE.parent / "near-objects" / "results" / "learned.json"
WITH_LIGHT = {
    "prophesee_gen3_rotating_light": "Gen3 light",
    "davis346_flicker_lamps": "DAVIS lamps",
    "night_recording": "night recording (guard)",
    "reference_window": "reference window (guard)",
}
WITHOUT_LIGHT = {
    "davis346_street_cars": "DAVIS street",
    "davis346_lowlight_cradle": "cradle",
    "prophesee_gen41_street": "Gen4.1 street",
    "evt2": "faery's leaves",
    "dvs": "faery's object",
}


def forward_row(path: Path, name: str) -> tuple[float, int]:
    """Chamfer below raw (a share) and the metrics better than raw, from a benchmark report."""
    rows = {}
    for line in path.read_text().splitlines():
        cells = [c.strip().strip("*") for c in line.strip("|").split("|")]
        if len(cells) == 9 and re.match(r"^-?[\d.]+$", cells[1]):
            rows[cells[0]] = [float(c) for c in cells[1:]]
    raw, run = rows["raw (input)"], rows[name]
    lower_better = 5  # Chamfer, Gaussian, MSE, PMSE-2, PMSE-4; then three F1s
    better = sum(
        (r < b) if i < lower_better else (r > b)
        for i, (r, b) in enumerate(zip(run, raw, strict=True))
    )
    return 1 - run[0] / raw[0], better


def main() -> None:
    runs, name = Path(sys.argv[1]), sys.argv[2]
    learned = json.loads(_LEARNED.read_text())
    score = json.loads((runs / f"score_{name}.json").read_text())
    probe = json.loads((runs / f"probe_{name}.json").read_text())
    gen3 = probe["prophesee_gen3_rotating_light"]
    share = gen3["0.5"][1] / gen3["1.0"][1]
    rows = [("Gen3 light kept at half its rate / as recorded", "", f"{share:.3f}", share >= 0.9)]
    for key, label in WITH_LIGHT.items():
        a, b = learned[key][3], score[key][3]
        rows.append((f"{label}: combined", f"{a:.3f}", f"{b:.3f}", b - a >= -0.03))
    for key, label in WITHOUT_LIGHT.items():
        a, b = 100 * learned[key][3], 100 * score[key][3]
        rows.append((f"{label} kept", f"{a:.1f} %", f"{b:.1f} %", b - a >= -2.0))
    below, better = forward_row(runs / f"forward_{name}.md", name)
    rows.append(
        (
            "eflare-forward: Chamfer below raw, metrics better than raw",
            "66 %, 8 of 8",
            f"{100 * below:.0f} %, {better} of 8",
            below >= 0.40 and better >= 7,
        )
    )
    print(f"| row | `learned` | {name} | rule |\n|---|---:|---:|---|")
    for label, a, b, ok in rows:
        print(f"| {label} | {a} | {b} | {'yes' if ok else '**no**'} |")
    print(f"\nall hold: {all(r[3] for r in rows)}")


if __name__ == "__main__":
    main()
