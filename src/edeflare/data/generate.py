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
from .kinds import STAGES, GenerationError, get_kind
from .recipe import KINDS, RECIPES, WEIGHTS, FlareConfig, Recipe, list_recipes
from .sources import cached_source, check_index, make_background_source

__all__ = [
    "GROUPS",
    "KINDS",
    "RECIPES",
    "STAGES",
    "WEIGHTS",
    "FlareConfig",
    "GenerationError",
    "GenerationReport",
    "Recipe",
    "SequenceData",
    "SequenceInputs",
    "draw_inputs",
    "generate_dataset",
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


def _manifest(recipe: Recipe, entries: Mapping[int, dict[str, Any]]) -> dict[str, Any]:
    splits: dict[str, dict[str, int]] = {}
    for split in ("train", "test"):
        n = sum(1 for i in range(recipe.sequences) if recipe.split_of(i) == split)
        splits[split] = {"sequences": n, "windows": n * recipe.windows_per_sequence}
    return {
        "format": _FORMAT,
        "edeflare_version": __version__,
        "recipe": recipe.identity(),
        "seed": recipe.seed,
        "seed_rule": "numpy.random.SeedSequence([seed, index])",
        "sequences": recipe.sequences,
        "splits": splits,
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
    recipe: Recipe,
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
    recipe : Recipe
    out : path-like
        Dataset folder (created).
    workers : int
        Processes (1: in this process).
    shard : (i, n) or "i/n"
        Make only the sequences with ``index % n == i``.
    progress : bool
        Show a progress bar with an ETA on stderr.
    on_sequence : callable, optional
        Called with ``(index, stage_seconds)`` as each sequence is written.

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
    if not isinstance(recipe, Recipe):
        raise ParameterError(f"recipe must be a Recipe, got {type(recipe).__name__}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an int >= 1, got {workers!r}")
    shard_i, shard_n = _parse_shard(shard)
    out = Path(out)
    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    manifest_path = out / "manifest.json"
    _check_existing_manifest(manifest_path, recipe)
    mine = [i for i in range(recipe.sequences) if i % shard_n == shard_i]
    for i in mine:  # temporary files of a killed run of this shard
        path = sequence_path(out, recipe, i)
        for stale in path.parent.glob(f".{path.name}.*.partial.h5"):
            stale.unlink(missing_ok=True)
    entries: dict[int, dict[str, Any]] = {}
    todo = []
    for i in mine:
        path = sequence_path(out, recipe, i)
        if path.is_file():
            entries[i] = _entry(path, recipe, i)
        else:
            todo.append(i)
    skipped = len(entries)
    own_path = (
        manifest_path if shard_n == 1 else out / f"manifest.shard-{shard_i}-of-{shard_n}.json"
    )
    if todo:  # find the kind's inputs (DSEC files, background files) here: errors surface early
        (get_kind(recipe.kind).check or cached_source)(recipe)
    stage_seconds = dict.fromkeys(STAGES, 0.0)
    bar = _progress(len(mine), skipped, recipe.name, progress)
    last_write = 0.0

    def finished(index: int, entry: dict[str, Any], timings: dict[str, float]) -> None:
        nonlocal last_write
        entries[index] = entry
        for k in STAGES:
            stage_seconds[k] += timings.get(k, 0.0)
        bar.update(1)
        if on_sequence is not None:
            on_sequence(index, timings)
        now = time.perf_counter()
        if now - last_write > 2.0:  # keep the manifest current without rewriting it per file
            _write_json(own_path, _manifest(recipe, entries))
            last_write = now

    try:
        with interruptible():  # Ctrl-C stops the run even if a finaliser swallows it
            if workers == 1 or len(todo) <= 1:
                for i in todo:
                    check_interrupt()
                    entry, timings = _work(recipe, i, str(out))
                    finished(i, entry, timings)
            else:
                _run_pool(recipe, todo, out, workers, finished)
    finally:
        bar.close()
    final_entries = dict(entries)
    if shard_n > 1:  # other shards' files, if they are all there
        for i in range(recipe.sequences):
            if i not in final_entries and sequence_path(out, recipe, i).is_file():
                final_entries[i] = _entry(sequence_path(out, recipe, i), recipe, i)
    manifest = _manifest(recipe, final_entries)
    target = manifest_path if manifest["complete"] else own_path
    if not manifest["complete"]:
        manifest = _manifest(recipe, entries)
    _write_json(target, manifest)
    return GenerationReport(
        manifest, target, len(todo), skipped, stage_seconds, time.perf_counter() - start
    )


def _check_existing_manifest(path: Path, recipe: Recipe) -> None:
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text())
        old_recipe = old["recipe"]
    except (OSError, ValueError, KeyError, TypeError):
        raise EventFileError(path, "is not a dataset manifest; use an empty folder") from None
    if old_recipe != recipe.identity():
        raise GenerationError(
            f"{path.parent} holds a dataset of another recipe ({old_recipe.get('name')!r}, "
            "different settings); generate into an empty folder"
        )


def _run_pool(
    recipe: Recipe,
    todo: Sequence[int],
    out: Path,
    workers: int,
    finished: Callable[[int, dict[str, Any], dict[str, float]], None],
) -> None:
    threads = max(1, (os.cpu_count() or 1) // workers)
    ctx = get_context("spawn")
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(os.getpid(), threads),
    ) as pool:
        pending: dict[Future[Any], int] = {}
        queue = list(todo)
        try:
            while queue or pending:
                while queue and len(pending) < 2 * workers:  # bounded: cancel stays quick
                    i = queue.pop(0)
                    with sigint_blocked():  # a worker started here starts deaf to Ctrl-C
                        pending[pool.submit(_work, recipe, i, str(out))] = i
                done, _ = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
                check_interrupt()
                for fut in sorted(done, key=lambda f: pending[f]):
                    i = pending.pop(fut)
                    entry, timings = fut.result()
                    finished(i, entry, timings)
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
