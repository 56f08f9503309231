"""Dataset folders: which sequence files a folder stands for in training and validation.

A *dataset folder* (``edeflare simulate`` output, ``edeflare pair`` output or
your own) holds ``train/`` and optionally ``test/`` folders of sequence files.
A *mix folder* (``edeflare simulate OUT --recipe eflare-mix``, a
:class:`~edeflare.data.recipe.Mix`) holds one dataset folder per part and a
manifest naming them (``"format": "edeflare-mix/1"``); it stands for its
parts, in the mix's order, so ``edeflare train MIX`` trains as
``edeflare train MIX/part1 MIX/part2 ...`` does.

Examples
--------
>>> import json, tempfile
>>> root = Path(tempfile.mkdtemp())
>>> for name in ("a/train/seq_0.h5", "a/test/seq_1.h5", "b/train/seq_0.h5"):
...     (root / "mix" / name).parent.mkdir(parents=True, exist_ok=True)
...     (root / "mix" / name).touch()
>>> parts = [{"folder": "b"}, {"folder": "a"}]
>>> _ = (root / "mix" / "manifest.json").write_text(
...     json.dumps({"format": "edeflare-mix/1", "parts": parts}))
>>> [p.name for p in dataset_folders(root / "mix")]
['b', 'a']
>>> train, val = dataset_files([root / "mix"])
>>> [p.relative_to(root).as_posix() for p in train], [p.name for p in val]
(['mix/b/train/seq_0.h5', 'mix/a/train/seq_0.h5'], ['seq_1.h5'])
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import EventFileError
from ..io.sequence import list_sequences

__all__ = ["MIX_FORMAT", "dataset_files", "dataset_folders", "mix_manifest", "sequence_files"]

MIX_FORMAT = "edeflare-mix/1"
"""The ``format`` of a mix's manifest (written by :func:`edeflare.data.generate.generate_mix`)."""


def mix_manifest(folder: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The mix manifest of ``folder``, or None when it is not a mix folder.

    ``manifest.json``, else any shard's ``manifest.shard-i-of-n.json`` (every
    one names the same parts), read when its ``format`` is a mix's.
    """
    folder = Path(folder)
    candidates = [folder / "manifest.json", *sorted(folder.glob("manifest.shard-*-of-*.json"))]
    for path in candidates:
        if not path.is_file():
            continue
        try:
            manifest = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(manifest, dict) and manifest.get("format") == MIX_FORMAT:
            parts = manifest.get("parts")
            if not isinstance(parts, list) or not all(
                isinstance(p, dict) and isinstance(p.get("folder"), str) for p in parts
            ):
                raise EventFileError(path, "is a mix manifest without a valid 'parts' list")
            return manifest
    return None


def dataset_folders(folder: str | os.PathLike[str]) -> list[Path]:
    """The dataset folders ``folder`` stands for: a mix's parts in order, else itself."""
    folder = Path(folder)
    manifest = mix_manifest(folder)
    if manifest is None:
        return [folder]
    return [folder / part["folder"] for part in manifest["parts"]]


def dataset_files(
    folders: Sequence[str | os.PathLike[str]],
) -> tuple[list[Path], list[Path]]:
    """The training and validation files of one or several dataset (or mix) folders.

    Each folder's ``train/`` files (sorted by name), the folders in the order
    given, a mix folder as its parts in the mix's order; likewise their
    ``test/`` files, for the folders that have one. The order fixes which
    window each sample index is, so two folders given as ``DAY NIGHT`` train
    exactly as one folder holding ``day_*.h5`` and ``night_*.h5`` links to
    their files did. A mix's part without a ``train/`` (all test) adds
    validation files only.

    Parameters
    ----------
    folders : sequence of path-like
        Dataset or mix folders (``edeflare simulate`` output), at least one.

    Returns
    -------
    train_paths, val_paths : list of Path
        ``val_paths`` is empty when no folder has a ``test/``.

    Examples
    --------
    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> for name in ("b/train/seq_1.h5", "b/train/seq_0.h5", "a/train/seq_0.h5", "a/test/seq_2.h5"):
    ...     (root / name).parent.mkdir(parents=True, exist_ok=True)
    ...     (root / name).touch()
    >>> train, val = dataset_files([root / "b", root / "a"])
    >>> [p.relative_to(root).as_posix() for p in train], [p.name for p in val]
    (['b/train/seq_0.h5', 'b/train/seq_1.h5', 'a/train/seq_0.h5'], ['seq_2.h5'])
    """
    train_paths: list[Path] = []
    val_paths: list[Path] = []
    for given in folders:
        parts = dataset_folders(given)
        is_mix = parts != [Path(given)]
        found = 0
        for folder in parts:
            if not is_mix or (folder / "train").is_dir():
                files = list_sequences(folder / "train")
                train_paths += files
                found += len(files)
            if (folder / "test").is_dir():
                val_paths += list_sequences(folder / "test")
        if is_mix and not found:
            raise EventFileError(Path(given), "is a mix whose parts hold no train/ sequences")
    return train_paths, val_paths


def sequence_files(paths: Sequence[str | os.PathLike[str]], split: str = "train") -> list[Path]:
    """Sequence files from files and folders, in the order given.

    A file stands for itself; a dataset folder (one with ``train/`` or
    ``test/``) for its ``split`` files (none if it has no such folder); a mix
    folder for its parts' ``split`` files, in the mix's order; any other folder
    for the ``*.h5`` files in it (a split folder such as ``DATA/test``).

    Examples
    --------
    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> for name in ("d/train/s0.h5", "d/test/s1.h5", "x.h5"):
    ...     (root / name).parent.mkdir(parents=True, exist_ok=True)
    ...     (root / name).touch()
    >>> [p.name for p in sequence_files([root / "d", root / "x.h5", root / "d" / "test"])]
    ['s0.h5', 'x.h5', 's1.h5']
    >>> [p.name for p in sequence_files([root / "d"], "test")]
    ['s1.h5']
    """
    files: list[Path] = []
    for given in paths:
        path = Path(given)
        if not path.is_dir():
            files.append(path)
            continue
        parts = dataset_folders(path)
        if parts != [path] or (path / "train").is_dir() or (path / "test").is_dir():
            for folder in parts:
                if (folder / split).is_dir():
                    files += list_sequences(folder / split)
        else:
            files += list_sequences(path)
    return files
