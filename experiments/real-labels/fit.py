"""The real-labels study: `learned`'s perceptrons fitted also to the annotated real
recordings' regions, each recording held out of the fit that scores it (README.md).

Steps (each cached in RUN, so a rerun after a kill goes on)::

    python experiments/real-labels/fit.py rows RUN --train TRAIN --faery FAERY_DATA
    python experiments/real-labels/fit.py loo RUN          # arm 1: nine held-out fits, scored
    python experiments/real-labels/fit.py nested RUN [--part I/N]  # arm 2: the nested choice
    python experiments/real-labels/fit.py loo RUN --balance  # arm 3: real classes balanced
    python experiments/real-labels/fit.py loo RUN --hold     # arm 4: simulation held to learned
    python experiments/real-labels/fit.py loo RUN --by-source  # arm 1, by source recording

``--by-source``: the reference window is a window of the night recording, so each of the
two is held out of its fit together with the other (arm 1's other folds are unchanged).

The fits are ``edeflare tune-head``'s (:mod:`edeflare.models.head_tuning`) on these rows.

``TRAIN``: ``edeflare simulate TRAIN --recipe eflare-train --shard 0/3``; ``FAERY_DATA``:
faery 0.7.1's ``tests/data`` (``benchmarks/night_recording.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "benchmarks"))

from flare_targets import same_recording  # noqa: E402

from edeflare.eval.leave_one_out import others_of  # noqa: E402
from edeflare.io import read_events  # noqa: E402
from edeflare.io.sequence import list_sequences  # noqa: E402
from edeflare.lights import Lights, bundled_lights, load_lights  # noqa: E402
from edeflare.models.event_head import head_logits  # noqa: E402
from edeflare.models.head_training import (  # noqa: E402
    HeadTrainingConfig,
    _group,
    choose_threshold,
    collect_features,
    context_columns,
)
from edeflare.models.head_tuning import DELAYS_US as DELAYS  # noqa: E402
from edeflare.models.head_tuning import (  # noqa: E402
    REGIONS,
    LabelledRecording,
    TuningConfig,
    fit_members,
    recording_inputs,
    recording_scores,
    region_labels,
)
from edeflare.models.infer import ModelDeflarer, bundled_weights  # noqa: E402
from edeflare.models.weights import load_model, read_card  # noqa: E402


def real_recordings(faery: Path | None) -> list[tuple[str, np.ndarray, tuple, Lights | None]]:
    """The nine real recordings the targets score: (name, events, sensor, lights or None)."""
    from _common import REAL
    from flare_targets import NO_LIGHT, RECORDINGS
    from night_recording import HERE as BENCH
    from night_recording import SCENES, faery_file
    from reference_window import LIGHTS as WINDOW_LIGHTS
    from reference_window import SENSOR, reference_window

    out = []
    for rec in RECORDINGS:
        r = read_events(REAL / rec)
        out.append((rec.split(".")[0], r.events, r.sensor_size,
                    load_lights(bundled_lights(rec), r.sensor_size)))  # fmt: skip
    if faery is not None:
        r = read_events(faery_file(faery / "evt3.raw"))
        lights = load_lights(BENCH / "night_recording_lights.json", (1280, 720))
        out.append(("night_recording", r.events, r.sensor_size, lights))
    window = load_lights(WINDOW_LIGHTS, SENSOR)
    out.append(("reference_window", reference_window(4), SENSOR, window))
    paths = [REAL / rec for rec in NO_LIGHT]
    if faery is not None:
        paths += [faery_file(faery / name, name) for name in SCENES]
    for path in paths:
        r = read_events(path)
        out.append((path.name.split(".")[0], r.events, r.sensor_size, None))
    return out


def cmd_rows(args) -> None:
    run = Path(args.run)
    run.mkdir(parents=True, exist_ok=True)
    learned = ModelDeflarer(bundled_weights("learned"), runtime="torch", batch_windows=8)
    for name, events, size, lights in real_recordings(args.faery):
        path = run / f"real-{name}.npz"
        if path.is_file():
            continue
        cols = recording_inputs(learned, events, size, DELAYS)
        code = region_labels(events, size, lights)
        # checked: these columns give `learned`'s own logits
        part = events[: min(events.size, 20_000)]
        base = learned.rule_terms(part, size, DELAYS).base
        mine = np.stack([head_logits(learned.head_params, c[: part.size]) for c in cols])
        if part.size < events.size:  # the windows the part holds whole, in every windowing
            t_end, w = int(events["t"][part.size]), learned.window_us
            whole = part["t"] < min((t_end + d) // w * w - d for d in DELAYS)
            base, mine = base[:, whole], mine[:, whole]
        gap = float(np.abs(base - mine).max()) if base.size else 0.0
        assert gap < 1e-3, (name, gap)
        np.savez(path, cols=cols, code=code, size=np.asarray(size))
        print(name, events.size, {REGIONS[c]: int((code == c).sum()) for c in range(4)}, flush=True)
    sim = run / "sim.npz"
    if not sim.is_file() and args.train is not None:
        # the base network's own keep logits, its rules off (as train-head reads them)
        base = bundled_weights("night")
        night = ModelDeflarer(base, runtime="torch", batch_windows=1,
                              **{k: 0 for k in read_card(base).rules})  # fmt: skip
        config = HeadTrainingConfig(context=8, seed=0)
        model, _ = load_model(bundled_weights("learned"))
        sets = {}
        for split, balanced in (("train", True), ("test", False)):
            files = [f for d in sorted(Path(args.train).iterdir()) if (d / split).is_dir()
                     for f in list_sequences(d / split)]  # fmt: skip
            data = collect_features(files, night.window_logits, night.window_us, config,
                                    balanced=balanced, desc=split, cell_scale=8)  # fmt: skip
            cols = context_columns(model.head, data)
            groups = np.array([_group([str(f) for f in files], int(s)) for s in data["source"]])
            sets[split] = (cols, data["y"], data["light"], data["source"], groups)
        keys = ("cols", "y", "light", "source", "group")
        np.savez(sim, **{f"{s}_{k}": v for s, parts in sets.items()
                         for k, v in zip(keys, parts, strict=True)})  # fmt: skip


def load_rows(run: Path):
    with np.load(run / "sim.npz") as z:
        sim = {k: z[k] for k in z.files}
    real = {}
    for p in sorted(run.glob("real-*.npz")):
        with np.load(p) as z:
            real[p.stem[5:]] = (z["cols"], z["code"], tuple(z["size"]))
    return sim, real


def fit(sim, real, names, alpha: float = 1.0, balance: bool = False, hold: bool = False):
    """`learned`'s head with its three perceptrons fitted further on these rows
    (:func:`~edeflare.models.head_tuning.fit_members`, as ``edeflare tune-head``), and the
    threshold its simulated validation rows choose."""
    model, card = load_model(bundled_weights("learned"))
    recordings = [LabelledRecording(n, real[n][0], real[n][1]) for n in names]
    fit_members(model.head, sim["train_cols"], sim["train_y"], recordings,
                TuningConfig(real_weight=alpha, balance_classes=balance,
                             hold_simulated=hold))  # fmt: skip
    params = model.head.numpy_params()
    threshold, table = choose_threshold(head_logits(params, sim["test_cols"]), sim["test_y"],
                                        sim["test_group"])  # fmt: skip
    return model, card, params, threshold, table


def score(real_item, params, threshold: float, lights_scored: bool) -> dict[str, float]:
    """A recording's scores at four phases, as TermsRecording.measure (benchmarks/_held_out.py)."""
    return scores(real_item, params, [threshold], lights_scored)[0]


