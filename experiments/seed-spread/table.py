"""The study's tables from score.py's JSON files (combined score of the recordings with a
light, share kept of those without).

Run: python experiments/seed-spread/table.py results/
"""

import json
import sys
from pathlib import Path

ROWS = [
    ("Gen3 light: combined", "prophesee_gen3_rotating_light"),
    ("DAVIS lamps: combined", "davis346_flicker_lamps"),
    ("night recording: combined", "night_recording"),
    ("reference window: combined", "reference_window"),
    ("DAVIS street: kept", "davis346_street_cars"),
    ("cradle: kept", "davis346_lowlight_cradle"),
    ("Gen4.1 street: kept", "prophesee_gen41_street"),
    ("faery's leaves: kept", "evt2"),
    ("faery's object: kept", "dvs"),
    ("unseen face: kept", "face"),
    ("unseen slider: kept", "slider_depth"),
]


def value(score: dict, key: str) -> float | None:
    v = score.get(key)
    if v is None:
        return None
    return v["kept"] / 100 if isinstance(v, dict) else v[3]


def table(folder: Path, columns: list[str], pairs: list[tuple[str, str]]) -> str:
    scores = {c: json.loads((folder / f"{c}.json").read_text()) for c in columns}
    head = ["row", *columns, *(f"{b} - {a}" for a, b in pairs)]
    lines = ["| " + " | ".join(head) + " |", "|---" + "|---:" * (len(head) - 1) + "|"]
    for label, key in ROWS:
        vals = [value(scores[c], key) for c in columns]
        cells = ["-" if v is None else f"{v:.3f}" for v in vals]
        for a, b in pairs:
            va, vb = value(scores[a], key), value(scores[b], key)
            cells.append("-" if va is None or vb is None else f"{vb - va:+.3f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    folder = Path(sys.argv[1])
    cols = sys.argv[2].split(",")
    pairs = [tuple(p.split(":")) for p in sys.argv[3].split(",")] if len(sys.argv) > 3 else []
    print(table(folder, cols, pairs))
