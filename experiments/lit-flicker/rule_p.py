"""The lit-flicker rule for P against M (the present `learned`): one table, each row judged.

Run: python experiments/lit-flicker/rule_p.py RUNS
(reads RUNS/score_P.json, RUNS/probe_P.json and RUNS/forward_P.md, as run.sh writes them;
M's are in experiments/gated-experts/results/; speed is judged apart, bench_realtime.py).
"""

from __future__ import annotations

import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(_HERE.parent / "relative-rates"))
sys.path.insert(0, str(_HERE.parent / "own-windows"))
from rule_n import _M, _read  # noqa: E402
from rule_s import WITH_LIGHT, WITHOUT_LIGHT  # noqa: E402

LAMPS = "davis346_flicker_lamps"


def main() -> None:
    runs = Path(sys.argv[1])
    m, m_share, (m_below, m_better) = _read(_M, "M")
    p, share, (below, better) = _read(runs, "P")
    rows = [("1. Gen3 light kept at half its rate / as recorded", f"{m_share:.3f}",
             f"{share:.3f}", share >= 0.9)]  # fmt: skip
    for key, label in WITH_LIGHT.items():
        if key != LAMPS:
            a, b = m[key][3], p[key][3]
            rows.append((f"2. {label}: combined", f"{a:.3f}", f"{b:.3f}", b - a >= -0.02))
    for key, label in WITHOUT_LIGHT.items():
        a, b = 100 * m[key][3], 100 * p[key][3]
        rows.append((f"3. {label} kept", f"{a:.1f} %", f"{b:.1f} %", b - a >= -2.0))
    rows.append((
        "4. eflare-forward: Chamfer below raw, metrics better than raw",
        f"{100 * m_below:.0f} %, {m_better} of 8",
        f"{100 * below:.0f} %, {better} of 8",
        below >= 0.40 and better >= 7,
    ))  # fmt: skip
    a, b = m[LAMPS][3], p[LAMPS][3]
    rows.append(("5. DAVIS lamps: combined", f"{a:.3f}", f"{b:.3f}", b - a >= 0.05))
    print("| row | M (`learned`) | P | rule |\n|---|---:|---:|---|")
    for label, a, b, ok in rows:
        print(f"| {label} | {a} | {b} | {'yes' if ok else '**no**'} |")
    print(f"\nrules 1-5 hold: {all(r[3] for r in rows)} (6, speed: bench_realtime.py)")


if __name__ == "__main__":
    main()