def scores(real_item, params, thresholds, lights_scored: bool) -> list[dict[str, float]]:
    """:func:`score` at each of ``thresholds`` (the head run once)."""
    cols, code, _ = real_item
    table = recording_scores(cols, code, params, thresholds, lights_scored)
    keys = ("removed", "light", "scene", "combined")  # edeflare.eval.phases.TERMS
    return [dict(zip(keys, map(float, row), strict=True)) for row in table]


LIT = ("prophesee_gen3_rotating_light", "davis346_flicker_lamps", "night_recording",
       "reference_window")  # fmt: skip


def cmd_loo(args) -> None:
    run = Path(args.run)
    sim, real = load_rows(run)
    arm = "-balanced" if args.balance else "-held" if args.hold else ""
    out_path = run / f"loo{arm}{'-by-source' if args.by_source else ''}.json"
    results = json.loads(out_path.read_text()) if out_path.is_file() else {}
    learned = ModelDeflarer(bundled_weights("learned"), runtime="torch")
    choosers = others_of(list(real), same_recording(list(real)) if args.by_source else None)
    plain = run / f"loo{arm}.json"  # a fold with the same fit, already scored
    plain = json.loads(plain.read_text()) if args.by_source and plain.is_file() else {}
    for held in real:
        if held not in results and held in plain and len(choosers[held]) == len(real) - 1:
            results[held] = plain[held]
        if held not in results:
            others = choosers[held]
            _, _, params, thr, _ = fit(sim, real, others, balance=args.balance, hold=args.hold)
            results[held] = {
                "threshold": thr,
                "held_out": score(real[held], params, thr, held in LIT),
                "learned": score(real[held], learned.head_params, learned.keep_threshold,
                                 held in LIT),
            }  # fmt: skip
            out_path.write_text(json.dumps(results, indent=1) + "\n")
        r = results[held]
        print(f"{held:32s} thr {r['threshold']:.2f}  held out {r['held_out']}  "
              f"learned {r['learned']}", flush=True)  # fmt: skip


ALPHAS = (0.1, 0.3, 1.0)
THRESHOLDS = tuple(float(t) for t in np.round(np.arange(0.05, 0.951, 0.05), 2))


