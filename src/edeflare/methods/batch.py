"""Batch de-flaring: every file of a folder or glob, one output each; parallel, sharded, resumable.

:func:`deflare_files` runs :func:`~edeflare.methods.streaming.deflare_file`
over many files, so each output equals a one-file run, event for event.

Inputs and outputs
    ``inputs`` is a folder, a glob pattern (``"drives/**/*.raw"``: ``**``
    recurses), a file, or a list of these. A folder contributes every file
    under it with a binary event suffix (``.h5``, ``.hdf5``, ``.raw``,
    ``.dat``, ``.aedat4``, ``.es``, ``.npz``); text files (``.csv``,
    ``.txt``), often notes or timestamps, are taken only when a glob or a name
    picks them; hidden files and the output folder are left out. The files are
    sorted by their path relative to the inputs' root (the folder, the
    pattern's fixed part, or the common folder of a list), and each output
    mirrors that path under ``out_dir`` with the suffix ``suffix`` (``.h5``;
    None keeps the input's).

Workers and shards
    ``workers=N`` runs N processes (a ``spawn`` pool; each builds the method
    once and de-flares file after file). ``shard="i/n"`` takes the files whose
    index in the sorted list has ``index % n == i``, as ``edeflare simulate
    --shard`` does: one task of a SLURM array or a Kubernetes indexed job each,
    all writing into the same ``out_dir``.

The manifest
    ``out_dir/manifest.json`` (a shard's own: ``manifest.shard-i-of-n.json``)
    describes each complete output: the input (path, size, modification time,
    SHA-256), the method (name, every parameter, the model's weights by their
    SHA-256), the run options that shape the output (window, seed, max lag,
    EVT version, group, sensor size), the output (size, modification time,
    SHA-256), the event counts and edeflare's version. It holds no timings.
    It is rewritten atomically at most every 2 s and at the end; the run of a
    shard that finds every file of every shard complete also writes
    ``manifest.json``.

Resuming
    A rerun skips a file when an entry records the same method, parameters and
    options, the same input bytes and an output still as it was written; any
    other file is de-flared again (the output replaced atomically). Files are
    compared by their SHA-256: a copy of the dataset elsewhere (new paths,
    new times) still matches, and a changed byte anywhere does not. Reading
    every file again on each rerun would cost as much as reading the dataset,
    so size and modification time (in ns) serve as a cache, as in git's index:
    a file whose both are as recorded is taken to be unchanged, any other is
    hashed and compared. A run killed at any moment (SIGKILL) leaves complete
    outputs or none (they are written atomically) and a manifest that lists
    only complete outputs (an output written after the manifest's last write
    is redone on the rerun: the same bytes).

Failures
    A file that cannot be de-flared (corrupt, unknown format) is reported in
    the result with the problem, and the others go on.

Examples
--------
>>> import tempfile, pathlib
>>> from edeflare.events import make_events
>>> from edeflare.io import write_events
>>> root = pathlib.Path(tempfile.mkdtemp())
>>> ev = make_events([0, 100, 40_000], [1, 2, 3], [1, 1, 1], [1, 0, 1])
>>> for name in ("day/a.h5", "night/b.h5"):
...     write_events(root / "rec" / name, ev, (8, 8))
>>> report = deflare_files(root / "rec", root / "clean", "raw", progress=False)
>>> [(r.name, r.status, r.events_out) for r in report.files]
[('day/a.h5', 'done', 3), ('night/b.h5', 'done', 3)]
>>> [r.status for r in deflare_files(root / "rec", root / "clean", "raw", progress=False).files]
['skipped', 'skipped']
"""

from __future__ import annotations

import dataclasses
import glob
import json
import os
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from multiprocessing import get_context
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from .._interrupt import check_interrupt, interruptible, sigint_blocked
from .._parallel import init_worker, parse_shard, stop_workers
from .._progress import progress_bar
from .._version import __version__
from ..errors import EdeflareError, EventFileError, ParameterError
from ..events import SensorSize
from ..io import list_formats
from ..io._atomic import atomic_path, remove_stale_temporaries
from ..io.sequence import file_sha256
from .base import Method, create_method
from .streaming import deflare_file

