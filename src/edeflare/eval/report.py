"""The HTML benchmark report: tables, qualitative grids, GIFs, reconstructions and flare scores.

:func:`write_report` writes a self-contained folder: ``index.html`` (inline
CSS, no script, no network) beside the PNG and GIF files it shows and a
``results.json`` with every number. The page holds

- the paper's metrics table (raw input unranked, best **bold**, second best
  *italic*, improvement row; as :mod:`edeflare.eval.tables`) and the speed table;
- a qualitative grid like the paper's Figures 4-5: rows are samples, columns
  the input, each method and the ground truth, events drawn red (ON) / blue
  (OFF) over 20 ms windows;
- one short GIF per sample over consecutive windows of its sequence;
- the downstream view: images reconstructed from each stream by the leaky
  integrator of :mod:`edeflare.eval.reconstruct`, side by side, and the
  no-reference flare score of :mod:`edeflare.eval.flare_score` before (input) and
  after (each method), per sample and as the median over every window of
  the split;
- optionally, real recordings (``real=``) reconstructed by the bundled recurrent
  reconstructor before and after each method (qualitative, as the paper's
  real-data figures: there is no flare-free image to score against).

Samples are chosen deterministically while the benchmark runs
(:class:`~edeflare.eval.figures.FigureCollector`, the ``on_output`` hook of
:func:`edeflare.eval.benchmark.benchmark`): each sequence offers its window with
the most flare -- the largest ``sum |N_input - N_gt|`` over pixels of the
per-pixel event counts -- and the sequences with the largest amounts are
kept (ties: earlier sequence first). Only the kept samples' pictures stay in
memory, never whole streams.
"""

from __future__ import annotations

import html
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from .._progress import progress_bar
from .._version import __version__
from ..errors import EventFileError
from ..io._atomic import atomic_path
from ..methods import Method
from ..viz import grid, save_animation, save_image
from .benchmark import BenchmarkResult, benchmark
from .downstream import RealReconstruction, reconstruct_recording
from .evaluate import convention_note
from .figures import (
    FIGURE_KINDS,
    GT,
    INPUT,
    FigureCollector,
    FigureData,
    Sample,
    nan_median,
    window_label,
)
from .reconstruct import display_scale, to_uint8
from .tables import METRIC_LABELS, ResultsTable

__all__ = [
    "DEFAULT_METHODS",
    "FigureCollector",
    "FigureData",
    "Sample",
    "check_report_dir",
    "downstream_table_html",
    "metrics_table_html",
    "speed_table_html",
    "write_report",
]

DEFAULT_METHODS = ("raw", "voxel", "efr", "pfd-a", "pfd-b", "model")
"""Rows of a report made straight from a split folder."""

_GIF_MAX_WIDTH = 1600


# ---------------------------------------------------------------------------------------
# HTML


_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.5em auto;
       max-width: 1400px; padding: 0 1em; color: #222; }
