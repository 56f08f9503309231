"""The HTML report: numbers, self-containment, escaping, sample choice, and a real browser."""

from __future__ import annotations

import json
import math
import os
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from conftest import browser
from edeflare.cli import main
from edeflare.data.toy import toy_flare_pair
from edeflare.errors import ParameterError
from edeflare.eval.benchmark import benchmark
from edeflare.eval.report import FigureCollector, write_report
from edeflare.eval.tables import METRIC_LABELS
from edeflare.io.dsec import write_dsec_groups
from edeflare.io.sequence import read_sequence
from edeflare.viz import OFF_COLOR, ON_COLOR

SIZE = (96, 72)
SPAN = {"t_start_us": 0, "t_end_us": 60_000}
ODD = '<b>A&B</b> "q"'  # a method name that must be escaped
METHODS = {"raw": "raw", "pfd-b": "pfd-b", ODD: "voxel"}


class _Page(HTMLParser):
    """Tables (by id) as rows of (text, tag) cells, and every src/href."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[tuple[str, str]]]] = {}
        self.links: list[str] = []
        self._table: str | None = None
        self._row: list[tuple[str, str]] | None = None
        self._cell: list[str] | None = None
        self._mark = ""

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        for key in ("src", "href"):
            if key in attrs:
                self.links.append(attrs[key])
        if tag == "table":
            self._table = attrs.get("id", "")
            self.tables[self._table] = []
        elif tag == "tr" and self._table is not None:
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell, self._mark = [], ""
        elif tag in ("strong", "em") and self._cell is not None:
            self._mark = tag

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(("".join(self._cell).strip(), self._mark))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.tables[self._table].append(self._row)
            self._row = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def _write_split(folder: Path) -> Path:
    """Three 60 ms sequences: one without flare, two with different amounts of it."""
    folder.mkdir()
    for k, rng in enumerate((11, 12, 13)):
        scene = toy_flare_pair(SIZE, duration_us=60_000, rng=rng)
        inputs = scene.clean if k == 0 else scene.observed
        if k == 2:  # less flare: keep every other flare event
            flare = np.setdiff1d(scene.observed, scene.clean)
            inputs = np.sort(np.concatenate([scene.clean, flare[::2]]), order="t", kind="stable")
        write_dsec_groups(folder / f"seq_{k}.h5", {"input": inputs, "gt": scene.clean}, SIZE, SPAN)
    return folder


def _amount(path: Path) -> float:
    inp, gt, size, start, end = read_sequence(path)
    best = 0.0
    for w in range(start, end, 20_000):
        counts = []
        for ev in (inp, gt):
            sel = ev[(ev["t"] >= w) & (ev["t"] < w + 20_000)]
            counts.append(np.bincount(sel["y"].astype(int) * size[0] + sel["x"], minlength=6912))
        best = max(best, float(np.abs(counts[0] - counts[1]).sum()))
    return best


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    split = _write_split(root / "test")
    collector = FigureCollector(samples=2, gif_windows=2)
    result = benchmark(split, METHODS, progress=False, on_output=collector)
    out = root / "report"
    page = write_report(result, out, figures=collector.finish())
    return split, result, out, page


def test_metrics_table_has_the_results_with_best_bold_and_second_italic(built):
    _, result, _, page = built
    rows = _parse(page).tables["metrics"]
    table = result.table()
    header = [text for text, _ in rows[0]]
    assert header == ["Method", *(METRIC_LABELS[m] for m in table.metrics)]
    by_name = {r[0][0]: r[1:] for r in rows[1:]}
    assert list(by_name) == ["raw (input)", "pfd-b", ODD, "Improvement (%)"]
    for name, cells in by_name.items():
        if name == "Improvement (%)":
            for (text, _), m in zip(cells, table.metrics, strict=True):
                imp = table.improvement[m]
                assert text == ("–" if math.isnan(imp) else f"{imp:.1f}%")
            continue
        key = "raw" if name == "raw (input)" else name
        for (text, mark), m in zip(cells, table.metrics, strict=True):
            value = table.values[key][m]
            assert text == ("–" if math.isnan(value) else f"{value:.4f}")
            expected = "strong" if key == table.best[m] else "em" if key == table.second[m] else ""
            assert mark == ("" if key == "raw" else expected), (name, m)


def test_speed_table(built):
    _, result, _, page = built
    rows = _parse(page).tables["speed"]
    assert [r[0][0] for r in rows[1:]] == list(METHODS)
    for row in rows[1:]:
        speed = result.speed[row[0][0]]
        assert row[1][0] == f"{speed.windows_per_s:.2f}"
        assert row[2][0] == f"{speed.real_time_factor:.3g}"


def test_self_contained_no_network_and_every_image_present(built):
    _, _, out, page = built
    text = page.read_text(encoding="utf-8")
    assert "http://" not in text and "https://" not in text
    assert "<script" not in text.lower() and "@import" not in text and "url(" not in text
    links = _parse(page).links
    assert {"qualitative.png", "reconstruction.png", "results.json"} <= set(links)
    assert any(link.endswith(".gif") for link in links)
    for link in links:
        assert "/" not in link and ":" not in link, link  # relative, same folder
        assert (out / link).is_file(), link
    assert not list(out.glob(".*partial*"))  # no temporary files left


def test_method_names_are_escaped(built):
    _, _, _, page = built
    text = page.read_text(encoding="utf-8")
    assert ODD not in text
    assert "&lt;b&gt;A&amp;B&lt;/b&gt; &quot;q&quot;" in text
    parsed = _parse(page)
    assert ODD in [cells[0][0] for cells in parsed.tables["metrics"]]
    assert ODD in [text for text, _ in parsed.tables["flare-split"][0]]


def test_samples_are_the_most_flared_windows_in_order(built):
    split, _, out, _ = built
    payload = json.loads((out / "results.json").read_text())
    samples = payload["flare_score"]["reconstruction"]
    amounts = {p.stem: _amount(p) for p in sorted(split.glob("*.h5"))}
    assert amounts["seq_0"] == 0 and amounts["seq_1"] > amounts["seq_2"] > 0
    assert [s["sequence"] for s in samples] == ["seq_1", "seq_2"]
    for s in samples:
        assert s["flare_amount"] == amounts[s["sequence"]]
        assert set(s["scores"]) == {"input", "pfd-b", ODD, "ground truth"}


def test_flare_tables_before_and_after(built):
    _, _, out, page = built
    payload = json.loads((out / "results.json").read_text())["flare_score"]
    tables = _parse(page).tables
    columns = [text for text, _ in tables["flare-split"][0][1:]]
    assert columns == ["input", "pfd-b", ODD, "ground truth"]
    medians = payload["median_over_windows"]
    for row, kind in zip(tables["flare-split"][1:], ("reconstruction", "events"), strict=True):
        assert f"{payload['windows']} windows" in row[0][0]
        for (text, _), column in zip(row[1:], columns, strict=True):
            assert text == f"{medians[kind][column]:.3f}"
    # The flare makes the input score above the clean ground truth (a third of the
    # windows have no flare), well above on the flared samples.
    for kind in ("reconstruction", "events"):
        assert medians[kind]["input"] > 1.3 * medians[kind]["ground truth"]
    for sample in payload["reconstruction"]:
        assert sample["scores"]["input"] > 2 * sample["scores"]["ground truth"]
    kept = payload["share_of_input_energy"]
    rows = tables["flare-kept"][1:]
    labels = [r[0][0] for r in rows]
    assert labels == [
        "flare energy left, reconstructed images",
        "source energy kept, reconstructed images",
        "flare energy left, events",
        "source energy kept, events",
    ]
    for row, (kind, part) in zip(
        rows,
        [(k, p) for k in ("reconstruction", "events") for p in ("flare", "source")],
        strict=True,
    ):
        for (text, _), column in zip(row[1:], columns, strict=True):
            assert text == f"{100 * kept[kind][column][part]:.0f}%"
        assert row[1][0] == "100%"  # the input itself
    # The ground truth has less flare than the input and keeps the source.
    for kind in ("reconstruction", "events"):
        assert kept[kind]["ground truth"]["flare"] < 0.8
        assert kept[kind]["ground truth"]["source"] > 0.9
    sample_rows = tables["flare-samples"][1:]
    assert [r[0][0] for r in sample_rows][-1] == "median" and len(sample_rows) == 3
    first = payload["reconstruction"][0]["scores"]
    assert [t for t, _ in sample_rows[0][1:]] == [f"{first[c]:.3f}" for c in columns]


def test_figures(built):
    _, _, out, _ = built
    qual = np.asarray(Image.open(out / "qualitative.png").convert("RGB"))
    # Two rows of four columns (input, pfd-b, the odd name, ground truth) of 96x72 frames.
    assert qual.shape[0] > 2 * 72 and qual.shape[1] > 4 * 96
    for color in (ON_COLOR, OFF_COLOR):
        assert (qual == color).all(axis=2).sum() > 100
    recon = np.asarray(Image.open(out / "reconstruction.png").convert("RGB"))
    assert recon.shape == qual.shape
    gray = recon[..., 0].astype(int)
    assert (np.abs(gray - recon[..., 2]) == 0).mean() > 0.99  # gray levels (and black labels)
    for k in (1, 2):
        with Image.open(out / f"animation_{k}.gif") as gif:
            assert gif.n_frames == 2


def test_collector_keeps_only_the_samples_and_is_deterministic(built):
    split, *_ = built
    runs = []
    for _ in range(2):
        collector = FigureCollector(samples=1, gif_windows=3)
        for path in sorted(split.glob("*.h5")):
            inp, gt, size, start, end = read_sequence(path)
            seq = {"inputs": inp, "gt": gt, "output": inp, "sensor_size": size}
            seq.update(start_us=start, end_us=end, window_us=20_000)
            for row in ("raw", "copy"):
                collector(row=row, path=path, **seq)
        runs.append(collector.finish())
    a, b = runs
    assert a.columns == ["input", "copy", "ground truth"]  # raw is the input column
    assert len(a.samples) == 1 and a.samples[0].sequence == "seq_1"
    sample = a.samples[0]
    assert len(sample.gif_starts) == 3 and all(len(v) == 3 for v in sample.gif.values())
    for column in a.columns:
        assert np.array_equal(sample.frames[column], b.samples[0].frames[column])
        assert np.array_equal(sample.recon[column], b.samples[0].recon[column])
    for kind in ("events", "reconstruction"):
        for column in a.columns:
            np.testing.assert_array_equal(a.energies[kind][column], b.energies[kind][column])
        # A copy of the input scores as the input and keeps all of its energy.
        np.testing.assert_array_equal(a.energies[kind]["copy"], a.energies[kind]["input"])
        assert a.kept(kind)["copy"] == (1.0, 1.0)
    assert a.n_windows == 9 and a.energies["events"]["input"].shape == (9, 2)  # 3 x 3 windows
    with pytest.raises(ParameterError, match="may not be called"):
        collector(row="input", path="x", **seq)


def test_tables_only_without_figures(built, tmp_path):
    _, result, _, _ = built
    page = write_report(result, tmp_path / "r")
    text = page.read_text(encoding="utf-8")
    assert 'id="metrics"' in text and 'id="speed"' in text and "No figures" in text
    assert sorted(p.name for p in page.parent.iterdir()) == ["index.html", "results.json"]


def test_cli_html(built, tmp_path, capsys):
    split, *_ = built
    out = tmp_path / "html"
    args = ["benchmark", str(split), "--methods", "raw", "pfd-b", "--samples", "1"]
    assert main([*args, "--html", str(out)]) == 0
    assert f"wrote {out / 'index.html'}" in capsys.readouterr().out
    assert (out / "qualitative.png").exists() and (out / "animation_1.gif").exists()
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    assert main(["benchmark", str(split), "--methods", "raw", "--html", str(blocker)]) == 1
    assert "not a folder" in capsys.readouterr().err


def _colored(pixels: np.ndarray, color: tuple[int, int, int], tol: int = 12) -> int:
    return int((np.abs(pixels.astype(int) - np.array(color)).max(axis=2) <= tol).sum())


def test_report_renders_in_a_headless_browser(built, tmp_path):
    """Debian's chromium takes a screenshot of the page: not blank, event colours visible."""
    _, _, _, page = built
    shot = tmp_path / "shot.png"
    command = [
        browser(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'profile'}",
        f"--screenshot={shot}",
        "--window-size=1200,2000",
        page.resolve().as_uri(),
    ]
    env = {**os.environ, "HOME": str(tmp_path)}
    subprocess.run(command, check=True, timeout=120, capture_output=True, env=env)
    assert shot.is_file()
    pixels = np.asarray(Image.open(shot).convert("RGB"))
    assert pixels.shape[:2] == (2000, 1200)
    assert pixels.std() > 20  # not a blank page
    assert _colored(pixels, ON_COLOR) > 200 and _colored(pixels, OFF_COLOR) > 200