__all__ = ["MANIFEST", "BatchReport", "FileResult", "deflare_files"]

MANIFEST = "manifest.json"
"""The manifest's name in the output folder (a shard writes ``manifest.shard-i-of-n.json``)."""

_FORMAT = "edeflare-deflare/1"
_TEXT_SUFFIXES = (".csv", ".txt")  # taken from a folder only when named or globbed
_WRITE_EVERY_S = 2.0
PathLike = str | os.PathLike[str]


# ----------------------------------------------------------------------------- results


@dataclasses.dataclass(frozen=True)
class FileResult:
    """What :func:`deflare_files` did with one input file.

    Attributes
    ----------
    name : str
        The output's path relative to the output folder (``/`` separated): the
        input's relative path with the output suffix.
    input, output : Path
    status : {"done", "skipped", "failed"}
        De-flared now, found complete (same input, method and options), or failed.
    events_in, events_out : int or None
        None for a failed file.
    seconds : float
        Wall time spent on the file (0 for a skipped one); not part of equality.
    error : str or None
        A failed file's problem, naming the file.
    """

    name: str
    input: Path
    output: Path
    status: str
    events_in: int | None = None
    events_out: int | None = None
    seconds: float = dataclasses.field(default=0.0, compare=False)
    error: str | None = None


@dataclasses.dataclass(frozen=True)
class BatchReport:
    """What :func:`deflare_files` did.

    Attributes
    ----------
    files : tuple of FileResult
        This run's files (its shard's), sorted by name.
    out_dir : Path
    manifest_path : Path
        The manifest this run wrote (``manifest.json``, or its shard's).
    complete : bool
        Whether every input of every shard has a complete output recorded.
    seconds : float
        Wall time of the run; not part of equality.
    """

    files: tuple[FileResult, ...]
    out_dir: Path
    manifest_path: Path
    complete: bool
    seconds: float = dataclasses.field(default=0.0, compare=False)

    def _with(self, status: str) -> list[FileResult]:
        return [r for r in self.files if r.status == status]

    @property
    def done(self) -> list[FileResult]:
        """The files de-flared by this run."""
        return self._with("done")

    @property
    def skipped(self) -> list[FileResult]:
        """The files found complete."""
        return self._with("skipped")

    @property
    def failed(self) -> list[FileResult]:
        """The files that failed (see their ``error``)."""
        return self._with("failed")

    def table(self) -> str:
        """A Markdown table: file, events in, events out, seconds, status.

        Examples
        --------
        >>> r = FileResult("a.h5", Path("in/a.h5"), Path("out/a.h5"), "done", 1200, 900, 0.5)
        >>> print(BatchReport((r,), Path("out"), Path("out/manifest.json"), True).table())
        | file | events in | events out | seconds | status |
        |---|---:|---:|---:|---|
        | a.h5 | 1,200 | 900 | 0.50 | done |
        """
        rows = ["| file | events in | events out | seconds | status |", "|---|---:|---:|---:|---|"]
        for r in self.files:
            n_in = "-" if r.events_in is None else f"{r.events_in:,}"
            n_out = "-" if r.events_out is None else f"{r.events_out:,}"
            secs = "-" if r.status == "skipped" else f"{r.seconds:.2f}"
            rows.append(f"| {r.name} | {n_in} | {n_out} | {secs} | {r.status} |")
        return "\n".join(rows)


# ----------------------------------------------------------------------------- the inputs


@dataclasses.dataclass(frozen=True)
class _Item:
    """One input file and where its output goes."""

    name: str  # the output, relative to out_dir (posix)
    source: str  # the input, relative to the inputs' root (posix)
    input: Path
    output: Path


def _has_magic(text: str) -> bool:
    return any(c in text for c in "*?[")


def _inside(path: str, folder: str | None) -> bool:
    return folder is not None and (path == folder or path.startswith(folder + os.sep))


