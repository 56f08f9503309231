"""python experiments/far-shift/sets.py r-sim|mini WEIGHTS...: the paper's eight metrics of
each weights file (its card's priors and shifts included) on the ``eflare-r-sim`` test set
or the ``eflare-mini`` test split, the sets of ``benchmarks/flare_targets.py`` (simulated
into ``benchmarks/.data`` when absent). One line per weights file; no baselines."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from flare_targets import _dataset, _model

from edeflare.eval.benchmark import benchmark

if __name__ == "__main__":
    which, data = sys.argv[1], Path("benchmarks/.data")
    if which == "r-sim":
        files = _dataset(data / "eflare-r-sim", "eflare-r-sim")
    elif which == "mini":
        files = _dataset(
            data / "eflare-mini-test", "eflare-mini", sequences=20, test_sequences=20, seed=9999
        )
    else:
        sys.exit(f"unknown set {which!r}: r-sim or mini")
    methods = {Path(w).stem: _model(w) for w in sys.argv[2:]}
    result = benchmark(files, methods, downstream=False, progress=False)
    for name, scores in result.evaluation.methods.items():
        print(which, name, " ".join(f"{k} {v:.4f}" for k, v in scores.means.items()), flush=True)
