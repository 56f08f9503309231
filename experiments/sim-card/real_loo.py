"""The rule knobs chosen on real recordings, each recording held out in turn.

`night`'s card knobs were chosen while looking at most of the real recordings that report
its scores. Here every real recording the project scores is one item: the annotated ones
with a light (score: the combined score, as ``edeflare score`` gives it, mean of four
window phases) and the scenes without a light (score: the share of events kept). For
each item, the six shifts and the keep threshold are searched on the *other* items (mean
score) and the choice is reported on the held-out one, beside the hand-set card's score.

Each recording's rule terms (:meth:`edeflare.models.infer.ModelDeflarer.rule_terms`) in
windowings delayed by 0, 5, 10 and 15 ms; phase k of four is the mean of windowings k
and k + 1, as ``score_recording(phases=4)`` runs the product (``benchmarks/_held_out.py``'s
``TermsRecording``; checked: the hand-set card reproduces ``flare_targets.py``'s rows).

    python real_loo.py --faery FAERY_TESTS_DATA --out real_loo.json
    python real_loo.py --faery FAERY_TESTS_DATA --out real_fits.json --fits-only \
        --fits fit.json fit-sparse.json
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parents[1] / "benchmarks"), str(HERE)]

from _held_out import TermsRecording  # noqa: E402
from fit import HAND, HAND_THRESHOLD, KNOBS  # noqa: E402

from edeflare.io import read_events  # noqa: E402
from edeflare.lights import bundled_lights, load_lights  # noqa: E402
from edeflare.models.infer import ModelDeflarer, bundled_weights  # noqa: E402

DELAYS = (0, 5_000, 10_000, 15_000)
SHIFTS = (0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
THRESHOLDS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)


@functools.cache
def _night() -> ModelDeflarer:
    return ModelDeflarer(bundled_weights("night"), runtime="torch")


class Item(TermsRecording):
    """One recording: its rule terms at four window phases (``benchmarks/_held_out.py``)."""

    def __init__(self, name: str, events: np.ndarray, size, lights=None) -> None:
        super().__init__(name, _night(), events, size, lights, phases=len(DELAYS))
        assert self.terms.delays_us == DELAYS

    def scores(
        self, knobs: tuple[float, ...], thresholds: tuple[float, ...] = THRESHOLDS
    ) -> np.ndarray:
        """Per keep threshold: the mean over the four phases of the combined
        score (or the share kept)."""
        return self.measure(dict(zip(KNOBS, knobs, strict=True)), thresholds)[:, -1]

    def score(self, knobs: tuple[float, ...], threshold: float) -> float:
        """At one keep threshold."""
        return float(self.scores(knobs, (threshold,))[0])


def load_items(real: Path, faery: Path | None) -> list[Item]:
    from flare_targets import NO_LIGHT, RECORDINGS
    from reference_window import LIGHTS as WINDOW_LIGHTS
    from reference_window import SENSOR, reference_window

    items = []
    for rec in RECORDINGS:
        r = read_events(real / rec)
        lights = load_lights(bundled_lights(rec), r.sensor_size)
        items.append(Item(rec.split(".")[0], r.events, r.sensor_size, lights))
    window = reference_window(4)
    items.append(Item("reference_window", window, SENSOR, load_lights(WINDOW_LIGHTS, SENSOR)))
    if faery is not None:
        from night_recording import HERE as BENCH
        from night_recording import SCENES, faery_file

        r = read_events(faery_file(faery / "evt3.raw"))
        lights = load_lights(BENCH / "night_recording_lights.json", r.sensor_size)
        items.append(Item("night_recording", r.events, r.sensor_size, lights))
    paths = [real / rec for rec in NO_LIGHT]
    if faery is not None:
        paths += [faery_file(faery / name, name) for name in SCENES]
    for path in paths:
        r = read_events(path)
        items.append(Item(path.name.split(".")[0], r.events, r.sensor_size))
    return items


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real", type=Path, default=HERE.parents[2] / "shared" / "data" / "real")
    ap.add_argument("--faery", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument(
        "--fits",
        type=Path,
        nargs="*",
        default=[],
        help="fit.py's JSON files: also score their cards on every item",
    )
    ap.add_argument("--fits-only", action="store_true", help="score the fits' cards, no search")
    args = ap.parse_args(argv)
    items = load_items(args.real, args.faery)
    names = [it.name for it in items]
    fitted = {}
    for path in args.fits:  # cards chosen on simulated data, every item held out
        best = json.loads(path.read_text())["best"]
        knobs = tuple(float(best["knobs"][k]) for k in KNOBS)
        fitted[path.stem] = {**best, "scores": {it.name: it.score(knobs, best["keep_threshold"])
                                                for it in items}}  # fmt: skip
        print(path.stem, {n: round(v, 4) for n, v in fitted[path.stem]["scores"].items()})

    if args.fits_only:
        args.out.write_text(json.dumps({"items": names, "simulated": fitted}, indent=1))
        return 0

    @functools.cache
    def table(knobs: tuple[float, ...]) -> np.ndarray:
        """(thresholds, items) scores."""
        return np.stack([it.scores(knobs) for it in items], 1)

    def best(knobs: tuple[float, ...], cols: list[int]) -> tuple[float, float]:
        means = table(knobs)[:, cols].mean(1)
        i = int(np.argmax(means))
        return float(means[i]), THRESHOLDS[i]

    def search(cols: list[int]) -> tuple[tuple[float, ...], float, float]:
        found = []
        for start in (tuple(HAND[k] for k in KNOBS), (0.0,) * len(KNOBS)):
            knobs = start
            score, thr = best(knobs, cols)
            moved = True
            while moved:
                moved = False
                for j in range(len(KNOBS)):
                    for v in SHIFTS:
                        trial = (*knobs[:j], v, *knobs[j + 1 :])
                        s, t = best(trial, cols)
                        if s > score + 1e-6:
                            knobs, score, thr, moved = trial, s, t, True
            found.append((score, knobs, thr))
        score, knobs, thr = max(found)
        return knobs, thr, score

    hand = tuple(HAND[k] for k in KNOBS)
    hand_scores = table(hand)[THRESHOLDS.index(HAND_THRESHOLD)]
    rows = []
    for i, name in enumerate(names):
        others = [j for j in range(len(items)) if j != i]
        knobs, thr, in_others = search(others)
        held = float(table(knobs)[THRESHOLDS.index(thr), i])
        rows.append({"held out": name, "knobs": dict(zip(KNOBS, knobs, strict=True)),
                     "keep_threshold": thr, "mean on the others": in_others,
                     "held-out score": held, "hand-set card": float(hand_scores[i])})  # fmt: skip
        print(
            f"{name:30s} held out {held:.3f}  hand {hand_scores[i]:.3f}  at {thr} "
            f"{dict(zip(KNOBS, knobs, strict=True))}",
            flush=True,
        )
    knobs, thr, score = search(list(range(len(items))))
    at = table(knobs)[THRESHOLDS.index(thr)].tolist()
    every = {"knobs": dict(zip(KNOBS, knobs, strict=True)), "keep_threshold": thr,
             "mean": score, "scores": dict(zip(names, at, strict=True))}  # fmt: skip
    print(f"chosen on every item: {score:.3f} at {thr} {every['knobs']}")
    hand_row = dict(zip(names, hand_scores.tolist(), strict=True))
    report = {"items": names, "hand": hand_row, "leave_one_out": rows, "every": every,
              "simulated": fitted}  # fmt: skip
    args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