def _walk(folder: Path, exclude: str | None) -> list[Path]:
    """Event files under ``folder`` (symbolic links followed once), hidden ones left out."""
    binary = tuple(s for s in list_formats() if s not in _TEXT_SUFFIXES)
    found, seen = [], set()
    for here, dirs, files in os.walk(folder, followlinks=True):
        real = os.path.realpath(here)
        if real in seen or _inside(real, exclude):
            dirs[:] = []
            continue
        seen.add(real)
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(files):
            if not name.startswith(".") and Path(name).suffix.lower() in binary:
                found.append(Path(here) / name)
    return found


def _expand(item: PathLike, exclude: str | None) -> tuple[str, list[Path]]:
    """One entry of ``inputs``: its root folder and its files."""
    text = os.fspath(item)
    path = Path(text)
    if path.is_dir():
        if _inside(_real(path), exclude):
            raise ParameterError(
                f"the input folder {text} lies in the output folder; write into another folder"
            )
        return os.path.abspath(path), _walk(path, exclude)
    if path.is_file():
        return os.path.abspath(path.parent), [path]
    if _has_magic(text):
        matches = sorted(glob.glob(text, recursive=True))
        files = [Path(m) for m in matches if Path(m).is_file() and not _inside(_real(m), exclude)]
        if not files:
            raise EventFileError(text, "no file matches this pattern")
        fixed = []
        for part in path.parts:
            if _has_magic(part):
                break
            fixed.append(part)
        return os.path.abspath(Path(*fixed) if fixed else Path(".")), files
    raise EventFileError(text, "no such file or folder")


def _real(path: PathLike) -> str:
    return os.path.realpath(path)


def _find_inputs(inputs: PathLike | Sequence[PathLike], out_dir: Path) -> list[tuple[Path, str]]:
    """``(file, path relative to the inputs' root)`` of every input file, sorted, unique."""
    items = [inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs)
    if not items:
        raise ParameterError("inputs is empty: give a folder, a glob pattern or files")
    exclude = _real(out_dir)
    expanded = [_expand(item, exclude) for item in items]
    root = os.path.commonpath([r for r, _ in expanded])
    found: dict[str, tuple[Path, str]] = {}
    for _, files in expanded:
        for f in files:
            key = os.path.abspath(f)
            rel = PurePosixPath(*Path(os.path.relpath(key, root)).parts).as_posix()
            found.setdefault(key, (f, rel))
    return sorted(found.values(), key=lambda pair: pair[1])


def _check_suffix(suffix: str | None) -> str | None:
    if suffix is None:
        return None
    if not isinstance(suffix, str) or not suffix.strip("."):
        raise ParameterError(f"suffix must be a format's suffix such as '.h5', got {suffix!r}")
    suffix = suffix if suffix.startswith(".") else "." + suffix
    if suffix.lower() not in list_formats():
        raise ParameterError(
            f"suffix {suffix!r} names no writable format; use one of {', '.join(list_formats())}"
        )
    return suffix


def _plan(files: list[tuple[Path, str]], out_dir: Path, suffix: str | None) -> list[_Item]:
    """Each input's output (mirroring its relative path); two inputs sharing one is an error."""
    items: list[_Item] = []
    taken: dict[str, Path] = {}
    inputs = {_real(f) for f, _ in files}
    for path, rel in files:
        name = rel if suffix is None else PurePosixPath(rel).with_suffix(suffix).as_posix()
        if name in taken:
            raise ParameterError(
                f"{taken[name]} and {path} would both be written to {out_dir / name}; "
                "keep the inputs' suffixes (suffix=None, --suffix keep) or rename one"
            )
        taken[name] = path
        output = out_dir.joinpath(*PurePosixPath(name).parts)
        if _real(output) in inputs:
            raise ParameterError(
                f"the output {output} would overwrite an input; write into another folder"
            )
        items.append(_Item(name, rel, path, output))
    return items


# ----------------------------------------------------------------------------- identity