def test_real_recordings_are_reconstructed_before_and_after_each_method(built, tmp_path, capsys):
    split, *_ = built
    scene = toy_flare_pair(SIZE, duration_us=60_000, rng=21)
    recording = tmp_path / "night drive.h5"  # a name to escape and to keep
    write_dsec_groups(recording, {"events": scene.observed}, SIZE, SPAN)
    out = tmp_path / "html"
    argv = ["benchmark", str(split), "--methods", "raw", "pfd-b", "--samples", "1"]
    assert main([*argv, "--html", str(out), "--real", str(recording)]) == 0
    assert "\r" not in capsys.readouterr().err  # no progress bar written into a log
    png = out / "real_night drive.png"
    text = (out / "index.html").read_text(encoding="utf-8")
    assert 'id="real-title"' in text and 'src="real_night drive.png"' in text
    counts = text[text.index("night drive.h5: events per stream") :].split("</figcaption>")[0]
    n = scene.observed.size
    assert f"input {n:,}, raw {n:,}, pfd-b " in counts
    assert int(counts.split("pfd-b ")[1].rstrip(".").replace(",", "")) < n  # flare removed
    image = np.asarray(Image.open(png))
    assert image.shape[1] >= 4 * SIZE[0]  # input events, then input, raw and pfd-b
    assert main([*argv, "--real", str(recording)]) == 1
    assert "--real shows recordings in the HTML report" in capsys.readouterr().err
    twin = tmp_path / "elsewhere" / recording.name  # the same name in another folder
    twin.parent.mkdir()
    write_dsec_groups(twin, {"events": scene.clean}, SIZE, SPAN)
    again = tmp_path / "html2"
    assert main([*argv, "--html", str(again), "--real", str(recording), str(twin)]) == 0
    text = (again / "index.html").read_text(encoding="utf-8")
    assert 'src="real_night drive.png"' in text and 'src="real_night drive_2.png"' in text
    assert f"input {scene.clean.size:,}," in text  # the twin's own figure and counts


def test_reconstruct_recording_on_a_real_flare_recording(real_data):
    from edeflare.eval.downstream import reconstruct_recording
    from edeflare.events import window_start_for
    from edeflare.io import read_events

    r = reconstruct_recording(
        real_data / "davis346_flicker_lamps.aedat4", {"model": "model", "raw": "raw"}
    )
    assert r.columns == ["input events", "input", "model", "raw"]
    assert r.events["raw"] == r.events["input"] == 117_667  # the whole 130 ms recording
    assert 0.5 * r.events["input"] < r.events["model"] < r.events["input"]  # flare removed
    events, _ = read_events(real_data / "davis346_flicker_lamps.aedat4")
    start = window_start_for(int(events["t"][0]), 20_000)  # aligned 20 ms windows
    assert r.span_us == (start, start + 20_000 * ((int(events["t"][-1]) + 1 - start) // 20_000))
    assert r.image.dtype == np.uint8 and r.image.shape[2] == 3
