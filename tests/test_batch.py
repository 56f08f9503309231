"""Batch de-flaring (edeflare.methods.batch, ``edeflare deflare FOLDER OUT``): outputs equal
one-file runs; workers, shards, resume by the manifest, failures, input discovery, SIGKILL."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import alive, random_events, same_events, sigkill_main_process
from edeflare.cli import main
from edeflare.errors import EventFileError, ParameterError
from edeflare.events import EVENT_DTYPE
from edeflare.io import read_events, write_events
from edeflare.methods import create_method, deflare_file
from edeflare.methods.batch import MANIFEST, BatchReport, FileResult, _identity, deflare_files

SIZE = (64, 48)
NAMES = ("a.h5", "night/b.raw", "night/deep/c.npz")  # three formats, two levels of subfolders
SRC = Path(__file__).resolve().parents[1] / "src"


def scene(rng: np.random.Generator, span_us: int = 120_000, t0: int = 1_000_000) -> np.ndarray:
    """A lamp (a dense 6x6 spot), a ring of scattered light around it, sparse background."""
    parts = [random_events(rng, 3_000, SIZE, t0=t0, span_us=span_us)]
    for n, (x0, x1, y0, y1) in ((6_000, (28, 34, 20, 26)), (1_500, (20, 44, 12, 36))):
        ev = np.empty(n, dtype=EVENT_DTYPE)
        ev["t"] = rng.integers(0, span_us, n) + t0
        ev["x"], ev["y"] = rng.integers(x0, x1, n), rng.integers(y0, y1, n)
        ev["p"] = rng.integers(0, 2, n)
        parts.append(ev)
    events = np.concatenate(parts)
    return events[np.argsort(events["t"], kind="stable")]


@pytest.fixture
def recordings(tmp_path, rng) -> Path:
    """``rec/`` with NAMES, each a different scene."""
    root = tmp_path / "rec"
    for name in NAMES:
        write_events(root / name, scene(rng), SIZE)
    return root


def out_name(name: str, suffix: str = ".h5") -> str:
    return str(Path(name).with_suffix(suffix))


def entries(folder: Path, manifest: str = MANIFEST) -> dict[str, dict]:
    """The manifest's entries by output name, without the files' modification times."""
    data = json.loads((folder / manifest).read_text())
    found = {}
    for e in data["files"]:
        e = json.loads(json.dumps(e))
        del e["input"]["mtime_ns"], e["output"]["mtime_ns"]
        found[e["output"]["file"]] = e
    return found


def partials(folder: Path) -> list[str]:
    return [p.name for p in folder.rglob("*") if ".partial" in p.name]


# ----------------------------------------------------------------------------- equal to one file


@pytest.mark.parametrize(
    ("method", "workers"),
    [("efr", 1), ("efr", 2), ("model", 1), ("model", 2)],
)
def test_batch_outputs_equal_one_file_runs_event_for_event(recordings, tmp_path, method, workers):
    report = deflare_files(recordings, tmp_path / "out", method, workers=workers, progress=False)
    assert [r.name for r in report.files] == sorted(out_name(n) for n in NAMES)
    assert [r.status for r in report.files] == ["done"] * 3 and report.complete
    m = create_method(method)
    for k, name in enumerate(NAMES):
        one = tmp_path / f"one_{k}.h5"
        stats = deflare_file(recordings / name, one, m, progress=False)
        batch = read_events(tmp_path / "out" / out_name(name)).events
        assert same_events(batch, read_events(one).events), name
        r = next(r for r in report.files if r.name == out_name(name))
        assert (r.events_in, r.events_out) == (stats.events_in, stats.events_out)
    assert 0 < sum(r.events_out for r in report.files) < sum(r.events_in for r in report.files)
    assert not partials(tmp_path / "out")


def test_one_progress_bar_counts_the_files_on_a_terminal(recordings, tmp_path, monkeypatch):
    import io

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    tty = Terminal()
    monkeypatch.setattr(sys, "stderr", tty)
    deflare_files(recordings, tmp_path / "out", "efr", workers=1)
    drawn = tty.getvalue()
    assert "efr: 100%" in drawn and "3/3" in drawn
    assert " ev" not in drawn and "first pass" not in drawn  # no bar per file
    tty.truncate(0)
    deflare_files(recordings, tmp_path / "again", "efr", progress=False)
    assert tty.getvalue() == ""


# ----------------------------------------------------------------------------- resume


def test_a_rerun_skips_complete_outputs_and_redoes_what_changed(recordings, tmp_path, rng):
    out = tmp_path / "out"
    deflare_files(recordings, out, "efr", progress=False)
    first = entries(out)
    times = {n: (out / out_name(n)).stat().st_mtime_ns for n in NAMES}
    again = deflare_files(recordings, out, "efr", progress=False)
    assert [r.status for r in again.files] == ["skipped"] * 3 and again.complete
    assert [r.events_out for r in again.files] == [
        first[out_name(n)]["events"]["out"] for n in NAMES
    ]
    assert {n: (out / out_name(n)).stat().st_mtime_ns for n in NAMES} == times  # untouched
    assert entries(out) == first

    # A copy with new times but the same bytes is recognised by its SHA-256, not redone.
    os.utime(recordings / NAMES[0], ns=(1, 1))
    os.utime(out / out_name(NAMES[1]), ns=(1, 1))
    status = {r.name: r.status for r in deflare_files(recordings, out, "efr", progress=False).files}
    assert set(status.values()) == {"skipped"}
    assert json.loads((out / MANIFEST).read_text())["files"][0]["input"]["mtime_ns"] == 1

    # A changed input, a deleted output, a damaged output (same size): those are redone.
    write_events(recordings / NAMES[0], scene(rng), SIZE)
    (out / out_name(NAMES[1])).unlink()
    damaged = out / out_name(NAMES[2])
    data = bytearray(damaged.read_bytes())
    data[-1] ^= 0xFF
    damaged.write_bytes(bytes(data))
    os.utime(damaged, ns=(2, 2))
    report = deflare_files(recordings, out, "efr", progress=False)
    assert [r.status for r in report.files] == ["done"] * 3
    for name in NAMES:
        expected = create_method("efr")(*read_events(recordings / name))
        assert same_events(read_events(out / out_name(name)).events, expected)
    assert entries(out)[out_name(NAMES[1])] == first[out_name(NAMES[1])]  # the same bytes again

    # Other parameters or run options make other outputs: every file is redone.
    report = deflare_files(recordings, out, "efr", params={"rho1": 0.5}, progress=False)
    assert [r.status for r in report.files] == ["done"] * 3
    assert {e["method"]["params"]["rho1"] for e in entries(out).values()} == {0.5}
    report = deflare_files(recordings, out, "efr", params={"rho1": 0.5}, rng=3, progress=False)
    assert [r.status for r in report.files] == ["done"] * 3
    report = deflare_files(recordings, out, "efr", params={"rho1": 0.5}, rng=3, progress=False)
    assert [r.status for r in report.files] == ["skipped"] * 3


def test_the_manifest_records_inputs_method_outputs_and_the_models_weights(recordings, tmp_path):
    from edeflare.io.sequence import file_sha256
    from edeflare.models.infer import resolve_weights

    out = tmp_path / "out"
    deflare_files(recordings / NAMES[0], out, "model", progress=False)
    data = json.loads((out / MANIFEST).read_text())
    assert data["format"] == "edeflare-deflare/1" and data["complete"] is True
    (entry,) = data["files"]
    assert entry["input"]["file"] == "a.h5"
    assert entry["input"]["sha256"] == file_sha256(recordings / "a.h5")
    assert entry["output"]["sha256"] == file_sha256(out / "a.h5")
    assert entry["output"]["bytes"] == (out / "a.h5").stat().st_size
    weights = entry["method"]["params"]["weights"]
    assert weights == {"file_sha256": file_sha256(resolve_weights(None))}  # not its path
    assert entry["method"]["name"] == "model" and entry["method"]["options"]["window_us"] == 20_000
    assert entry["events"]["in"] == read_events(recordings / "a.h5").events.size
    # Other weights are another method; the same weights elsewhere are the same.
    copy = tmp_path / "copy.safetensors"
    copy.write_bytes(Path(resolve_weights(None)).read_bytes())
    assert _identity(create_method("model", weights=copy), {}) == _identity(
        create_method("model"), {}
    )
    other = _identity(create_method("model", weights="eflare"), {})["params"]["weights"]
    assert other != weights


# ----------------------------------------------------------------------------- shards


def test_shards_split_the_sorted_files_and_together_make_the_whole_manifest(tmp_path, rng):
    names = [f"r{k:02d}.h5" for k in range(7)]
    for name in names:
        write_events(tmp_path / "rec" / name, scene(rng, span_us=30_000), SIZE)
    whole = deflare_files(tmp_path / "rec", tmp_path / "whole", "pfd-a", progress=False)
    out = tmp_path / "sharded"
    reports = [
        deflare_files(tmp_path / "rec", out, "pfd-a", shard=f"{i}/3", progress=False)
        for i in range(3)
    ]
    for i, report in enumerate(reports):
        assert [r.name for r in report.files] == names[i::3]  # index % n == i
        assert report.manifest_path == out / f"manifest.shard-{i}-of-3.json"
    assert [r.complete for r in reports] == [False, False, True]  # the last one merges
    assert entries(out) == entries(tmp_path / "whole")
    for name in names:
        assert (out / name).read_bytes() == (tmp_path / "whole" / name).read_bytes()
    # An unsharded rerun over the shards' folder finds every file complete.
    rerun = deflare_files(tmp_path / "rec", out, "pfd-a", progress=False)
    assert [r.status for r in rerun.files] == ["skipped"] * 7 and rerun.complete
    assert rerun == BatchReport(rerun.files, out, out / MANIFEST, True)
    assert [r.events_out for r in rerun.files] == [r.events_out for r in whole.files]
    with pytest.raises(ParameterError, match="shard i/n needs n >= 1 and 0 <= i < n, got 3/3"):
        deflare_files(tmp_path / "rec", out, "raw", shard="3/3")


# ----------------------------------------------------------------------------- failures


def test_a_failing_file_is_reported_and_the_others_go_on(recordings, tmp_path, capsys):
    (recordings / "night" / "broken.h5").write_bytes(b"not an HDF5 file")
    (tmp_path / "notes.evt").write_text("a format edeflare does not know")
    argv = ["deflare", str(recordings), str(tmp_path / "notes.evt"), str(tmp_path / "out")]
    assert main([*argv, "-m", "raw", "--no-progress"]) == 1
    captured = capsys.readouterr()
    errors = captured.err.splitlines()
    assert len(errors) == 2 and all(e.startswith("edeflare: error: ") for e in errors)
    assert any("broken.h5: not a readable HDF5 file" in e for e in errors)
    assert any("notes.evt: unknown event file suffix '.evt'" in e for e in errors)
    table = captured.out.splitlines()
    assert table[0] == "| file | events in | events out | seconds | status |"
    rows = {row.split(" | ")[0][2:]: row for row in table[2:-1]}
    assert rows["rec/night/broken.h5"].endswith("| - | - | 0.00 | failed |")
    assert rows["notes.h5"].endswith("| failed |")
    assert rows[f"rec/{out_name(NAMES[0])}"].endswith("| done |")
    assert table[-1].startswith("raw: 3 de-flared, 0 already done, 2 failed, of 5 files (")
    assert sorted(entries(tmp_path / "out")) == sorted(f"rec/{out_name(n)}" for n in NAMES)
    assert not json.loads((tmp_path / "out" / MANIFEST).read_text())["complete"]


def test_the_report_names_each_file_and_its_problem(recordings, tmp_path):
    (recordings / "zz.h5").write_bytes(b"")
    seen: list[FileResult] = []
    report = deflare_files(recordings, tmp_path / "out", "raw", on_file=seen.append, progress=False)
    assert seen == list(report.files) and len(report.done) == 3
    (bad,) = report.failed
    assert bad.name == "zz.h5" and bad.events_in is None and str(recordings / "zz.h5") in bad.error
    assert not report.complete and not (tmp_path / "out" / "zz.h5").exists()


# ----------------------------------------------------------------------------- inputs, outputs


def test_inputs_from_a_folder_a_glob_or_a_list_mirror_their_subfolders(recordings, tmp_path):
    (recordings / "notes.txt").write_text("text files come only by name or pattern")
    (recordings / ".hidden.h5").write_bytes(b"")
    (recordings / "night" / "timestamps.csv").write_text("t\n1\n")
    out = recordings / "clean"  # inside the input folder: not an input
    report = deflare_files(recordings, out, "raw", progress=False)
    assert [r.name for r in report.files] == sorted(out_name(n) for n in NAMES)
    rerun = deflare_files(recordings, out, "raw", progress=False)
    assert [r.name for r in rerun.skipped] == [r.name for r in report.files]

    globbed = deflare_files(str(recordings / "**" / "*.npz"), tmp_path / "g", "raw", progress=False)
    assert [r.name for r in globbed.files] == ["night/deep/c.h5"]  # root: the pattern's fixed part
    listed = deflare_files(
        [recordings / NAMES[1], recordings / NAMES[2]],
        tmp_path / "l",
        "raw",
        suffix=None,
        progress=False,
    )
    assert [r.name for r in listed.files] == ["b.raw", "deep/c.npz"]  # their common folder
    assert same_events(
        read_events(tmp_path / "l" / "b.raw").events, read_events(recordings / NAMES[1]).events
    )
    npz = deflare_files(recordings / "a.h5", tmp_path / "n", "raw", suffix="npz", progress=False)
    assert npz.files[0].output == tmp_path / "n" / "a.npz"


@pytest.mark.parametrize(
    ("setup", "kwargs", "error", "message"),
    [
        (None, {"inputs": "missing"}, EventFileError, "missing: no such file or folder"),
        (None, {"inputs": "rec/*.dat"}, EventFileError, r"\*.dat: no file matches this pattern"),
        ("empty", {"inputs": "empty"}, ParameterError, "no event files in empty"),
        ("clash", {}, ParameterError, "would both be written to out/a.h5"),
        (
            None,
            {"inputs": "rec/a.h5", "out_dir": "rec", "suffix": None},
            ParameterError,
            "would overwrite an input",
        ),
        (None, {"out_dir": "rec"}, ParameterError, "the input folder rec lies in the output"),
        (None, {"suffix": ".png"}, ParameterError, "suffix '.png' names no writable format"),
        (None, {"workers": 0}, ParameterError, "workers must be an int >= 1"),
        (None, {"shard": "1-2"}, ParameterError, "shard must look like 0/4"),
        (None, {"rng": np.random.default_rng(0)}, ParameterError, "rng must be an int seed"),
        (None, {"params": {"rho": 1}}, ParameterError, "method 'efr' has no parameter 'rho'"),
        ("file", {}, EventFileError, "out: is a file"),
        ("manifest", {}, EventFileError, "is a manifest of another kind"),
    ],
)
def test_bad_arguments_fail_before_any_output(
    recordings, monkeypatch, setup, kwargs, error, message
):
    monkeypatch.chdir(recordings.parent)
    if setup == "empty":
        Path("empty").mkdir()
    elif setup == "clash":
        write_events("rec/a.npz", scene(np.random.default_rng(0)), SIZE)
    elif setup == "file":
        Path("out").write_text("")
    elif setup == "manifest":
        Path("out").mkdir()
        Path("out/manifest.json").write_text('{"format": "edeflare-dataset/1", "files": []}')
    args = {"inputs": "rec", "out_dir": "out", "method": "efr", "progress": False, **kwargs}
    with pytest.raises(error, match=message):
        deflare_files(**args)
    assert not (Path("out").is_dir() and list(Path("out").rglob("*.h5")))


def test_a_method_object_runs_in_workers_unless_it_cannot_be_sent(recordings, tmp_path):
    efr = create_method("efr", frequency_hz=100)
    report = deflare_files(recordings, tmp_path / "out", efr, workers=2, progress=False)
    for name in NAMES:
        expected = efr(*read_events(recordings / name))
        assert same_events(read_events(tmp_path / "out" / out_name(name)).events, expected)
    used = create_method("model")
    used(*read_events(recordings / NAMES[0]))  # holds its loaded network now
    with pytest.raises(ParameterError, match="cannot be sent to worker processes"):
        deflare_files(recordings, tmp_path / "m", used, workers=2, progress=False)
    assert report.complete and not (tmp_path / "m").exists()


def test_cli_batch_options_apply_to_several_files_only(recordings, tmp_path, capsys):
    one = str(recordings / "a.h5")
    assert main(["deflare", one, str(tmp_path / "o.h5"), "-m", "raw", "--workers", "2"]) == 1
    assert "--workers apply to several files" in capsys.readouterr().err
    assert main(["deflare", str(recordings), str(tmp_path / "o"), "-m", "raw", "-v"]) == 1
    assert "-v applies to one file" in capsys.readouterr().err
    # A quoted pattern is expanded by edeflare; the shell's expansion (a list) works too.
    argv = ["deflare", str(recordings / "*.h5"), str(tmp_path / "o"), "-m", "raw", "--suffix"]
    assert main([*argv, "keep"]) == 0
    assert capsys.readouterr().out.splitlines()[2].startswith("| a.h5 | 10,500 | 10,500 | ")
    assert main(["deflare", one, str(recordings / NAMES[1]), str(tmp_path / "o"), "-m", "raw"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [row.split(" | ")[-1] for row in out[2:4]] == ["skipped |", "done |"]
    assert out[-1].endswith(f"all inputs complete; manifest {tmp_path / 'o' / MANIFEST}")


# ----------------------------------------------------------------------------- SIGKILL


_KILLED_RUN = """
import sys
from edeflare.methods.batch import deflare_files
deflare_files(sys.argv[1], sys.argv[2], "efr", workers=2, progress=False)
"""


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_a_batch_killed_with_sigkill_resumes_to_the_straight_runs_outputs(tmp_path, rng):
    names = [f"r{k:02d}.h5" for k in range(10)]
    for name in names:
        write_events(tmp_path / "rec" / name, scene(rng, span_us=60_000), SIZE)
    straight = deflare_files(tmp_path / "rec", tmp_path / "straight", "efr", progress=False)
    out = tmp_path / "killed"
    status, workers = sigkill_main_process(
        [sys.executable, "-c", _KILLED_RUN, str(tmp_path / "rec"), str(out)],
        tmp_path / "stderr.txt",
        lambda: len(list(out.glob("r*.h5"))) >= 2,
    )
    assert status == -signal.SIGKILL, (tmp_path / "stderr.txt").read_text()
    assert workers and not any(alive(w) for w in workers)
    assert not partials(out)  # a worker whose parent died deleted what it was writing
    done = sorted(p.name for p in out.glob("r*.h5"))
    assert 0 < len(done) < len(names)
    for name in done:  # complete files only, equal to the straight run's
        assert (out / name).read_bytes() == (tmp_path / "straight" / name).read_bytes()
    if (out / MANIFEST).exists():  # only complete outputs, none twice
        recorded = json.loads((out / MANIFEST).read_text())["files"]
        assert len({e["output"]["file"] for e in recorded}) == len(recorded)
        assert {e["output"]["file"] for e in recorded} <= set(done)
    resumed = deflare_files(tmp_path / "rec", out, "efr", workers=2, progress=False)
    assert resumed.complete and not resumed.failed
    assert {r.name for r in resumed.skipped} <= set(done)
    assert [r.events_out for r in resumed.files] == [r.events_out for r in straight.files]
    for name in names:
        assert (out / name).read_bytes() == (tmp_path / "straight" / name).read_bytes()
    assert entries(out) == entries(tmp_path / "straight")
    assert not partials(out)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_ctrl_c_stops_a_batch_with_workers_and_a_rerun_completes(tmp_path, rng):
    """Ctrl-C at a terminal (SIGINT to the process group) while files are being written."""
    names = [f"r{k:02d}.h5" for k in range(12)]
    for name in names:
        write_events(tmp_path / "rec" / name, scene(rng, span_us=400_000), SIZE)
    straight = tmp_path / "straight"
    deflare_files(tmp_path / "rec", straight, "efr", progress=False)
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "edeflare", "deflare", str(tmp_path / "rec"), str(out)]
    env = dict(os.environ, PYTHONPATH=str(SRC))
    proc = subprocess.Popen(
        [*argv, "-m", "efr", "--workers", "2"],
        env=env,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 120
    while not list(out.glob("r*.h5")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err.decode()
    assert "edeflare: interrupted; rerun to resume" in err.decode()
    assert not partials(out)  # the stopped workers' temporaries are gone
    assert 0 < len(list(out.glob("r*.h5"))) < len(names)
    rerun = subprocess.run([*argv, "-m", "efr"], env=env, capture_output=True)
    assert rerun.returncode == 0, rerun.stderr.decode()
    for name in names:
        assert (out / name).read_bytes() == (straight / name).read_bytes()
    assert entries(out) == entries(straight) and not partials(out)