def _jsonable(key: str, value: Any) -> Any:
    """A parameter's value as JSON; weights files and arrays by their SHA-256."""
    import hashlib

    if isinstance(value, np.ndarray):
        digest = hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest()
        return {"array_sha256": digest, "dtype": value.dtype.str, "shape": list(value.shape)}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike) or (key == "weights" and isinstance(value, str)):
        path = Path(value)
        if path.is_file():
            return {"file_sha256": file_sha256(path)}  # the same weights wherever they lie
        return os.fspath(value)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_jsonable(key, v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _jsonable(str(k), v) for k, v in value.items()}
    return repr(value)


def _identity(method: Method, options: Mapping[str, Any]) -> dict[str, Any]:
    """What decides an output besides its input: the method, its parameters, the run options."""
    params = {k: _jsonable(k, v) for k, v in sorted(method.params.items())}
    ident = {"name": method.name or type(method).__qualname__, "params": params}
    ident["options"] = {k: _jsonable(k, v) for k, v in sorted(options.items())}
    return json.loads(json.dumps(ident))  # tuples as lists: compares with a read manifest


# ----------------------------------------------------------------------------- the manifest


def _stat(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_size, st.st_mtime_ns


def _recorded(entry: Mapping[str, Any], side: str) -> tuple[int, int] | None:
    try:
        return int(entry[side]["bytes"]), int(entry[side]["mtime_ns"])
    except (KeyError, TypeError, ValueError):
        return None


def _fresh_by_stat(entry: Mapping[str, Any], item: _Item) -> bool:
    """The entry holds for the files as they are, judged by size and time (no reading)."""
    now_in, now_out = _stat(item.input), _stat(item.output)
    return (
        now_in is not None
        and now_out is not None
        and _recorded(entry, "input") == now_in
        and _recorded(entry, "output") == now_out
    )


def _manifest_paths(out_dir: Path) -> list[Path]:
    shards = sorted(out_dir.glob("manifest.shard-*-of-*.json"))
    return [p for p in [out_dir / MANIFEST, *shards] if p.is_file()]


def _load_manifests(out_dir: Path) -> dict[str, list[dict[str, Any]]]:
    """Every entry of the folder's manifests by output name (``manifest.json``'s first)."""
    known: dict[str, list[dict[str, Any]]] = {}
    for path in _manifest_paths(out_dir):
        try:
            data = json.loads(path.read_text())
            kind, files = data["format"], data["files"]
        except (OSError, ValueError, KeyError, TypeError):
            raise EventFileError(
                path, "is not a manifest of edeflare deflare; de-flare into another folder"
            ) from None
        if kind != _FORMAT:
            raise EventFileError(
                path, f"is a manifest of another kind ({kind!r}); de-flare into another folder"
            )
        for entry in files if isinstance(files, list) else []:
            try:
                name = entry["output"]["file"]
            except (KeyError, TypeError):
                continue
            if isinstance(name, str):
                known.setdefault(name, []).append(entry)
    return known


def _best(entries: list[dict[str, Any]], output: Path) -> dict[str, Any] | None:
    """The entry that describes the output file as it is (else the first), if it exists."""
    now = _stat(output)
    if now is None:
        return None
    return next((e for e in entries if _recorded(e, "output") == now), entries[0])


def _manifest(entries: Mapping[str, dict[str, Any]], complete: bool, shard: str | None) -> dict:
    out: dict[str, Any] = {"format": _FORMAT, "complete": complete}
    if shard is not None:
        out["shard"] = shard
    out["files"] = [entries[k] for k in sorted(entries)]
    return out


def _remove_temporaries(outputs: list[Path]) -> None:
    """Delete the temporaries that dead writers left beside ``outputs`` (one listing per folder)."""
    by_folder: dict[Path, list[Path]] = {}
    for output in outputs:
        by_folder.setdefault(output.parent, []).append(output)
    for folder, targets in by_folder.items():
        try:
            temporaries = [e.name for e in os.scandir(folder) if e.name.startswith(".")]
        except OSError:  # not made yet
            continue
        temporaries = [name for name in temporaries if ".partial" in name]
        for target in targets if temporaries else []:
            if any(name.startswith(f".{target.name}.") for name in temporaries):
                remove_stale_temporaries(target)


def _write_json(path: Path, payload: dict[str, Any]) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(payload, indent=1, sort_keys=True) + "\n")


