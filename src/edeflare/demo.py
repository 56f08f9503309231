"""The embedded demo: simulate a flare scene, de-flare it with every method, picture and score it.

:func:`run_demo` (``edeflare demo``) needs nothing but the installed
package: the physics-driven simulator makes the scene, the baselines and the
bundled default model de-flare it, and the paper's metrics score it.
:func:`edeflare.data.toy.toy_flare_pair` is a cheaper procedural pair (a moving
bar, a 100 Hz lamp, a six-spike flare halo) used by benchmarks and tests.
"""

from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from ._progress import progress_bar
from .errors import EdeflareError
from .events import slice_time
from .io import write_events
from .io._atomic import atomic_path
from .viz import event_frame, grid, save_animation, save_image, voxel_montage
from .voxel import encode

__all__ = ["run_demo"]


DEMO_SEED = 20261122
"""Dataset seed of the demo scene (its sequences are not in the bundled model's data)."""
DEMO_INDEX = 6
"""The sequence of that seed shown by default: a travelling light whose scattered light
is 15 % of the input's events (most sequences of the recipe hold under 3 %, as real
recordings do: too little to see in a picture)."""


def _demo_methods() -> dict[str, Any]:
    """Rows of the demo: the baselines, the bundled models and (with the dv extra) dv-fastdecay.

    Without the bundled weights the demo fails loudly (an installation
    problem), rather than showing a table without its main row.
    """
    from .methods import create_method
    from .models.infer import DEFAULT_MODEL, bundled_weights

    methods = {name: create_method(name) for name in ("raw", "voxel", "efr", "pfd-a", "pfd-b")}
    try:
        bundled_weights()
    except EdeflareError as exc:
        raise EdeflareError(
            f"the demo needs the bundled default weights, which this installation lacks "
            f"({exc}); reinstall edeflare"
        ) from None
    # The default model (night), the bundled voxel-to-voxel model of the uncalibrated
    # simulator, and the filter users already run where dv-processing is installed
    # (the dv extra).
    methods[DEFAULT_MODEL] = create_method("model")
    methods["eflare"] = create_method("model", weights="eflare")
    if importlib.util.find_spec("dv_processing") is not None:
        methods["dv-fastdecay"] = create_method("dv-fastdecay")
    return methods


def _shares_markdown(shares: dict[str, tuple[float, float] | None]) -> str:
    """The per-method shares of flare removed and true events kept, as a Markdown table
    (None: a method that moves or adds events, whose shares an event-for-event count
    cannot give)."""
    lines = [
        "What the methods that only delete events did to the input's events "
        "(`edeflare.eval.metrics.deletion_shares`):",
        "",
        "| Method | flare events removed | true events kept |",
        "|---|---|---|",
    ]
    for name, v in shares.items():
        cells = (
            ("moves or adds events", "-")
            if v is None
            else (f"{100 * v[0]:.1f} %", f"{100 * v[1]:.1f} %")
        )
        lines.append(f"| {name} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines) + "\n"


def _write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def run_demo(
    out_dir: str | os.PathLike[str] = "demo",
    *,
    rng: int = 0,
    progress: bool = True,
) -> dict[str, str]:
    """Simulate a flare scene, de-flare it with every method, and write pictures and metrics.

    Every file is written atomically; without the bundled model it raises
    :class:`~edeflare.errors.EdeflareError` before writing anything.

    The scene is one 100 ms sequence of the ``eflare-night`` recipe (346x260,
    physics-driven flare over a synthetic night street, sensed as sparse events the
    way real sensors record scattered light, with background activity; its ground
    truth is the input's own true events) drawn with the dataset seed
    :data:`DEMO_SEED` and index :data:`DEMO_INDEX` ``+ rng``. Writes to ``out_dir``:
    ``input.h5`` / ``ground_truth.h5`` and one ``<method>.h5`` per method,
    ``comparison.png`` (rows: 20 ms windows; columns: input, each method,
    ground truth), ``comparison.gif``, ``voxels.png`` (the input's 8 bins),
    ``metrics.md`` / ``metrics.json`` (the paper's table over the scene's
    20 ms segments; ``metrics.md`` also says, per method, the share of the flare
    events removed and of the true events kept,
    :func:`~edeflare.eval.metrics.deletion_shares`) and ``summary.json`` (event
    counts and those shares). Returns artefact name -> path.
    """
    from .data.generate import RECIPES, generate_sequence
    from .eval.evaluate import evaluate_streams, summarize
    from .eval.metrics import deletion_shares
    from .eval.tables import ResultsTable

    out = Path(out_dir)
    recipe = RECIPES["eflare-night"].replace(seed=DEMO_SEED)
    seq = generate_sequence(recipe, (DEMO_INDEX + int(rng)) % recipe.sequences)
    size, start, end = seq.sensor_size, seq.t_start_us, seq.t_end_us
    inp, gt = seq.streams["input"], seq.streams["gt"]
    outputs: dict[str, np.ndarray] = {}
    for name, method in progress_bar(
        _demo_methods().items(), enabled=progress, desc="methods", leave=False
    ):
        outputs[name] = method(inp, size, rng=rng)
    write_events(out / "input.h5", inp, size)
    write_events(out / "ground_truth.h5", gt, size)
    for name, events in outputs.items():
        write_events(out / f"{name}.h5", events, size)
    window = recipe.window_us
    summaries = {}
    for name, events in outputs.items():
        segments = evaluate_streams(gt, events, size, window_us=window, start_us=start, end_us=end)
        summaries[name] = summarize(m for _, m in segments)
    table = ResultsTable({name: s.means for name, s in summaries.items()})
    shares = {name: deletion_shares(inp, gt, events, size) for name, events in outputs.items()}
    columns = ["input (flare)", *[n for n in outputs if n != "raw"], "ground truth"]
    streams = [inp, *[outputs[n] for n in outputs if n != "raw"], gt]
    frames, cells, row_labels = [], [], []
    for k, w_start in enumerate(range(start, end, window)):
        row = [event_frame(slice_time(ev, w_start, w_start + window), size) for ev in streams]
        frames.append(grid(row, labels=columns))
        if k < 3:
            cells.extend(row)
            row_labels.append(
                f"{(w_start - start) // 1000}-{(w_start - start + window) // 1000} ms"
            )
    paths = {
        "comparison": out / "comparison.png",
        "animation": out / "comparison.gif",
        "voxels": out / "voxels.png",
        "metrics": out / "metrics.md",
    }
    save_image(paths["comparison"], grid(cells, labels=columns, row_labels=row_labels))
    save_animation(paths["animation"], frames, fps=4)
    first = slice_time(inp, start, start + window)
    save_image(paths["voxels"], voxel_montage(encode(first, size, start, window), ncols=4))
    _write_text(out / "metrics.md", table.to_markdown() + "\n" + _shares_markdown(shares))
    _write_text(out / "metrics.json", table.to_json())
    summary = {
        "scene": {
            "recipe": recipe.name,
            "seed": DEMO_SEED,
            "index": seq.index,
            "sensor_size": list(size),
            "span_us": [start, end],
        },
        "events": {
            "input": int(inp.size),
            "ground_truth": int(gt.size),
            **{n: int(e.size) for n, e in outputs.items()},
        },
        "flare_removed": {n: None if v is None else round(v[0], 4) for n, v in shares.items()},
        "true_kept": {n: None if v is None else round(v[1], 4) for n, v in shares.items()},
        **{k: str(v) for k, v in paths.items()},
    }
    _write_text(out / "summary.json", json.dumps(summary, indent=2))
    return {k: str(v) for k, v in paths.items()}
