"""Byte-identity proof for restructurings: digests of what the package makes.

Records the SHA-256 of

- generated sequence files of every recipe kind (fixed seeds, small sizes):
  ``flare`` (eflare-mini shrunk, with the variants and weights the pair loop
  branches on, and a recorded background), ``optics`` (eflare-r-sim-mini
  shrunk, synthetic and recorded backgrounds) and ``dsec`` (dsec-flare on a
  small fake DSEC tree written here);
- ``deflare`` outputs of every registered method on short crops of the shared
  real recordings, in memory and streamed through ``deflare_file``;
- a benchmark table (markdown, CSV and JSON) over a generated optics split;
- every CLI command's ``--help`` option list;

and compares them with a recorded JSON::

    python benchmarks/refactor_proof.py record proof.json
    python benchmarks/refactor_proof.py check proof.json

Run it at the commit before the change and after it; ``check`` lists every
digest that differs and exits 1. Recorded: ``results/refactor_proof_e8f9624.json``
(before the recipe split) and ``results/refactor_proof_caac30c.json`` (after it: every
digest of the first unchanged; new methods and commands added since), and
``results/refactor_proof_3513a7a.json`` (before the methods, rules and lights packages:
``check`` against it gives 0 differences after them, added options noted). Run it
in a clean worktree (``PYTHONPATH=WORKTREE/src``) so that uncommitted work in
progress is not measured.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import re
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

REAL = Path(os.environ.get("EDEFLARE_REAL_DATA", "/work/shared/data/real"))
REAL_FILES = (
    "davis346_flicker_lamps.aedat4",
    "prophesee_gen3_rotating_light.raw",
    "atis_ncars_crop.dat",
)
CROP_US = 60_000
BG_FILE = "davis346_street_cars.aedat4"


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _file_sha(path: Path) -> str:
    return _sha(path.read_bytes())


def _recipes():
    try:
        from edeflare.data.recipes import RECIPES  # after the restructure, if moved
    except ImportError:
        from edeflare.data.generate import RECIPES
    return RECIPES


def _generate(recipe, out: Path) -> dict[str, str]:
    from edeflare.data.generate import generate_dataset

    report = generate_dataset(recipe, out, progress=False)
    digests = {f["file"]: f["sha256"] for f in report.manifest["files"]}
    for f in report.manifest["files"]:  # the manifest's digests are the files'
        assert _file_sha(out / f["file"]) == f["sha256"], f["file"]
    manifest = dict(report.manifest)
    digests["manifest"] = _sha(json.dumps(manifest, sort_keys=True).encode())
    return digests


def _replace(recipe, **changes):
    """A changed recipe across the flat (old) and per-kind (new, ``Recipe.replace``) layouts."""
    if hasattr(recipe, "replace"):
        return recipe.replace(**changes)
    return dataclasses.replace(recipe, **changes)


def _fake_dsec(root: Path) -> None:
    import h5py
    import hdf5plugin

    layouts = {
        "zurich_city_03_a": "{seq}/events/left/events.h5",
        "zurich_city_10_b": "train/{seq}/events/left/events.h5",
        "zurich_city_12_a": "test/{seq}/events/left/events.h5",
        "zurich_city_09_c": "{seq}/events_left/events.h5",
        "zurich_city_09_d": "train/{seq}/events/left/events.h5",
    }
    span = 27_000_000
    for i, (seq, layout) in enumerate(layouts.items()):
        gen = np.random.default_rng(i)
        n = span // 2500
        ev = {
            "t": np.sort(gen.integers(0, span, n)).astype(np.uint32),
            "x": gen.integers(0, 640, n).astype(np.uint16),
            "y": gen.integers(0, 480, n).astype(np.uint16),
            "p": gen.integers(0, 2, n).astype(np.uint8),
        }
        path = root / layout.format(seq=seq)
        path.parent.mkdir(parents=True, exist_ok=True)
        comp = hdf5plugin.Blosc(cname="zstd", clevel=1)
        ms = np.searchsorted(ev["t"], np.arange(int(ev["t"][-1]) // 1000 + 1) * 1000)
        with h5py.File(path, "w") as f:
            for k in ("p", "t", "x", "y"):
                f.create_dataset(f"events/{k}", data=ev[k], **comp)
            f.create_dataset("ms_to_idx", data=ms.astype(np.uint64))
            f.create_dataset("t_offset", data=np.int64(49_599_300_523))


def sequences(tmp: Path) -> dict[str, dict[str, str]]:
    """Digests of generated datasets, one entry per configuration."""
    from edeflare.sim.background import SceneConfig
    from edeflare.sim.optics_scene import OpticsSceneConfig

    recipes = _recipes()
    out: dict[str, dict[str, str]] = {}
    small = {"sensor_size": (64, 48), "duration_us": 40_000, "window_us": 20_000}
    mini = _replace(recipes["eflare-mini"], sequences=2, test_sequences=1, **small)
    configs = {
        "flare": mini,
        "flare-forward": _replace(mini, variant="forward", name="fwd"),
        "flare-counts-simple+random": _replace(
            mini, weights="counts", variant="simple+random", name="counts"
        ),
        "flare-accumulation-noindep": _replace(
            mini, weights="accumulation", independent_background=True, name="acc"
        ),
        "flare-recorded": _replace(
            mini,
            background="recorded",
            background_files=(str(REAL / BG_FILE),),
            name="rec",
            components=False,
        ),
    }
    rsim = recipes["eflare-r-sim-mini"]
    optics_small = {
        "sensor_size": (64, 48),
        "duration_us": 20_000,
        "window_us": 10_000,
        "sequences": 2,
    }
    configs["optics"] = _replace(rsim, **optics_small)
    configs["optics-recorded"] = _replace(
        rsim,
        background="recorded",
        background_files=(str(REAL / BG_FILE),),
        name="optics-rec",
        **optics_small,
    )
    del SceneConfig, OpticsSceneConfig
    for name, recipe in configs.items():
        print(f"  generate {name}", file=sys.stderr)
        out[name] = _generate(recipe, tmp / name)
    root = tmp / "dsec-root"
    _fake_dsec(root)
    from edeflare.data.dsec_flare import DsecFlareConfig

    dsec = _replace(recipes["dsec-flare"], dsec=DsecFlareConfig(root=str(root)))
    print("  generate dsec", file=sys.stderr)
    out["dsec"] = _generate(dsec, tmp / "dsec")
    return out


def deflare_outputs(tmp: Path) -> dict[str, str]:
    """Digests of every method's output on crops of the real recordings."""
    try:
        from edeflare.methods import deflare, deflare_file, list_methods
    except ImportError:  # before the methods package
        from edeflare.deflare import deflare, deflare_file, list_methods
    from edeflare.events import slice_time
    from edeflare.io import read_events, write_events

    out: dict[str, str] = {}
    for fname in REAL_FILES:
        events, size = read_events(REAL / fname)
        t0 = int(events["t"][0])
        crop = slice_time(events, t0, t0 + CROP_US)
        crop_path = tmp / f"{Path(fname).stem}.h5"
        write_events(crop_path, crop, size)
        for method in list_methods():
            print(f"  deflare {fname} {method}", file=sys.stderr)
            try:
                res = deflare(crop, size, method, rng=3)
            except ImportError as exc:  # an optional extra not installed here
                out[f"{fname}:{method}"] = f"unavailable: {type(exc).__name__}"
                continue
            out[f"{fname}:{method}:memory"] = _sha(res.tobytes())
            dst = tmp / f"{Path(fname).stem}.{method}.h5"
            deflare_file(crop_path, dst, method, rng=3, progress=False)
            back, _ = read_events(dst)
            out[f"{fname}:{method}:file"] = _sha(back.tobytes())
    return out