# ----------------------------------------------------------------------------- one file


@dataclasses.dataclass(frozen=True)
class _Task:
    item: _Item
    candidates: tuple[dict[str, Any], ...]  # entries of the same identity, to verify
    identity: dict[str, Any]
    run: dict[str, Any]  # deflare_file's options


@dataclasses.dataclass(frozen=True)
class _Outcome:
    result: FileResult
    entry: dict[str, Any] | None
    warnings: tuple[tuple[type[Warning], str], ...] = ()


def _verify(entry: dict[str, Any], item: _Item, input_sha: Callable[[], str]) -> dict | None:
    """The entry refreshed to the files' times if its input and output are as recorded."""
    in_stat, out_stat = _stat(item.input), _stat(item.output)
    if in_stat is None or out_stat is None:
        return None
    try:
        same_in = in_stat == _recorded(entry, "input") or input_sha() == entry["input"]["sha256"]
        same_out = out_stat == _recorded(entry, "output") or (
            out_stat[0] == entry["output"]["bytes"]
            and file_sha256(item.output) == entry["output"]["sha256"]
        )
    except (KeyError, TypeError):
        return None
    if not (same_in and same_out):
        return None
    fresh = json.loads(json.dumps(entry))
    fresh["input"].update(bytes=in_stat[0], mtime_ns=in_stat[1])
    fresh["output"].update(bytes=out_stat[0], mtime_ns=out_stat[1])
    return fresh


def _problem(exc: BaseException, path: Path) -> str:
    """One line naming the file and what is wrong."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if not isinstance(exc, (EdeflareError, OSError)):
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text if os.fspath(path) in text else f"{path}: {text}"


def _attempt(method: Method, task: _Task) -> tuple[FileResult, dict[str, Any] | None]:
    item, t0 = task.item, time.perf_counter()
    in_stat = _stat(item.input)
    if in_stat is None:
        raise EventFileError(item.input, "cannot be read (it went away)")
    digest: list[str] = []

    def input_sha() -> str:
        if not digest:
            digest.append(file_sha256(item.input))
        return digest[0]

    for entry in task.candidates:  # a copied dataset: same bytes, new times
        fresh = _verify(entry, item, input_sha)
        if fresh is not None:
            counts = fresh.get("events", {})
            result = FileResult(
                item.name, item.input, item.output, "skipped", counts.get("in"), counts.get("out")
            )
            return result, fresh
    sha = input_sha()  # before de-flaring: a file changed meanwhile is redone next time
    stats = deflare_file(item.input, item.output, method, **task.run, progress=False)
    out_stat = _stat(item.output)
    if out_stat is None:
        raise EventFileError(item.output, "went away as soon as it was written")
    entry = {
        "input": {"file": item.source, "bytes": in_stat[0], "mtime_ns": in_stat[1], "sha256": sha},
        "method": task.identity,
        "output": {
            "file": item.name,
            "bytes": out_stat[0],
            "mtime_ns": out_stat[1],
            "sha256": file_sha256(item.output),
        },
        "events": {"in": stats.events_in, "out": stats.events_out, "dropped": stats.late_dropped},
        "edeflare_version": __version__,
    }
    seconds = time.perf_counter() - t0
    result = FileResult(
        item.name, item.input, item.output, "done", stats.events_in, stats.events_out, seconds
    )
    return result, entry


def _run_one(method: Method, task: _Task) -> _Outcome:
    """De-flare (or verify) one file; a failure is a result, not an exception."""
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result, entry = _attempt(method, task)
        except Exception as exc:  # a bad file must not stop the others
            check_interrupt()  # unless it is a Ctrl-C that compiled code wrapped in an error
            item = task.item
            result = FileResult(
                item.name,
                item.input,
                item.output,
                "failed",
                seconds=time.perf_counter() - t0,
                error=_problem(exc, item.input),
            )
            entry = None
    said = tuple((w.category, str(w.message)) for w in caught)
    return _Outcome(result, entry, said)


# ----------------------------------------------------------------------------- workers

_worker_method: Method | None = None


def _init_batch_worker(parent: int, threads: int, spec: Method | tuple[str, dict]) -> None:
    """A pool worker's start: the shared set-up, then the method, built once."""
    global _worker_method
    init_worker(parent, threads)
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # torch reads them when imported
        os.environ.setdefault(var, str(threads))
    import sys

    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)
    _worker_method = spec if isinstance(spec, Method) else create_method(spec[0], **spec[1])


