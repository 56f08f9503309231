r"""Paired datasets from the simulator: parallel, sharded, resumable, bit-reproducible.

A :class:`Recipe` says what to make (the paper's E-Flare-2.7K is
``RECIPES["eflare-2.7k"]``: 544 sequences of 100 ms at 640x480, i.e. 2,720
paired 20 ms windows, 509 sequences / 2,545 windows for training and 35 / 175
for testing; ``eflare-mini`` is a small one for CPU training).
:func:`generate_dataset` writes it:

``OUT/train/seq_00000.h5 ... OUT/test/seq_00543.h5``
    One sequence per file (:func:`edeflare.io.dsec.write_dsec_groups`), the
    groups ``input`` (flare-corrupted events), ``gt`` (ground truth),
    ``flare``, ``light`` and ``background`` (the pure streams, so other
    compositions can be rebuilt without simulating again), each in the DSEC
    layout, and root attributes ``sensor_size``, ``t_start_us`` /
    ``t_end_us`` (the span; windows are aligned 20 ms windows from
    ``t_start_us``), ``script`` (the :class:`~edeflare.sim.script.FlareScript`
    JSON), ``background`` (its provenance JSON), ``recipe``, ``recipe_sha256``,
    ``index``, ``seed``, ``variant`` and ``edeflare_version``. This is the
    contract :class:`edeflare.data.pairs.PairedWindows` reads.
``OUT/manifest.json``
    The recipe, the package version, the seeds, per-split counts, and per
    file its split, seed, event counts per group, size and SHA-256. It holds
    nothing that depends on timing or on the order of work, so a resumed run
    ends with the same manifest as an uninterrupted one.

Sequence ``i`` is a pure function of ``(recipe, i)``: its random draws come
from ``numpy.random.SeedSequence([recipe.seed, i])`` (children: script,
background, composition, forward model; sparse sensing from ``(recipe.seed,
i, 7)``), so any sequence can be regenerated
alone, on any worker, in any order, and files are byte-identical whatever the
number of workers (HDF5 stores no timestamps; the compressor is deterministic).

One sequence (:func:`generate_sequence`) is made by the recipe's kind
(:mod:`edeflare.data.kinds`, each registered with its own config and
``make_sequence``): ``"flare"`` (:mod:`edeflare.data.eflare`: draw the
script and the background, then :func:`edeflare.sim.pair.simulate_pair`, the
simulator's one streaming frame loop, and the composition; the training
pipeline), ``"optics"`` (the paper's model of its real captures,
:mod:`edeflare.data.eflare_r_sim`: ``eflare-r-sim`` and ``eflare-r-sim-mini``,
files with ``input`` and ``gt`` only) or ``"dsec"`` (windows of the user's
DSEC copy, :mod:`edeflare.data.dsec_flare`: ``dsec-flare``, files with an
``input`` group only, no ground truth). Both test-set kinds put every
sequence in ``test/``; their files record ``kind`` and their provenance
(:class:`~edeflare.sim.optics_scene.OpticsScene` or
:class:`~edeflare.data.dsec_flare.DsecWindow` JSON) as ``script``. Recipes
themselves live in :mod:`edeflare.data.recipe`; this module keeps the seeds,
the files, the manifest and the process pool.

A :class:`~edeflare.data.recipe.Mix` (``eflare-mix``) is a dataset of datasets:
:func:`generate_mix` builds each part into ``OUT/<part>/`` as above (its own
files and manifest, byte for byte what ``generate_dataset(part, OUT/<part>)``
writes) with one process pool for all of them, and writes ``OUT/manifest.json``
(:data:`MIX_FORMAT`: the parts, their recipes' digests and, once complete,
their manifests' digests); ``generate_dataset`` hands a mix to it.

Runs are parallel (a ``spawn`` process pool; numba and ``fork`` do not mix),
sharded (``shard=(i, n)`` makes the sequences with ``index % n == i``, for array
jobs; the run that finds every file present writes ``manifest.json``, the
others ``manifest.shard-i-of-n.json``), and resumable (files are written
atomically and existing ones skipped, so a killed run loses only the
sequences in flight).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from .._interrupt import check_interrupt, interruptible, sigint_blocked
from .._parallel import init_worker as _init_worker
from .._parallel import parse_shard as _parse_shard
from .._parallel import stop_workers as _stop_workers
from .._version import __version__
from ..errors import EventFileError, ParameterError
from ..events import SensorSize
from ..io._atomic import atomic_path
from ..io.sequence import GROUPS as FILE_GROUPS
from ..io.sequence import file_sha256, sequence_counts
from ..io.sequence import write_sequence as write_file
from ..sim.background import BackgroundSource
from ..sim.compose import Components
from ..sim.optics_scene import OpticsScene
from ..sim.script import FlareScript
from .dsec_flare import DsecWindow
from .eflare import SequenceInputs, draw_inputs
from .folders import MIX_FORMAT
from .kinds import STAGES, GenerationError, get_kind
from .recipe import KINDS, RECIPES, WEIGHTS, FlareConfig, Mix, Recipe, list_recipes
from .sources import cached_source, check_index, make_background_source

__all__ = [
    "GROUPS",
    "KINDS",
    "MIX_FORMAT",
    "RECIPES",
    "STAGES",
    "WEIGHTS",
    "FlareConfig",
    "GenerationError",
    "GenerationReport",
    "Mix",
    "Recipe",
    "SequenceData",
    "SequenceInputs",
    "draw_inputs",
    "generate_dataset",
    "generate_mix",
    "generate_sequence",
    "list_recipes",
    "make_background_source",
    "sequence_path",
    "write_sequence",
]

_FORMAT = "edeflare-dataset/1"


def sequence_path(out: str | os.PathLike[str], recipe: Recipe, index: int) -> Path:
    """Where sequence ``index`` lives: ``out/<split>/seq_<index:05d>.h5``."""
    return Path(out) / recipe.split_of(index) / f"seq_{index:05d}.h5"


@dataclass(frozen=True)
class SequenceData:
    """One generated sequence in memory.

    Attributes
    ----------
    index : int
    streams : dict
        ``{"input", "gt", "flare", "light", "background"} -> events`` (kind
        ``"optics"``: input and gt; ``"dsec"``: input).
    components : Components or None
        The pure streams and their intensities at each other's events, as
        weighted by the recipe (to recompose with other variants or draws);
        None for the other kinds.
    script : FlareScript, OpticsScene or DsecWindow
    background : dict
        The background's provenance.
    sensor_size : (width, height)
    t_start_us, t_end_us : int
    timings : dict
        Seconds per stage (:data:`STAGES`).
    frames : (times_us, images) or None
        The clean scene's images at the windows' ends (kind ``"optics"``).
    """

    index: int
    streams: dict[str, np.ndarray]
    components: Components | None
    script: FlareScript | OpticsScene | DsecWindow
    background: dict[str, Any]
    sensor_size: SensorSize
    t_start_us: int
    t_end_us: int
    timings: dict[str, float]
    frames: tuple[np.ndarray, np.ndarray] | None = None


GROUPS = tuple(g for g in FILE_GROUPS if g != "gt_full")
"""The streams of every generated sequence (sparse sensing adds ``gt_full``)."""


def generate_sequence(
    recipe: Recipe, index: int, *, source: BackgroundSource | None = None
) -> SequenceData:
    """Simulate sequence ``index`` of ``recipe`` (a pure function of both).

    Parameters
    ----------
    recipe : Recipe
    index : int
        In ``[0, recipe.sequences)``.
    source : BackgroundSource, optional
        Reuse an opened source (default: the recipe's, cached per process).

    Examples
    --------
    >>> from edeflare.sim.background import SceneConfig
    >>> r = Recipe(sequences=2, test_sequences=1, sensor_size=(32, 24), duration_us=20_000,
    ...            scene=SceneConfig(fps=1000.0))
    >>> a, b = generate_sequence(r, 1), generate_sequence(r, 1)
    >>> all(np.array_equal(a.streams[k], b.streams[k]) for k in GROUPS)
    True
    >>> sorted(a.streams) == sorted(GROUPS), a.t_end_us
    (True, 20000)
    """
    index = check_index(recipe, index)
    made = get_kind(recipe.kind).make_sequence(recipe, index, source)
    timings = dict.fromkeys(STAGES, 0.0) | made.seconds
    return SequenceData(
        index,
        made.streams,
        made.components,
        made.provenance,
        made.background,
        recipe.sensor_size,
        0,
        recipe.duration_us,
        timings,
        made.frames,
    )


def write_sequence(
    path: str | os.PathLike[str], data: SequenceData, recipe: Recipe
) -> dict[str, Any]:
    """Write one sequence file atomically; return its manifest entry (counts, size, SHA-256)."""
    path = Path(path)
    kind = get_kind(recipe.kind)
    groups = (kind.file_groups(recipe) if kind.file_groups else None) or FILE_GROUPS
    groups = tuple(g for g in groups if g in data.streams)  # gt_full: sparse sensing only
    attrs = {
        "t_start_us": np.int64(data.t_start_us),
        "t_end_us": np.int64(data.t_end_us),
        "script": data.script.to_json(),
        "background": json.dumps(data.background, sort_keys=True),
        "recipe": recipe.name,
        "recipe_sha256": recipe.sha256(),
        "index": np.int64(data.index),
        "seed": json.dumps([recipe.seed, data.index]),
    }
    # attribute order as before kinds existed (HDF5 keeps it: files stay byte-identical)
    if kind.file_attrs is not None:  # the flare kind: its composition variant
        attrs |= kind.file_attrs(recipe)
    attrs["edeflare_version"] = __version__
    if kind.file_attrs is None:  # no composition variant; say what the file is instead
        attrs["kind"] = recipe.kind
    write_file(path, {g: data.streams[g] for g in groups}, data.sensor_size, attrs, data.frames)
    return _entry(path, recipe, data.index)


def _entry(path: Path, recipe: Recipe, index: int) -> dict[str, Any]:
    """The manifest entry of an existing file (checked to belong to ``recipe``)."""
    try:
        counts, attrs = sequence_counts(path)
        stored = attrs.get("recipe_sha256")
        if isinstance(stored, bytes):
            stored = stored.decode()
    except (OSError, KeyError) as exc:
        raise EventFileError(path, f"is not a readable sequence file ({exc}); delete it") from None
    if stored != recipe.sha256():
        raise GenerationError(
            f"{path} was made by another recipe; generate into an empty folder "
            "or delete the old files"
        )
    return {
        "index": int(index),
        "split": recipe.split_of(index),
        "file": f"{recipe.split_of(index)}/{path.name}",
        "seed": [recipe.seed, int(index)],
        "events": counts,
        "bytes": path.stat().st_size,
        "sha256": file_sha256(path),
    }


def _splits(recipe: Recipe) -> dict[str, dict[str, int]]:
    splits: dict[str, dict[str, int]] = {}
    for split in ("train", "test"):
        n = sum(1 for i in range(recipe.sequences) if recipe.split_of(i) == split)
        splits[split] = {"sequences": n, "windows": n * recipe.windows_per_sequence}
    return splits


def _manifest(recipe: Recipe, entries: Mapping[int, dict[str, Any]]) -> dict[str, Any]:
    return {
        "format": _FORMAT,
        "edeflare_version": __version__,
        "recipe": recipe.identity(),
        "seed": recipe.seed,
        "seed_rule": "numpy.random.SeedSequence([seed, index])",
        "sequences": recipe.sequences,
        "splits": _splits(recipe),
        "complete": len(entries) == recipe.sequences,
        "files": [entries[i] for i in sorted(entries)],
    }


def _write_json(path: Path, payload: dict[str, Any]) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(payload, indent=1, sort_keys=True) + "\n")


# ----------------------------------------------------------------------------- workers


def _work(recipe: Recipe, index: int, out: str) -> tuple[dict[str, Any], dict[str, float]]:
    data = generate_sequence(recipe, index)
    t0 = time.perf_counter()
    entry = write_sequence(sequence_path(out, recipe, index), data, recipe)
    timings = dict(data.timings)
    timings["write"] += time.perf_counter() - t0
    return entry, timings


@dataclass(frozen=True)
class GenerationReport:
    """What :func:`generate_dataset` did.

    Attributes
    ----------
    manifest : dict
        The manifest written (``complete`` tells whether every sequence exists).
    manifest_path : Path
    generated, skipped : int
        Sequences made in this run, and found complete.
    stage_seconds : dict
        Summed per-stage seconds of the sequences made (:data:`STAGES`).
    wall_seconds : float
    """

    manifest: dict[str, Any]
    manifest_path: Path
    generated: int
    skipped: int
    stage_seconds: dict[str, float]
    wall_seconds: float


def generate_dataset(
    recipe: Recipe | Mix,
    out: str | os.PathLike[str],
    *,
    workers: int = 1,
    shard: tuple[int, int] | str = (0, 1),
    progress: bool = True,
    on_sequence: Callable[[int, dict[str, float]], None] | None = None,
) -> GenerationReport:
    """Generate (or resume) a dataset into ``out`` (see the module docstring).

    Parameters
    ----------
    recipe : Recipe or Mix
        A :class:`~edeflare.data.recipe.Mix` builds each part into ``out/<part>/``
        and writes ``out/manifest.json`` listing them (:func:`generate_mix`).
    out : path-like
        Dataset folder (created).
    workers : int
        Processes (1: in this process).
    shard : (i, n) or "i/n"
        Make only the sequences with ``index % n == i`` (a mix: its items with
        ``position % n == i`` in the mix's order).
    progress : bool
        Show a progress bar with an ETA on stderr.
    on_sequence : callable, optional
        Called with ``(index, stage_seconds)`` as each sequence is written (a
        mix: the sequence's position in the mix's order).

    Returns
    -------
    GenerationReport

    Examples
    --------
    >>> import tempfile
    >>> from edeflare.sim.background import SceneConfig
    >>> r = Recipe(sequences=2, test_sequences=1, sensor_size=(32, 24), duration_us=20_000,
    ...            scene=SceneConfig(fps=1000.0))
    >>> report = generate_dataset(r, tempfile.mkdtemp(), progress=False)
    >>> report.generated, report.manifest["complete"], [f["file"] for f in report.manifest["files"]]
    (2, True, ['train/seq_00000.h5', 'test/seq_00001.h5'])
    """
    if isinstance(recipe, Mix):
        return generate_mix(
            recipe, out, workers=workers, shard=shard, progress=progress, on_sequence=on_sequence
        )
    if not isinstance(recipe, Recipe):
        raise ParameterError(f"recipe must be a Recipe or a Mix, got {type(recipe).__name__}")
    _check_workers(workers)
    shard = _parse_shard(shard)
    start = time.perf_counter()
    run = _DatasetRun(recipe, Path(out), shard)
    run.check_inputs()
    report_to = None
    if on_sequence is not None:
        report_to = lambda _, i, t: on_sequence(i, t)  # noqa: E731
    _make([run], workers, progress, recipe.name, report_to)
    manifest, target = run.finish()
    return GenerationReport(
        manifest,
        target,
        len(run.todo),
        run.skipped,
        run.stage_seconds,
        time.perf_counter() - start,
    )


def generate_mix(
    mix: Mix,
    out: str | os.PathLike[str],
    *,
    workers: int = 1,
    shard: tuple[int, int] | str = (0, 1),
    progress: bool = True,
    on_sequence: Callable[[int, dict[str, float]], None] | None = None,
) -> GenerationReport:
    """Generate (or resume) a :class:`~edeflare.data.recipe.Mix` into ``out``.

    Part ``p`` becomes the dataset ``out/<p>/``, exactly as
    ``generate_dataset(mix.part(p), out / p)`` makes it (its files, its
    ``manifest.json``); one process pool makes every part's sequences, in
    the mix's order. ``out/manifest.json`` (:data:`MIX_FORMAT`) lists the
    parts: folder, recipe name and digest, counts, whether complete, and the
    SHA-256 of the part's manifest once complete (which lists every file's),
    so a complete mix is pinned to its bytes. It holds nothing that depends on
    timing, so a resumed run ends with the same bytes as an uninterrupted one.
    A shard (``shard=(i, n)``: the items at positions ``i, i + n, ...`` of the
    mix's order) writes ``out/manifest.shard-i-of-n.json`` unless it finds
    every part complete. Parameters and result as :func:`generate_dataset`.

    Examples
    --------
    >>> import tempfile
    >>> from edeflare.sim.background import SceneConfig
    >>> r = Recipe(sequences=2, test_sequences=1, sensor_size=(32, 24), duration_us=20_000,
    ...            scene=SceneConfig(fps=1000.0))
    >>> mix = Mix("two", (("a", r), ("b", r.replace(seed=1))))
    >>> report = generate_mix(mix, tempfile.mkdtemp(), progress=False)
    >>> m = report.manifest
    >>> report.generated, m["complete"], [p["folder"] for p in m["parts"]]
    (4, True, ['a', 'b'])
    """
    if not isinstance(mix, Mix):
        raise ParameterError(f"mix must be a Mix, got {type(mix).__name__}")
    _check_workers(workers)
    shard = _parse_shard(shard)
    start = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    manifest_path = out / "manifest.json"
    _check_existing_mix(manifest_path, mix)
    own_path = manifest_path if shard[1] == 1 else out / _shard_manifest_name(shard)
    runs = [_DatasetRun(r, out / p, mix.shard_of(p, shard)) for p, r in mix.parts]
    _write_json(own_path, _mix_manifest(mix, out))  # names the parts while they are made
    for run in runs:
        run.check_inputs()
    offsets = [mix.offset(p) for p in mix.part_names]
    report_to = None
    if on_sequence is not None:
        report_to = lambda k, i, t: on_sequence(offsets[k] + i, t)  # noqa: E731
    _make(runs, workers, progress, mix.name, report_to)
    for run in runs:
        run.finish()
    manifest = _mix_manifest(mix, out)
    target = manifest_path if manifest["complete"] else own_path
    _write_json(target, manifest)
    stage_seconds = {k: sum(run.stage_seconds[k] for run in runs) for k in STAGES}
    return GenerationReport(
        manifest,
        target,
        sum(len(run.todo) for run in runs),
        sum(run.skipped for run in runs),
        stage_seconds,
        time.perf_counter() - start,
    )


def _check_workers(workers: int) -> None:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an int >= 1, got {workers!r}")


def _shard_manifest_name(shard: tuple[int, int]) -> str:
    return f"manifest.shard-{shard[0]}-of-{shard[1]}.json"


class _DatasetRun:
    """One dataset's share of a run: the files there, the sequences to make, its manifest.

    Made in the run's process: finds the files of its shard already written
    (checked to be the recipe's), deletes the temporaries a killed run left
    and lists the rest to make. :meth:`add` records each sequence written
    (keeping the shard's manifest current); :meth:`finish` writes the final one.
    """

    def __init__(self, recipe: Recipe, out: Path, shard: tuple[int, int]) -> None:
        self.recipe, self.out = recipe, out
        self.shard_n = shard[1]
        out.mkdir(parents=True, exist_ok=True)
        self.manifest_path = out / "manifest.json"
        _check_existing_manifest(self.manifest_path, recipe)
        mine = [i for i in range(recipe.sequences) if i % shard[1] == shard[0]]
        for i in mine:  # temporary files of a killed run of this shard
            path = sequence_path(out, recipe, i)
            for stale in path.parent.glob(f".{path.name}.*.partial.h5"):
                stale.unlink(missing_ok=True)
        self.entries: dict[int, dict[str, Any]] = {}
        self.todo: list[int] = []
        for i in mine:
            path = sequence_path(out, recipe, i)
            if path.is_file():
                self.entries[i] = _entry(path, recipe, i)
            else:
                self.todo.append(i)
        self.mine = len(mine)
        self.skipped = len(self.entries)
        self.own_path = self.manifest_path if shard[1] == 1 else out / _shard_manifest_name(shard)
        self.stage_seconds = dict.fromkeys(STAGES, 0.0)
        self._last_write = 0.0

    def check_inputs(self) -> None:
        """Find the kind's inputs (DSEC files, background files) now: errors surface early."""
        if self.todo:
            (get_kind(self.recipe.kind).check or cached_source)(self.recipe)

    def add(self, index: int, entry: dict[str, Any], timings: dict[str, float]) -> None:
        """Record sequence ``index`` as written."""
        self.entries[index] = entry
        for k in STAGES:
            self.stage_seconds[k] += timings.get(k, 0.0)
        now = time.perf_counter()
        if now - self._last_write > 2.0:  # keep the manifest current without rewriting it per file
            _write_json(self.own_path, _manifest(self.recipe, self.entries))
            self._last_write = now

    def finish(self) -> tuple[dict[str, Any], Path]:
        """Write the final manifest: ``manifest.json`` if every file is there (any shard's)."""
        final_entries = dict(self.entries)
        recipe, out = self.recipe, self.out
        if self.shard_n > 1:  # other shards' files, if they are all there
            for i in range(recipe.sequences):
                if i not in final_entries and sequence_path(out, recipe, i).is_file():
                    final_entries[i] = _entry(sequence_path(out, recipe, i), recipe, i)
        manifest = _manifest(recipe, final_entries)
        target = self.manifest_path if manifest["complete"] else self.own_path
        if not manifest["complete"]:
            manifest = _manifest(recipe, self.entries)
        _write_json(target, manifest)
        return manifest, target


def _make(
    runs: Sequence[_DatasetRun],
    workers: int,
    progress: bool,
    name: str,
    on_sequence: Callable[..., None] | None,
) -> None:
    """Make every run's sequences, in order, in this process or in one pool.

    ``on_sequence(k, index, timings)`` is told of sequence ``index`` of ``runs[k]``.
    """
    items = [(k, i) for k, run in enumerate(runs) for i in run.todo]
    bar = _progress(sum(r.mine for r in runs), sum(r.skipped for r in runs), name, progress)

    def finished(item: tuple[int, int], entry: dict[str, Any], timings: dict[str, float]) -> None:
        k, index = item
        runs[k].add(index, entry, timings)
        bar.update(1)
        if on_sequence is not None:
            on_sequence(k, index, timings)

    try:
        with interruptible():  # Ctrl-C stops the run even if a finaliser swallows it
            if workers == 1 or len(items) <= 1:
                for k, i in items:
                    check_interrupt()
                    entry, timings = _work(runs[k].recipe, i, str(runs[k].out))
                    finished((k, i), entry, timings)
            else:
                tasks = [(runs[k].recipe, i, str(runs[k].out)) for k, i in items]
                _run_pool(tasks, workers, lambda n, e, t: finished(items[n], e, t))
    finally:
        bar.close()


def _mix_manifest(mix: Mix, out: Path) -> dict[str, Any]:
    """The mix's manifest from what its part folders hold now."""
    parts = []
    for name, recipe in mix.parts:
        folder = out / name
        done = sum(1 for i in range(recipe.sequences) if sequence_path(folder, recipe, i).is_file())
        manifest_sha256 = None
        path = folder / "manifest.json"
        if done == recipe.sequences and path.is_file():
            try:
                complete = json.loads(path.read_text()).get("complete") is True
            except (OSError, ValueError, AttributeError):
                complete = False
            if complete:
                manifest_sha256 = file_sha256(path)
        parts.append(
            {
                "name": name,
                "folder": name,
                "recipe": recipe.name,
                "recipe_sha256": recipe.sha256(),
                "sensor_size": list(recipe.sensor_size),
                "sequences": recipe.sequences,
                "splits": _splits(recipe),
                "done": done,
                "complete": manifest_sha256 is not None,
                "manifest_sha256": manifest_sha256,
            }
        )
    splits = {
        split: {k: sum(p["splits"][split][k] for p in parts) for k in ("sequences", "windows")}
        for split in ("train", "test")
    }
    return {
        "format": MIX_FORMAT,
        "edeflare_version": __version__,
        "name": mix.name,
        "mix_sha256": mix.sha256(),
        "sequences": mix.sequences,
        "splits": splits,
        "done": sum(p["done"] for p in parts),
        "complete": all(p["complete"] for p in parts),
        "parts": parts,
    }


def _check_existing_mix(path: Path, mix: Mix) -> None:
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text())
        kind, digest = old.get("format"), old.get("mix_sha256")
    except (OSError, ValueError, AttributeError):
        raise EventFileError(path, "is not a mix manifest; use an empty folder") from None
    if kind != MIX_FORMAT:
        raise GenerationError(
            f"{path.parent} holds a dataset, not a mix; generate the mix into an empty folder"
        )
    if digest != mix.sha256():
        raise GenerationError(
            f"{path.parent} holds another mix ({old.get('name')!r}, other parts or "
            "settings); generate into an empty folder"
        )


def _check_existing_manifest(path: Path, recipe: Recipe) -> None:
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text())
        mix = old.get("format") == MIX_FORMAT
        old_recipe = None if mix else old["recipe"]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        raise EventFileError(path, "is not a dataset manifest; use an empty folder") from None
    if mix:
        raise GenerationError(
            f"{path.parent} holds a mix ({old.get('name')!r}); generate into an empty folder"
        )
    if old_recipe != recipe.identity():
        raise GenerationError(
            f"{path.parent} holds a dataset of another recipe ({old_recipe.get('name')!r}, "
            "different settings); generate into an empty folder"
        )


def _run_pool(
    tasks: Sequence[tuple[Recipe, int, str]],
    workers: int,
    finished: Callable[[int, dict[str, Any], dict[str, float]], None],
) -> None:
    """Run ``_work(*task)`` for every task in a pool; ``finished(position, entry, timings)``."""
    threads = max(1, (os.cpu_count() or 1) // workers)
    ctx = get_context("spawn")
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(os.getpid(), threads),
    ) as pool:
        pending: dict[Future[Any], int] = {}
        queue = list(range(len(tasks)))
        try:
            while queue or pending:
                while queue and len(pending) < 2 * workers:  # bounded: cancel stays quick
                    n = queue.pop(0)
                    with sigint_blocked():  # a worker started here starts deaf to Ctrl-C
                        pending[pool.submit(_work, *tasks[n])] = n
                done, _ = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
                check_interrupt()
                for fut in sorted(done, key=lambda f: pending[f]):
                    n = pending.pop(fut)
                    entry, timings = fut.result()
                    finished(n, entry, timings)
        except Exception:
            for fut in pending:
                fut.cancel()
            raise
        except BaseException:  # Ctrl-C: the sequences in flight stop too
            _stop_workers(pool)  # (their futures fail with the pool; none is cancelled first,
            raise  # which the pool's own clean-up would trip over)


def _progress(total: int, initial: int, name: str, enabled: bool) -> Any:
    from .._progress import progress_bar  # no bar when stderr is not a terminal (logs, nohup)

    return progress_bar(
        total=total, initial=initial, enabled=enabled, desc=name, unit="seq", dynamic_ncols=True
    )