def benchmark_table(tmp: Path) -> dict[str, str]:
    """Digests of a benchmark table over an optics split."""
    try:
        from edeflare.eval.benchmark import benchmark
    except ImportError:
        from edeflare.benchmark import benchmark

    recipe = _replace(
        _recipes()["eflare-r-sim-mini"],
        sensor_size=(64, 48),
        duration_us=40_000,
        window_us=20_000,
        sequences=2,
        seed=5,
    )
    from edeflare.data.generate import generate_dataset

    generate_dataset(recipe, tmp / "bench", progress=False)
    rows = {"raw": "raw", "efr": "efr", "pfd-a": "pfd-a", "pfd-b": "pfd-b", "voxel": "voxel"}
    result = benchmark(tmp / "bench" / "test", rows, progress=False)
    table = result.table()
    ev = result.evaluation.to_dict()
    if ev.get("convention") == "edeflare":  # added with the authors' convention; the default
        del ev["convention"]
    return {
        "markdown": _sha(table.to_markdown().encode()),
        "csv": _sha(table.to_csv().encode()),
        "json": _sha(table.to_json().encode()),
        "evaluation": _sha(json.dumps(ev, sort_keys=True).encode()),
    }


def cli_options() -> dict[str, list[str]]:
    """Every command's option strings (sorted), from its parser."""
    import argparse

    from edeflare.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = {"": sorted(s for a in parser._actions for s in a.option_strings)}
    for name, p in sub.choices.items():
        opts = []
        for a in p._actions:
            if a.option_strings:
                opts.extend(a.option_strings)
            else:
                opts.append(f"<{a.dest}>")
        out[name] = sorted(opts)
    return out