def _work(task: _Task) -> _Outcome:
    if _worker_method is None:  # pragma: no cover - the initializer always runs first
        raise RuntimeError("batch worker used before its initializer")
    return _run_one(_worker_method, task)


def _run_pool(
    spec: Method | tuple[str, dict],
    tasks: Sequence[_Task],
    workers: int,
    finished: Callable[[_Outcome], None],
) -> None:
    threads = max(1, (os.cpu_count() or 1) // workers)
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=get_context("spawn"),
        initializer=_init_batch_worker,
        initargs=(os.getpid(), threads, spec),
    ) as pool:
        pending: dict[Future[_Outcome], int] = {}
        queue = list(enumerate(tasks))
        try:
            while queue or pending:
                while queue and len(pending) < 2 * workers:  # bounded: cancel stays quick
                    k, task = queue.pop(0)
                    with sigint_blocked():  # a worker started here starts deaf to Ctrl-C
                        pending[pool.submit(_work, task)] = k
                done, _ = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
                check_interrupt()
                for fut in sorted(done, key=lambda f: pending[f]):
                    pending.pop(fut)
                    finished(fut.result())
        except Exception:
            for fut in pending:
                fut.cancel()
            raise
        except BaseException:  # Ctrl-C: the files in flight stop too (they stay temporary)
            stop_workers(pool)
            raise


# ----------------------------------------------------------------------------- the run


def _check_run_options(
    window_us: Any, max_lag_us: Any, evt_version: Any, rng: Any, workers: Any
) -> None:
    if isinstance(window_us, bool) or not isinstance(window_us, (int, np.integer)):
        raise ParameterError(f"window_us must be a positive int, got {window_us!r}")
    if window_us <= 0:
        raise ParameterError(f"window_us must be a positive int, got {window_us!r}")
    if max_lag_us is not None and (
        isinstance(max_lag_us, bool)
        or not isinstance(max_lag_us, (int, np.integer))
        or max_lag_us < 0
    ):
        raise ParameterError(f"max_lag_us must be a non-negative int or None, got {max_lag_us!r}")
    if evt_version not in ("evt2", "evt3"):
        raise ParameterError(f"evt_version must be 'evt2' or 'evt3', got {evt_version!r}")
    if rng is not None and (isinstance(rng, bool) or not isinstance(rng, (int, np.integer))):
        raise ParameterError(
            "rng must be an int seed or None here (every file is seeded alike, "
            f"as a one-file run with that seed), got {type(rng).__name__}"
        )
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an int >= 1, got {workers!r}")


def _check_picklable(method: Method) -> None:
    """A method object goes to the workers by pickle (a used model holds a live network)."""
    import pickle

    try:
        pickle.dumps(method)
    except Exception as exc:
        raise ParameterError(
            f"the method object {method!r} cannot be sent to worker processes ({exc}); "
            "pass its name and params instead, or workers=1"
        ) from None


