"""The own-windows rule for N against M (the present `learned`): one table, each row judged.

Run: python experiments/own-windows/rule_n.py RUNS
(reads RUNS/score_N.json, RUNS/probe_N.json and RUNS/forward_N.md, as run.sh writes them;
M's are in experiments/gated-experts/results/).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(_HERE.parent / "relative-rates"))
from rule_s import WITH_LIGHT, WITHOUT_LIGHT, forward_row  # noqa: E402

_M = _HERE.parent / "gated-experts" / "results"


def _read(folder: Path, name: str) -> tuple[dict, float, tuple[float, int]]:
    score = json.loads((folder / f"score_{name}.json").read_text())
    gen3 = json.loads((folder / f"probe_{name}.json").read_text())["prophesee_gen3_rotating_light"]
    return score, gen3["0.5"][1] / gen3["1.0"][1], forward_row(folder / f"forward_{name}.md", name)


def main() -> None:
    runs = Path(sys.argv[1])
    m, m_share, (m_below, m_better) = _read(_M, "M")
    n, share, (below, better) = _read(runs, "N")
    rows = [("Gen3 light kept at half its rate / as recorded", f"{m_share:.3f}", f"{share:.3f}",
             share >= 0.9, False)]  # fmt: skip
    for key, label in WITH_LIGHT.items():
        a, b = m[key][3], n[key][3]
        rows.append((f"{label}: combined", f"{a:.3f}", f"{b:.3f}", b - a >= -0.02, b - a >= 0.02))
    for key, label in WITHOUT_LIGHT.items():
        a, b = 100 * m[key][3], 100 * n[key][3]
        rows.append((f"{label} kept", f"{a:.1f} %", f"{b:.1f} %", b - a >= -2.0, b - a >= 2.0))
    rows.append((
        "eflare-forward: Chamfer below raw, metrics better than raw",
        f"{100 * m_below:.0f} %, {m_better} of 8",
        f"{100 * below:.0f} %, {better} of 8",
        below >= 0.40 and better >= 7,
        below - m_below >= 0.05,
    ))  # fmt: skip
    print("| row | M (`learned`) | N | rules 1-4 | better (5) |\n|---|---:|---:|---|---|")
    for label, a, b, ok, gain in rows:
        print(f"| {label} | {a} | {b} | {'yes' if ok else '**no**'} | {'yes' if gain else ''} |")
    held = all(r[3] for r in rows)
    gained = any(r[4] for r in rows)
    print(f"\nrules 1-4 hold: {held}; better somewhere (5): {gained}; "
          f"N replaces M: {held and gained}")


if __name__ == "__main__":
    main()