def value(s: dict[str, float]) -> float:
    """The score a leave-one-out choice reads: combined, or the share kept without a light."""
    return s["combined"]


def cmd_nested(args) -> None:
    """Every fit without one or two recordings at each ALPHA, its left-out recordings scored
    at every threshold (cached in nested.json), then the nested choice per recording."""
    run = Path(args.run)
    sim, real = load_rows(run)
    names = sorted(real)
    # with --by-source a recording is left out with every input cut from it
    source = {r: r for r in names}
    source.update(same_recording(names) if args.by_source else {})
    groups = sorted({tuple(r for r in names if source[r] == g) for g in source.values()})

    def out_of(*rs: str) -> tuple[str, ...]:
        return tuple(
            sorted({m for g in groups for m in g if source[g[0]] in {source[r] for r in rs}})
        )

    part, parts = (int(v) for v in args.part.split("/"))
    path = run / ("nested.json" if parts == 1 else f"nested-{part}-of-{parts}.json")
    cache = {}
    for other in sorted(run.glob("nested*.json")):  # every part's fits so far
        cache.update(json.loads(other.read_text()))
    plans = [(a, g) for a in ALPHAS for g in groups]
    plans += [(a, tuple(sorted(g + h))) for a in ALPHAS for g in groups for h in groups if g < h]
    for n, (alpha, out) in enumerate(plans):
        key = f"{alpha}|{'+'.join(out)}"
        if key in cache or n % parts != part:
            continue
        _, _, params, sim_thr, _ = fit(sim, real, [r for r in names if r not in out], alpha)
        cache[key] = {
            "sim_threshold": sim_thr,
            "scores": {
                r: [value(v) for v in scores(real[r], params, THRESHOLDS, r in LIT)] for r in out
            },
        }
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(cache) + "\n")
        tmp.replace(path)
        print(f"{n + 1}/{len(plans)} {key}", flush=True)
    missing = [f"{a}|{'+'.join(out)}" for a, out in plans if f"{a}|{'+'.join(out)}" not in cache]
    if missing:
        print(f"{len(missing)} fits left to other parts", flush=True)
        return

    def inner(alpha: float, o: str) -> np.ndarray:
        """Mean over i of another source of fit-without-{o, i}'s score on i, per threshold."""
        rows = [cache[f"{alpha}|{'+'.join(out_of(o, i))}"]["scores"][i]
                for i in names if source[i] != source[o]]  # fmt: skip
        return np.mean(rows, axis=0)

    result = {}
    for o in names:
        table = {a: inner(a, o) for a in ALPHAS}
        a, k = max(((a, k) for a in ALPHAS for k in range(len(THRESHOLDS))),
                   key=lambda ak: table[ak[0]][ak[1]])  # fmt: skip
        result[o] = {"alpha": a, "threshold": THRESHOLDS[k],
                     "inner_mean": float(table[a][k]),
                     "held_out": cache[f"{a}|{'+'.join(out_of(o))}"]["scores"][o][k]}  # fmt: skip
        print(f"{o:32s} alpha {a} thr {THRESHOLDS[k]:.2f} held out {result[o]['held_out']:.3f}")
    plain = {a: np.mean([cache[f"{a}|{'+'.join(out_of(o))}"]["scores"][o] for o in names], axis=0)
             for a in ALPHAS}  # fmt: skip
    a, k = max(((a, k) for a in ALPHAS for k in range(len(THRESHOLDS))),
               key=lambda ak: plain[ak[0]][ak[1]])  # fmt: skip
    result["_bundle"] = {"alpha": a, "threshold": THRESHOLDS[k], "loo_mean": float(plain[a][k])}
    print("bundle:", result["_bundle"])
    choice = "choice-by-source.json" if args.by_source else "choice.json"
    (run / choice).write_text(json.dumps(result, indent=1) + "\n")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("rows")
    r.add_argument("run")
    r.add_argument("--train", help="the simulated rows' data (without: the real rows only)")
    r.add_argument("--faery", type=Path)
    lo = sub.add_parser("loo")
    lo.add_argument("run")
    lo.add_argument("--balance", action="store_true", help="arm 3: the real rows' classes balanced")
    lo.add_argument("--hold", action="store_true", help="arm 4: the simulated rows held to learned")
    lo.add_argument(
        "--by-source",
        action="store_true",
        help="the reference window held out with the night recording it is cut from",
    )
    ne = sub.add_parser("nested")
    ne.add_argument("run")
    ne.add_argument("--part", default="0/1", help="I/N: the fits with index %% N == I")
    ne.add_argument(
        "--by-source",
        action="store_true",
        help="the reference window left out with the night recording it is cut from",
    )
    args = p.parse_args()
    {"rows": cmd_rows, "loo": cmd_loo, "nested": cmd_nested}[args.cmd](args)


if __name__ == "__main__":
    main()