h1 { font-size: 1.6em; } h2 { margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.6em 0; font-variant-numeric: tabular-nums; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: right; }
th:first-child, td:first-child { text-align: left; }
thead th { background: #f0f0f0; }
tr.raw td { color: #777; background: #f4f4f4; }
tr.improvement td { border-top: 2px solid #888; }
td strong { color: #1f4fbf; } td em { color: #c0392b; }
figure { margin: 0.8em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; max-width: 60em; }
.gifs { display: flex; flex-wrap: wrap; gap: 0.8em; }
.gifs figure { flex: 1 1 40em; }
.note { color: #555; font-size: 0.9em; max-width: 60em; }
code { background: #f4f4f4; padding: 0 0.2em; }
"""


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _fmt(value: float, digits: int) -> str:
    return "–" if value is None or math.isnan(value) else f"{value:.{digits}f}"


def metrics_table_html(table: ResultsTable, digits: int = 4) -> str:
    """The paper's table as HTML: raw row first (gray), best ``<strong>``, second ``<em>``.

    Examples
    --------
    >>> t = ResultsTable({"raw": {"chamfer": 2.0}, "a<b": {"chamfer": 1.0},
    ...                   "c": {"chamfer": 1.5}}, metrics=["chamfer"])
    >>> "<strong>1.0000</strong>" in metrics_table_html(t), "a&lt;b" in metrics_table_html(t)
    (True, True)
    """
    best, second = table.best, table.second
    head = "".join(f"<th>{_e(METRIC_LABELS.get(m, m))}</th>" for m in table.metrics)
    lines = [
        '<table id="metrics">',
        f"<thead><tr><th>Method</th>{head}</tr></thead>",
        "<tbody>",
    ]
    raw = table.raw
    names = [n for n in table.values if n == raw] + [n for n in table.values if n != raw]
    for name in names:
        cells = []
        for m in table.metrics:
            text = _fmt(float(table.values[name].get(m, math.nan)), digits)
            if name != raw and name == best[m]:
                text = f"<strong>{text}</strong>"
            elif name != raw and name == second[m]:
                text = f"<em>{text}</em>"
            cells.append(f"<td>{text}</td>")
        label = f"{_e(name)} (input)" if name == raw else _e(name)
        cls = ' class="raw"' if name == raw else ""
        lines.append(f"<tr{cls}><td>{label}</td>{''.join(cells)}</tr>")
    imp = table.improvement
    if any(not math.isnan(v) for v in imp.values()):
        cells = "".join(
            f"<td>{'–' if math.isnan(imp[m]) else f'{imp[m]:.1f}%'}</td>" for m in table.metrics
        )
        lines.append(f'<tr class="improvement"><td>Improvement (%)</td>{cells}</tr>')
    lines += ["</tbody>", "</table>"]
    return "\n".join(lines)


def speed_table_html(result: BenchmarkResult) -> str:
    """Per-method speed as HTML: 20 ms windows per second and real-time factor.

    Examples
    --------
    >>> from edeflare.eval.benchmark import MethodSpeed
    >>> from edeflare.eval.evaluate import Evaluation
    >>> r = BenchmarkResult(Evaluation(), {"pfd-b": MethodSpeed(2.0, 50, 1_000_000)})
    >>> "<td>pfd-b</td><td>25.00</td><td>2</td>" in speed_table_html(r)
    True
    """
    lines = [
        '<table id="speed">',
        "<thead><tr><th>Method</th><th>windows/s</th><th>real-time factor</th></tr></thead>",
        "<tbody>",
    ]
    for name, s in result.speed.items():
        lines.append(
            f"<tr><td>{_e(name)}</td><td>{s.windows_per_s:.2f}</td>"
            f"<td>{s.real_time_factor:.3g}</td></tr>"
        )
    lines += ["</tbody>", "</table>"]
    return "\n".join(lines)


def downstream_table_html(result: BenchmarkResult) -> str:
    """Reconstruction scores as HTML (empty string when the benchmark has none).

    Examples
    --------
    >>> from edeflare.eval.evaluate import Evaluation
    >>> r = BenchmarkResult(Evaluation(), {}, {"raw": {"psnr": 20.0, "ssim": 0.5, "windows": 3}})
    >>> "<td>raw</td><td>20.00</td><td>0.5000</td><td>–</td><td>3</td>" in downstream_table_html(r)
    True
    """
    if not result.downstream:
        return ""
    lines = [
        '<table id="downstream">',
        "<thead><tr><th>Stream</th><th>PSNR (dB) ↑</th><th>SSIM ↑</th><th>flare-region RMSE ↓</th>"
        "<th>windows</th></tr></thead>",
        "<tbody>",
    ]
    for name, d in result.downstream.items():
        lines.append(
            f"<tr><td>{_e(name)}</td><td>{_fmt(d['psnr'], 2)}</td>"
            f"<td>{_fmt(d['ssim'], 4)}</td><td>{_fmt(d.get('flare', math.nan), 4)}</td>"
            f"<td>{int(d['windows'])}</td></tr>"
        )
    lines += ["</tbody>", "</table>"]
    return "\n".join(lines)


def _score_table(
    table_id: str,
    columns: Sequence[str],
    rows: Sequence[tuple[str, Mapping[str, float]]],
    *,
    percent: bool = False,
    bold: Sequence[bool] | None = None,
) -> str:
    """Rows of per-column values; the lowest method value of each row in bold (where asked)."""
    head = "".join(f"<th>{_e(c)}</th>" for c in columns)
    methods = [c for c in columns if c not in (INPUT, GT)]
    lines = [f'<table id="{table_id}">', f"<thead><tr><th></th>{head}</tr></thead>", "<tbody>"]
    for r, (label, values) in enumerate(rows):
        finite = {c: values[c] for c in methods if not math.isnan(values.get(c, math.nan))}
        best = min(finite, key=lambda c: finite[c]) if finite else None
        if bold is not None and not bold[r]:
            best = None
        cells = []
        for c in columns:
            value = values.get(c, math.nan)
            text = _fmt(100 * value, 0) + "%" if percent and not math.isnan(value) else None
            text = text or _fmt(value, 3)
            cells.append(f"<td><strong>{text}</strong></td>" if c == best else f"<td>{text}</td>")
        lines.append(f"<tr><td>{_e(label)}</td>{''.join(cells)}</tr>")
    lines += ["</tbody>", "</table>"]
    return "\n".join(lines)


def _gray(image: np.ndarray) -> np.ndarray:
    return np.repeat(image[..., None], 3, axis=2)


def _fit(image: np.ndarray, max_width: int) -> np.ndarray:
    h, w = image.shape[:2]
    if w <= max_width:
        return image
    size = (max_width, max(1, round(h * max_width / w)))
    return np.asarray(Image.fromarray(image).resize(size, Image.Resampling.BOX))


def _write_figures(out: Path, figures: FigureData) -> dict[str, Any]:
    """PNG/GIF files of the figures; returns names for the page."""
    cols = figures.columns
    samples = figures.samples
    names: dict[str, Any] = {"gifs": []}
    if not samples:
        return names
    cells = [s.frames[c] for s in samples for c in cols]
    row_labels = [s.label for s in samples]
    save_image(out / "qualitative.png", grid(cells, labels=cols, row_labels=row_labels))
    names["qualitative"] = "qualitative.png"
    recon_cells = []
    for s in samples:
        ref = s.recon[GT] if np.any(s.recon[GT]) else s.recon[INPUT]
        scale = display_scale(ref)
        recon_cells += [_gray(to_uint8(s.recon[c], scale=scale)) for c in cols]
    save_image(out / "reconstruction.png", grid(recon_cells, labels=cols, row_labels=row_labels))
    names["reconstruction"] = "reconstruction.png"
    for k, s in enumerate(samples, start=1):
        if not s.gif_starts:
            continue
        frames = []
        for i, g in enumerate(s.gif_starts):
            caption = window_label(s.sequence, g, s.t_start_us, s.window_us)
            row = grid([s.gif[c][i] for c in cols], labels=cols, row_labels=[caption])
            frames.append(_fit(row, _GIF_MAX_WIDTH))
        name = f"animation_{k}.gif"
        save_animation(out / name, frames, fps=4)
        names["gifs"].append((name, s.label))
    return names


def _write_downstream_animation(out: Path, result: BenchmarkResult) -> str | None:
    """``downstream.gif``: one sequence's reconstructions side by side, window by window."""
    sample = result.downstream_sample
    if not sample:
        return None
    columns = [c for c in sample if c not in ("clean", "ground truth")]
    columns += [c for c in ("ground truth", "clean") if c in sample]
    label_of = {"ground truth": "ground-truth events", "clean": "clean frame"}
    labels = [label_of.get(c, c) for c in columns]
    n = min(len(sample[c]) for c in columns)
    frames = []
    for t in range(n):
        gray = [np.round(np.clip(sample[c][t], 0, 1) * 255).astype(np.uint8) for c in columns]
        cells = [_gray(g) for g in gray]
        frames.append(_fit(grid(cells, labels=labels, ncols=len(columns)), _GIF_MAX_WIDTH))
    save_animation(out / "downstream.gif", frames, fps=2.0)
    return "downstream.gif"


def _write_real(
    out: Path,
    paths: Sequence[str | os.PathLike[str]],
    methods: Mapping[str, str | Method],
    progress: bool,
) -> list[tuple[str, RealReconstruction]]:
    """``real_<name>.png`` for each real recording (``real_<name>_<k>.png`` for a name
    seen before): its figure name and its reconstructions before and after."""
    done: list[tuple[str, RealReconstruction]] = []
    for path in progress_bar(paths, enabled=progress and bool(paths), desc="real recordings"):
        r = reconstruct_recording(path, methods)
        png = f"real_{Path(r.name).stem}.png"
        taken = {name for name, _ in done}
        k = 2
        while png in taken:
            png, k = f"real_{Path(r.name).stem}_{k}.png", k + 1
        save_image(out / png, _fit(r.image, _GIF_MAX_WIDTH))
        done.append((png, r))
    return done


def _nan_none(value: float) -> float | None:
    return None if math.isnan(value) else float(value)


def _results_json(result: BenchmarkResult, figures: FigureData | None) -> str:
    payload: dict[str, Any] = {
        "edeflare_version": __version__,
        "table": json.loads(result.table().to_json()),
        "benchmark": result.to_dict(),
    }
    if figures is not None:
        payload["flare_score"] = {
            "median_over_windows": {
                kind: {c: _nan_none(v) for c, v in values.items()}
                for kind, values in figures.medians().items()
            },
            "share_of_input_energy": {
                kind: {
                    c: {"flare": _nan_none(f), "source": _nan_none(src)}
                    for c, (f, src) in figures.kept(kind).items()
                }
                for kind in FIGURE_KINDS
            },
            "windows": figures.n_windows,
            "reconstruction": [
                {
                    "sequence": s.sequence,
                    "window_start_us": s.window_start_us,
                    "flare_amount": s.flare_amount,
                    "source_xy": list(s.geometry.center),
                    "scores": {c: _nan_none(v) for c, v in s.scores.items()},
                }
                for s in figures.samples
            ],
            "cutoff_hz": figures.cutoff_hz,
            "contrast": figures.contrast,
        }
    return json.dumps(payload, indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def _page(
    result: BenchmarkResult, figures: FigureData | None, names: dict[str, Any], title: str
) -> str:
    table = result.table()
    n_files = len(next(iter(result.evaluation.per_file.values()), {}))
    n_segments = max((s.n_segments for s in result.evaluation.methods.values()), default=0)
    body = [
        f"<h1>{_e(title)}</h1>",
        f'<p class="note">{n_files} sequence(s), {n_segments} segment(s); '
        f"edeflare {_e(__version__)}. {_e(convention_note(result.evaluation.convention))} "
        "Lower is better for ↓ metrics, higher for ↑; "
        "among the methods (the raw input is not ranked) the best value is <strong>bold"
        "</strong> and the second best <em>italic</em>; the last row is the best method's "
        "gain over the second best.</p>",
        '<h2 id="metrics-title">Metrics</h2>',
        metrics_table_html(table),
        '<h2 id="speed-title">Speed</h2>',
        '<p class="note">Processing time only (no I/O); real-time factor = processing time '
        "over stream duration (below 1: faster than real time).</p>",
        speed_table_html(result),
    ]
    if result.downstream:
        body += [
            '<h2 id="downstream-title">Downstream: image reconstruction</h2>',
            '<p class="note">Every stream reconstructed into images by the bundled recurrent '
            "reconstructor (<code>edeflare.recon</code>) and scored against the simulator's "
            "flare-free image at each window's end (log intensity, both shifted to mean 0.5; "
            "the first windows of each sequence are a burn-in). <em>ground truth</em> is the "
            "reconstruction of the ground-truth events: the ceiling.</p>",
            downstream_table_html(result),
        ]
        if names.get("downstream"):
            body.append(
                '<figure><img src="downstream.gif" alt="reconstructions side by side">'
                "<figcaption>One sequence, window by window: the reconstruction of each "
                "stream, of the ground-truth events, and the clean frame it is scored "
                "against (all with their mean shifted to mid-gray).</figcaption></figure>"
            )
    if figures is None or not figures.samples:
        body.append('<p class="note">No figures (no sample windows were collected).</p>')
    else:
        cols = figures.columns
        col_text = ", ".join(_e(c) for c in cols)
        window_ms = figures.samples[0].window_us / 1000
        body += [
            '<h2 id="qualitative-title">Qualitative comparison</h2>',
            '<figure><a href="qualitative.png"><img src="qualitative.png" '
            'alt="event frames of the sample windows"></a>',
            f"<figcaption>Rows: the {len(figures.samples)} windows with the most flare "
            "(largest per-pixel difference of event counts between input and ground truth, "
            f"one per sequence). Columns: {col_text}. Events of one {window_ms:g} ms window; "
            '<span style="color:#dc1e1e">red: ON</span>, '
            '<span style="color:#1e46dc">blue: OFF</span>.</figcaption></figure>',
            '<h2 id="animations-title">Animations</h2>',
            '<div class="gifs">',
        ]
        for name, label in names["gifs"]:
            body.append(
                f'<figure><img src="{_e(name)}" alt="{_e(label)}">'
                f"<figcaption>{_e(label)} and the windows around it.</figcaption></figure>"
            )
        body.append("</div>")
        sample_rows = [(s.label, s.scores) for s in figures.samples]
        sample_rows.append(
            ("median", {c: nan_median([s.scores[c] for s in figures.samples]) for c in cols})
        )
        medians = figures.medians()
        n_windows = figures.n_windows
        kept = {kind: figures.kept(kind) for kind in FIGURE_KINDS}
        kept_rows = [
            (f"{part} energy {verb}, {name}", {c: v[i] for c, v in kept[kind].items()})
            for kind, name in (("reconstruction", "reconstructed images"), ("events", "events"))
            for i, (part, verb) in enumerate((("flare", "left"), ("source", "kept")))
        ]
        split_rows = [
            (f"reconstructed images, median over {n_windows} windows", medians["reconstruction"]),
            (f"event counts, median over {n_windows} windows", medians["events"]),
        ]
        body += [
            '<h2 id="reconstruction-title">Downstream: image reconstruction</h2>',
            '<figure><a href="reconstruction.png"><img src="reconstruction.png" '
            'alt="reconstructed images of the sample windows"></a>',
            "<figcaption>Images reconstructed from each stream at the end of the sample window "
            "by a per-pixel leaky integrator (high-pass filter, Scheerlinck et al. 2018) run "
            "from the start of the sequence: each event adds ±c to the pixel's log intensity "
            "L, which decays as exp(−α Δt) between events; "
            f"c = {figures.contrast:g}, α = 2π·{figures.cutoff_hz:g} Hz. Gray: no change; "
            "each row shares the ground truth's display scale (99th percentile of |L|), so "
            "flare saturates.</figcaption></figure>",
            "<h3>Flare score (no reference; lower is less flare)</h3>",
            '<p class="note">Energy in the annulus around the light source divided by the '
            "energy of the source (energies above the far-field median). The source is the "
            "brightest compact region of the input's events in the window, located once and "
            "used for every column, so the input is the <em>before</em> and each method an "
            "<em>after</em>. Zero for a source without flare; a method that also erases the "
            "source scores high. Lowest method in bold. Over every window of the split:</p>",
            _score_table("flare-split", cols, split_rows),
            '<p class="note">What moved the score: the flare energy a stream leaves and the '
            "source energy it keeps, as shares of the input's (sums over every window; the "
            "score changes by their ratio). The ground truth shows what a perfect method "
            "keeps. Lowest flare share in bold.</p>",
            _score_table("flare-kept", cols, kept_rows, percent=True, bold=[True, False] * 2),
            '<p class="note">On the reconstructed images above (|L|):</p>',
            _score_table("flare-samples", cols, sample_rows),
        ]
    if names.get("real"):
        body += [
            '<h2 id="real-title">Real recordings: reconstruction before and after</h2>',
            '<p class="note">Each recording (its first 2 s at most) de-flared by every method, '
            "and every stream reconstructed by the bundled recurrent reconstructor "
            "(<code>edeflare.recon</code>) from the recording's start. Shown: the last "
            "complete 20 ms window's input events, then each stream's image at that "
            "window's end. Qualitative, as the paper's real-data figures: a real recording "
            "has no flare-free image to score against.</p>",
        ]
        for png, r in names["real"]:
            counts = ", ".join(f"{_e(k)} {v:,}" for k, v in r.events.items())
            body.append(
                f'<figure><a href="{_e(png)}"><img src="{_e(png)}" '
                f'alt="reconstructions of {_e(r.name)}"></a>'
                f"<figcaption>{_e(r.name)}: events per stream: {counts}.</figcaption></figure>"
            )
    body.append(
        '<p class="note">Every number of this page is in <a href="results.json">'
        "results.json</a>. See the edeflare documentation (docs/report.md) for the "
        "definitions.</p>"
    )
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )


def check_report_dir(out_dir: str | os.PathLike[str]) -> Path:
    """``out_dir`` as a path; an error if it exists and is not a folder (check before long work).

    Examples
    --------
    >>> check_report_dir("report").name
    'report'
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise EventFileError(out, "exists and is not a folder (the HTML report is a folder)")
    return out


def write_report(
    source: BenchmarkResult | str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    figures: FigureData | None = None,
    methods: Mapping[str, str | Method] | None = None,
    params: Mapping[str, Mapping[str, Any]] | None = None,
    seed: int = 0,
    samples: int = 4,
    gif_windows: int = 5,
    cutoff_hz: float = 5.0,
    contrast: float = 0.2,
    title: str = "edeflare benchmark report",
    progress: bool = True,
    downstream: bool | str | os.PathLike[str] = False,
    real: Sequence[str | os.PathLike[str]] = (),
    real_methods: Mapping[str, str | Method] | None = None,
) -> Path:
    """Write the HTML report folder; return the path of its ``index.html``.

    Parameters
    ----------
    source : BenchmarkResult or path-like
        A finished benchmark (give its ``figures`` from a
        :class:`FigureCollector` passed as ``on_output``; without them the
        page has the tables only), or a split folder to benchmark now.
    out_dir : path-like
        Folder to write ``index.html``, ``results.json``, ``qualitative.png``,
        ``reconstruction.png`` and ``animation_<k>.gif`` into (created if
        needed; other files in it are left alone). Every file is written
        atomically and ``index.html`` last, so a page never links to a
        missing or half-written file.
    methods, params, seed :
        With a split folder: rows to run (default :data:`DEFAULT_METHODS`),
        as :func:`edeflare.eval.benchmark.benchmark`.
    samples, gif_windows, cutoff_hz, contrast :
        With a split folder: the :class:`FigureCollector` settings.
    title : str
        Page title.
    downstream : bool or path-like
        With a split folder: also score reconstructions (see
        :func:`edeflare.eval.benchmark.benchmark`); the page gets their table.
    real : sequence of path-like
        Real recordings (any readable format) to reconstruct before and after
        de-flaring by ``real_methods`` (default: ``methods``, else
        :data:`DEFAULT_METHODS`): one figure each, ``real_<name>.png``
        (:func:`edeflare.eval.downstream.reconstruct_recording`; qualitative,
        real recordings have no flare-free image).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.data.toy import toy_flare_pair
    >>> from edeflare.io.dsec import write_dsec_groups
    >>> split = pathlib.Path(tempfile.mkdtemp())
    >>> s = toy_flare_pair((64, 48), duration_us=40_000, rng=0)
    >>> write_dsec_groups(split / "s0.h5", {"input": s.observed, "gt": s.clean}, (64, 48))
    >>> page = write_report(split, split / "report", methods={"raw": "raw", "pfd-b": "pfd-b"},
    ...                     progress=False)
    >>> page.name, (page.parent / "qualitative.png").exists()
    ('index.html', True)
    """
    out = check_report_dir(out_dir)
    if isinstance(source, BenchmarkResult):
        result = source
    else:
        collector = FigureCollector(samples, gif_windows, cutoff_hz=cutoff_hz, contrast=contrast)
        rows = methods if methods is not None else {m: m for m in DEFAULT_METHODS}
        result = benchmark(
            source,
            rows,
            params=params,
            seed=seed,
            progress=progress,
            on_output=collector,
            downstream=downstream,
        )
        figures = collector.finish()
    out.mkdir(parents=True, exist_ok=True)
    names = _write_figures(out, figures) if figures is not None else {"gifs": []}
    names["downstream"] = _write_downstream_animation(out, result)
    rows = real_methods if real_methods is not None else methods
    rows = rows if rows is not None else {m: m for m in DEFAULT_METHODS}
    names["real"] = _write_real(out, real, rows, progress)
    with atomic_path(out / "results.json") as tmp:
        tmp.write_text(_results_json(result, figures), encoding="utf-8")
    page = out / "index.html"
    with atomic_path(page) as tmp:
        tmp.write_text(_page(result, figures, names, title), encoding="utf-8")
    return page