def deflare_files(
    inputs: PathLike | Sequence[PathLike],
    out_dir: PathLike,
    method: str | Method,
    window_us: int = 20_000,
    sensor_size: SensorSize | None = None,
    *,
    params: Mapping[str, Any] | None = None,
    rng: int | None = None,
    max_lag_us: int | None = 10_000_000,
    evt_version: str = "evt2",
    group: str | None = None,
    suffix: str | None = ".h5",
    workers: int = 1,
    shard: tuple[int, int] | str | None = None,
    progress: bool | None = None,
    on_file: Callable[[FileResult], None] | None = None,
) -> BatchReport:
    """De-flare many files into a folder, one output each; parallel, sharded, resumable.

    See the module's description for how inputs are found, outputs named,
    work shared and reruns resumed.

    Parameters
    ----------
    inputs : path-like or sequence of path-like
        A folder, a glob pattern, a file, or a list of these.
    out_dir : path-like
        The output folder (created), mirroring the inputs' subfolders.
    method : str or Method
        A registered name (see :func:`list_methods`) or a method object.
    window_us, sensor_size, params, max_lag_us, evt_version, group
        As for :func:`~edeflare.methods.streaming.deflare_file`, for every file.
    rng : int, optional
        Seed of methods that draw, the same for every file (a generator,
        whose draws would depend on the order of the files, is refused).
    suffix : str or None
        The outputs' format (``".h5"``); None keeps each input's suffix.
    workers : int
        Processes (1: in this process). Each builds the method once.
    shard : (i, n) or "i/n", optional
        De-flare only the files whose index in the sorted list is ``i`` modulo ``n``.
    progress : bool, optional
        False: no progress bar; otherwise one bar over the files, on a terminal only.
    on_file : callable, optional
        Called with each :class:`FileResult` as it is known (skipped files first).

    Returns
    -------
    BatchReport
        One :class:`FileResult` per file of this run (failed ones included).

    Raises
    ------
    ParameterError
        For a bad option, no input files, or two inputs mapped to one output
        (before any file is written).
    EventFileError
        For an input path that does not exist or a pattern that matches
        nothing, or a folder holding another kind of manifest.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io import write_events, read_events
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> ev = make_events([0, 5_000, 30_000], [1, 2, 3], [0, 0, 0], [1, 0, 1])
    >>> for name in ("a.h5", "b.h5"):
    ...     write_events(root / "in" / name, ev, (4, 1))
    >>> report = deflare_files(root / "in", root / "out", "efr", workers=1, shard="0/1",
    ...                        params={"frequency_hz": 50}, progress=False)
    >>> [(r.name, r.events_in, r.events_out) for r in report.done], report.complete
    ([('a.h5', 3, 2), ('b.h5', 3, 2)], True)
    >>> read_events(root / "out" / "a.h5").events["t"].tolist()
    [0, 5000]
    """
    start = time.perf_counter()
    _check_run_options(window_us, max_lag_us, evt_version, rng, workers)
    shard_i, shard_n = parse_shard((0, 1) if shard is None else shard)
    suffix = _check_suffix(suffix)
    if isinstance(method, Method):
        if params:
            raise ParameterError("pass parameters either to create_method or here, not both")
        m, spec = method, method
        if workers > 1:
            _check_picklable(method)
    else:
        m = create_method(method, **dict(params or {}))  # a bad parameter fails here, once
        spec = (method, dict(params or {}))
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise EventFileError(out_dir, "is a file; the outputs of several inputs go to a folder")
    if not out_dir.exists() and out_dir.suffix.lower() in list_formats():
        raise ParameterError(
            f"{out_dir} names an event file, but the outputs of several inputs go to a "
            "folder: name a folder"
        )
    items = _plan(_find_inputs(inputs, out_dir), out_dir, suffix)
    if not items:
        raise ParameterError(
            f"no event files in {inputs}: a folder contributes files with the suffixes "
            f"{', '.join(s for s in list_formats() if s not in _TEXT_SUFFIXES)}; "
            "name others or use a glob pattern"
        )
    run = {
        "window_us": int(window_us),
        "sensor_size": None if sensor_size is None else tuple(int(v) for v in sensor_size),
        "rng": None if rng is None else int(rng),
        "max_lag_us": None if max_lag_us is None else int(max_lag_us),
        "evt_version": evt_version,
        "group": group,
    }
    options = {k if k != "rng" else "seed": v for k, v in run.items()}
    identity = _identity(m, options)
    out_dir.mkdir(parents=True, exist_ok=True)
    known = _load_manifests(out_dir)
    mine = [item for k, item in enumerate(items) if k % shard_n == shard_i]
    mine_names = {item.name for item in mine}
    shard_text = None if shard_n == 1 else f"{shard_i}/{shard_n}"
    own_path = out_dir / (
        MANIFEST if shard_n == 1 else f"manifest.shard-{shard_i}-of-{shard_n}.json"
    )

    # What the manifest says of each output as it is; this run updates its own files'.
    view: dict[str, dict[str, Any]] = {}
    for name, entries in known.items():
        if shard_n == 1 or name in mine_names:
            best = _best(entries, out_dir.joinpath(*PurePosixPath(name).parts))
            if best is not None:
                view[name] = best
    _remove_temporaries([item.output for item in mine])  # of killed runs
    results: dict[str, FileResult] = {}
    tasks: list[_Task] = []
    for item in mine:
        same = tuple(e for e in known.get(item.name, []) if e.get("method") == identity)
        fresh = next((e for e in same if _fresh_by_stat(e, item)), None)
        if fresh is not None:
            counts = fresh.get("events", {})
            results[item.name] = FileResult(
                item.name, item.input, item.output, "skipped", counts.get("in"), counts.get("out")
            )
            view[item.name] = fresh
        else:
            tasks.append(_Task(item, same, identity, run))
    if on_file is not None:
        for r in results.values():
            on_file(r)

    def own_manifest() -> dict[str, Any]:
        complete = len(results) == len(mine) and all(r.status != "failed" for r in results.values())
        return _manifest(view, complete, shard_text)

    bar = progress_bar(
        total=len(mine),
        initial=len(results),
        enabled=progress,
        desc=m.name or type(m).__name__,
        unit="file",
        dynamic_ncols=True,
    )
    next_write = time.perf_counter() + _WRITE_EVERY_S

    def finished(outcome: _Outcome) -> None:
        nonlocal next_write
        r = outcome.result
        results[r.name] = r
        if outcome.entry is not None:
            view[r.name] = outcome.entry
        for category, message in outcome.warnings:
            warnings.warn(message, category, stacklevel=3)
        bar.update(1)
        if on_file is not None:
            on_file(r)
        now = time.perf_counter()
        if now > next_write:  # current without rewriting it per file
            _write_json(own_path, own_manifest())
            spent = time.perf_counter() - now  # a large manifest: at most 5% of the time
            next_write = now + max(_WRITE_EVERY_S, 20 * spent)

    try:
        with interruptible():  # Ctrl-C stops the run even if a finaliser swallows it
            if workers == 1 or len(tasks) <= 1:
                for task in tasks:
                    check_interrupt()
                    finished(_run_one(m, task))
            else:
                _run_pool(spec, tasks, workers, finished)
    except BaseException:  # stopped (Ctrl-C): the stopped workers' temporaries go too
        _remove_temporaries([task.item.output for task in tasks])
        raise
    finally:
        bar.close()
        _write_json(own_path, own_manifest())  # also when interrupted: keep what is done
    complete = _whole_set_complete(items, out_dir, identity, view, shard_n)
    files = tuple(results[item.name] for item in mine)
    return BatchReport(files, out_dir, own_path, complete, time.perf_counter() - start)


def _whole_set_complete(
    items: list[_Item],
    out_dir: Path,
    identity: dict[str, Any],
    view: dict[str, dict[str, Any]],
    shard_n: int,
) -> bool:
    """Whether every input (of every shard) has its output; a shard then writes manifest.json."""
    if shard_n == 1:
        return all(
            item.name in view
            and view[item.name].get("method") == identity
            and _fresh_by_stat(view[item.name], item)
            for item in items
        )
    known = _load_manifests(out_dir)  # the other shards' progress, as of now
    merged: dict[str, dict[str, Any]] = {}
    for name, entries in known.items():
        best = _best(entries, out_dir.joinpath(*PurePosixPath(name).parts))
        if best is not None:
            merged[name] = best
    for item in items:
        ok = [
            e
            for e in ([view[item.name]] if item.name in view else []) + known.get(item.name, [])
            if e.get("method") == identity and _fresh_by_stat(e, item)
        ]
        if not ok:
            return False
        merged[item.name] = ok[0]
    _write_json(out_dir / MANIFEST, _manifest(merged, True, None))
    return True