def cli_help() -> dict[str, str]:
    """Every command's full ``--help`` text (compared as a warning only)."""
    import argparse

    from edeflare.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    os.environ["COLUMNS"] = "100"
    return {name: re.sub(r"\s+", " ", p.format_help()) for name, p in sub.choices.items()}


def collect(parts: list[str]) -> dict[str, object]:
    warnings.simplefilter("ignore")
    result: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if "cli" in parts:
            result["cli_options"] = cli_options()
            result["cli_help"] = cli_help()
        if "sequences" in parts:
            result["sequences"] = sequences(tmp)
        if "deflare" in parts:
            result["deflare"] = deflare_outputs(tmp)
        if "benchmark" in parts:
            result["benchmark"] = benchmark_table(tmp)
    return result


def _diff(a: object, b: object, where: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}/{k}: only in {'recorded' if k in a else 'now'}")
            else:
                out.extend(_diff(a[k], b[k], f"{where}/{k}"))
        return out
    return [] if a == b else [f"{where}: {a!r} != {b!r}"[:300]]


# options renamed since a record, each command line of the old name still working
RENAMED = {"deflare": {"<input>": "<inputs>"}}  # deflare IN [IN ...] OUT: one or many inputs


def _option_diff(recorded: dict[str, list[str]], now: dict[str, list[str]]) -> list[str]:
    """Commands and options lost are differences; new ones are noted (an addition keeps
    every recorded command line working); renamed ones (:data:`RENAMED`) are mapped."""
    out = []
    recorded = {
        c: sorted(RENAMED.get(c, {}).get(o, o) for o in opts) for c, opts in recorded.items()
    }
    for command in sorted(set(recorded) | set(now)):
        if command not in now:
            out.append(f"/cli_options/{command}: only in recorded")
            continue
        gone = sorted(set(recorded.get(command, [])) - set(now[command]))
        added = sorted(set(now[command]) - set(recorded.get(command, [])))
        if gone:
            out.append(f"/cli_options/{command}: options gone {gone}")
        if added:
            print(f"note (added): /cli_options/{command}: {added}")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("record", "check"))
    parser.add_argument("path", type=Path)
    parser.add_argument("--parts", nargs="+", default=["cli", "sequences", "deflare", "benchmark"])
    args = parser.parse_args(argv)
    now = collect(args.parts)
    if args.mode == "record":
        args.path.write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
        print(f"recorded {args.path}")
        return 0
    recorded = json.loads(args.path.read_text())
    recorded = {k: v for k, v in recorded.items() if k in now}
    n = sum(len(v) if isinstance(v, dict) else 1 for k, v in recorded.items() if k != "cli_help")
    help_diff = _diff(recorded.pop("cli_help", {}), now.pop("cli_help", {}), "cli_help")
    for line in help_diff:
        print(f"note (help text): {line}")
    diff = _option_diff(recorded.pop("cli_options", {}), now.pop("cli_options", {}))
    diff += _diff(recorded, json.loads(json.dumps(now)))
    for line in diff:
        print(f"DIFFERS {line}")
    print(f"{'FAIL' if diff else 'OK'}: {n} groups compared, {len(diff)} differ")
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
