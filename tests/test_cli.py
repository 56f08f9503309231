"""The ``edeflare`` command: real outputs, one-line errors, non-zero exits, nothing half-written."""

from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import torch
from PIL import Image

from conftest import kill_at_random_moments, random_events, same_events
from edeflare.cli import EXIT_INTERNAL, main
from edeflare.errors import EventFileError
from edeflare.events import make_events
from edeflare.io import read_events, write_events


@pytest.fixture
def small_h5(tmp_path, rng):
    events = random_events(rng, 5000, (64, 48), t0=1_000_000, span_us=100_000)
    path = tmp_path / "in.h5"
    write_events(path, events, (64, 48))
    return path, events


def test_info_reports_exact_figures(tmp_path, capsys):
    ev = make_events([1000, 2000, 3000, 11_000], [0, 1, 2, 3], [0, 0, 0, 0], [1, 1, 1, 0])
    path = tmp_path / "a.npz"
    write_events(path, ev, (4, 1))
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "numpy npz" in out
    assert "4x1 (file)" in out
    assert "events      4" in out
    assert "span        10.000 ms" in out
    assert "rate        0.000 Mev/s" in out  # 4 events / 10 ms = 400 ev/s
    assert "ON fraction 0.7500" in out


def test_info_prints_a_weights_files_card(tmp_path, capsys):
    from safetensors.torch import save_file

    from edeflare.models import create_model
    from edeflare.models.weights import ModelCard, save_model

    assert main(["info", "night"]) == 0  # a bundled model, by name
    out = capsys.readouterr().out
    assert "preset      mask.pixel (8 bins, 20 ms windows)" in out
    assert "rule halo   halo_shift 3\n" in out and "rule streak streak_shift 8\n" in out
    assert (
        "rule light-free light_free_shift 4, light_free_support 2, light_free_crowding 3, "
        "scatter_shift 4\n"
    ) in out
    assert "keep        probability > 0.4" in out
    assert "score_davis_lamps_combined 0.872" in out
    assert main(["info", "firenet"]) == 0  # the bundled reconstructor's card
    out = capsys.readouterr().out
    assert "model       reconstructor (5 bins, 16 features, 20 ms windows)" in out
    assert "ratio       0.89" in out and "command     python -m edeflare.recon.train" in out
    path = tmp_path / "m.safetensors"
    save_model(path, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny", seed=3))
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "preset      unet2d.tiny (8 bins, 20 ms windows)" in out and "priors" not in out
    ens = tmp_path / "ens.safetensors"  # a mask model with an ensemble of context heads
    head = {"features": ["net_logit"], "hidden": [4], "members": 3,
            "context": {"channels": 2, "inputs": 33, "widths": [4, 8]}}  # fmt: skip
    save_model(ens, create_model("mask.lite"), ModelCard(preset="mask.lite", head=head))
    assert main(["info", str(ens)]) == 0
    out = capsys.readouterr().out
    assert "head        learned: 1 features, hidden 4\n" in out
    assert "context     2 maps of 33 cell channels, U-Net widths 4, 8\n" in out
    assert "members     3 heads, their mean keep logit\n" in out
    bare = tmp_path / "bare.safetensors"  # tensors, but no card
    save_file({"w": torch.zeros(2)}, str(bare))
    assert main(["info", str(bare)]) == 1
    assert f"{bare}: no edeflare model card in the metadata" in capsys.readouterr().err


def test_info_sensor_size_option_and_inference_warning(tmp_path, capsys):
    path = tmp_path / "a.txt"
    path.write_text("0 3 1 1\n5 7 2 0\n")
    assert main(["info", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "8x3 (inferred)" in out
    # warnings at the command line are one line each
    (line,) = err.strip().splitlines()
    assert line.startswith("edeflare: warning: ") and "no sensor size recorded; using 8x3" in line
    assert main(["info", str(path), "--sensor-size", "640x480"]) == 0
    assert "640x480 (option)" in capsys.readouterr().out


def test_convert_round_trip_and_centre_crop(small_h5, tmp_path, capsys):
    path, events = small_h5
    out = tmp_path / "out.raw"
    assert main(["convert", str(path), str(out)]) == 0
    back, size = read_events(out)
    assert size == (64, 48) and same_events(back, events)
    cropped = tmp_path / "crop.npz"
    assert main(["convert", str(path), str(cropped), "--crop", "32x24"]) == 0
    got, size = read_events(cropped)
    keep = (events["x"] >= 16) & (events["x"] < 48) & (events["y"] >= 12) & (events["y"] < 36)
    assert size == (32, 24)
    assert np.array_equal(got["x"], events["x"][keep] - 16)
    assert np.array_equal(got["y"], events["y"][keep] - 12)
    assert np.array_equal(got["t"], events["t"][keep])
    assert f"wrote {keep.sum():,} events (32x24)" in capsys.readouterr().out


def test_convert_rectangle_crop_and_time_range(small_h5, tmp_path):
    path, events = small_h5
    out = tmp_path / "out.h5"
    argv = [
        "convert",
        str(path),
        str(out),
        "--crop",
        "10,5,20,10",
        "--start-ms",
        "20",
        "--end-ms",
        "50",
    ]
    assert main(argv) == 0
    got, size = read_events(out)
    t = events["t"]
    t0 = t[0]  # times are relative to the recording's first event
    keep = (
        (t >= t0 + 20_000)
        & (t < t0 + 50_000)
        & (events["x"] >= 10)
        & (events["x"] < 30)
        & (events["y"] >= 5)
        & (events["y"] < 15)
    )
    assert size == (20, 10)
    assert np.array_equal(got["t"], t[keep])
    assert np.array_equal(got["x"], events["x"][keep] - 10)


def test_view_png_gif_mp4(small_h5, tmp_path, capsys):
    path, _ = small_h5
    png = tmp_path / "v.png"
    assert main(["view", str(path), "-o", str(png), "--count", "3", "--window-ms", "10"]) == 0
    assert "wrote 3 window(s) of 10 ms" in capsys.readouterr().out
    with Image.open(png) as im:
        assert im.size[0] >= 3 * 64  # three frames side by side
    gif = tmp_path / "v.gif"
    assert main(["view", str(path), "-o", str(gif), "--count", "4"]) == 0
    with Image.open(gif) as im:
        assert im.n_frames == 4
    mp4 = tmp_path / "v.mp4"
    assert main(["view", str(path), "-o", str(mp4), "--count", "2"]) == 0
    assert mp4.stat().st_size > 0


def test_demo_writes_everything(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    events = summary["events"]
    assert events["input"] > events["ground_truth"] > 0
    for name in (
        "input.h5",
        "ground_truth.h5",
        "raw.h5",
        "pfd-b.h5",
        "comparison.png",
        "comparison.gif",
        "voxels.png",
        "metrics.md",
        "metrics.json",
    ):
        assert (out / name).stat().st_size > 0
    inp, size = read_events(out / "input.h5")
    assert size == (346, 260) and inp.size == events["input"]
    raw, _ = read_events(out / "raw.h5")
    assert raw.size == inp.size  # the raw row is the input itself
    table = json.loads((out / "metrics.json").read_text())
    values = table["values"]
    assert set(values) == {
        "raw", "voxel", "efr", "pfd-a", "pfd-b", "night", "eflare", "dv-fastdecay"
    }  # fmt: skip
    for name, row in values.items():  # every metric a real number in its range
        assert all(math.isfinite(v) for v in row.values()), name
        assert 0 <= row["r_f1"] <= 1 and row["chamfer"] > 0 and row["mse"] >= 0
        assert read_events(out / f"{name}.h5").events.size == events[name]
    # The scene has flare to remove (15 % of its events): the default model removes it
    # and keeps most of the rest; on the paper's metrics it beats the input.
    model, flare = values["night"], values["raw"]
    assert model["chamfer"] < 0.1 * flare["chamfer"] and model["mse"] < flare["mse"]
    key = lambda e: ((e["t"].astype(np.int64) * 512 + e["x"]) * 512 + e["y"]) * 2 + e["p"]  # noqa: E731
    gt = read_events(out / "ground_truth.h5").events
    is_gt = np.isin(key(inp), key(gt))
    kept = np.isin(key(inp), key(read_events(out / "night.h5").events))
    assert (~is_gt).mean() > 0.1  # flare to remove: 15 %
    assert 1 - kept[~is_gt].mean() > 0.95 and kept[is_gt].mean() > 0.8  # 98.0 %, 90.7 %
    # the same shares, in the summary and the table (the input itself removes nothing)
    assert summary["flare_removed"]["night"] == round(1 - kept[~is_gt].mean(), 4)
    assert summary["true_kept"]["night"] == round(kept[is_gt].mean(), 4)
    assert summary["flare_removed"]["raw"] == 0.0 and summary["true_kept"]["raw"] == 1.0
    shares_row = f"| night | {100 * (1 - kept[~is_gt].mean()):.1f} % |"
    assert shares_row in (out / "metrics.md").read_text()
    assert events["pfd-b"] < events["input"] and events["efr"] < events["input"]
    assert "| night |" in (out / "metrics.md").read_text()
    assert summary["scene"]["sensor_size"] == [346, 260]
    assert not [p.name for p in out.iterdir() if ".partial" in p.name]
    assert str(out) in capsys.readouterr().out


def test_demo_fails_loudly_without_its_model(tmp_path, monkeypatch, capsys):
    import edeflare.models.infer as infer

    def missing():
        raise EventFileError("edeflare/assets/model.safetensors", "no such file")

    monkeypatch.setattr(infer, "bundled_weights", missing)
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 1
    err = capsys.readouterr().err
    assert "needs the bundled default weights" in err and err.count("\n") == 1
    assert not (tmp_path / "demo" / "metrics.json").exists()


def test_internal_errors_show_the_traceback_and_ask_for_a_report(monkeypatch, capsys):
    import edeflare.cli.info as info

    def broken(args):
        raise IndexError("index 5 is out of bounds")

    monkeypatch.setattr(info, "run", broken)
    assert main(["info", "any.h5"]) == EXIT_INTERNAL
    err = capsys.readouterr().err
    assert "Traceback" in err and "IndexError: index 5 is out of bounds" in err
    assert "this is a bug" in err.splitlines()[-1] and "report it" in err


def _wrapped(error: Exception) -> Exception:
    """``error`` raised while handling a KeyboardInterrupt (as compiled code reports one)."""
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise error  # noqa: B904 - the implicit context is the point
    except Exception as exc:
        return exc


@pytest.mark.parametrize("command", ["info", "simulate"])
@pytest.mark.parametrize(
    "error",
    [
        KeyboardInterrupt(),
        _wrapped(SystemError("returned a result with an exception set")),
        _wrapped(EventFileError("x.h5", "cannot write")),
    ],
    ids=["plain", "system-error", "edeflare-error"],
)
def test_an_interrupt_is_one_line_and_exit_130(monkeypatch, capsys, command, error):
    import edeflare.cli.info as info
    import edeflare.cli.simulate as simulate

    def interrupted(args):
        raise error

    module = {"info": info, "simulate": simulate}[command]
    monkeypatch.setattr(module, "run", interrupted)
    assert main([command, "x.h5"]) == 130
    resume = "; rerun to resume" if command == "simulate" else ""  # simulate resumes
    assert capsys.readouterr().err == f"edeflare: interrupted{resume}\n"


def test_warnings_are_one_line_and_resource_warnings_stay_hidden(monkeypatch, capsys):
    """A command's warning is one line; a ResourceWarning (a file left to the collector,
    as a Ctrl-C between open() and its with-block leaves one) is not shown."""
    import warnings

    from edeflare.cli import info

    def run(args):
        warnings.warn("unclosed file <_io.BufferedReader>", ResourceWarning, stacklevel=1)
        warnings.warn("no sensor size recorded", UserWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(info, "run", run)
    assert main(["info", "x.h5"]) == 0
    assert capsys.readouterr().err == "edeflare: warning: no sensor size recorded\n"


@pytest.mark.filterwarnings("default")
@pytest.mark.parametrize("suffix", [".h5", ".csv"])
def test_view_and_convert_times_are_relative_to_the_recording(tmp_path, capsys, suffix):
    """A recording starting at 11.2 s: --start-ms 50 means 11.25 s; 5000 is past its end."""
    t = np.arange(11_200_000, 11_400_000, 100)
    path = tmp_path / f"rec{suffix}"
    write_events(path, make_events(t, t % 7, t % 5, t % 2), (8, 8))
    out = tmp_path / "cut.h5"
    assert main(["convert", str(path), str(out), "--start-ms", "50", "--end-ms", "60"]) == 0
    got = read_events(out).events["t"]
    assert got[0] == 11_250_000 and got[-1] == 11_259_900 and got.size == 100
    assert "warning" not in capsys.readouterr().err
    assert main(["convert", str(path), str(out), "--start-ms", "5000"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("edeflare: warning: ") and err.count("\n") == 1
    assert "5000 ms on lies outside the recording" in err and "0-199.9 ms" in err
    png = tmp_path / "v.png"
    assert main(["view", str(path), "-o", str(png), "--start-ms", "40", "--count", "2"]) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err and "wrote 2 window(s) of 20 ms (40-80 ms)" in captured.out
    with Image.open(png) as im:
        assert np.asarray(im.convert("RGB")).std() > 0  # events drawn
    assert main(["view", str(path), "-o", str(png), "--start-ms", "5000"]) == 0
    assert "the window 5000-5020 ms lies outside the recording" in capsys.readouterr().err
    # by default the first window starts at the first event (11.2 s is not a multiple
    # of 30 ms, so an aligned window would start 10 ms before it)
    assert main(["view", str(path), "-o", str(png), "--window-ms", "30"]) == 0
    assert "wrote 1 window(s) of 30 ms (0-30 ms)" in capsys.readouterr().out


def test_view_and_convert_help_say_times_are_relative(capsys):
    for command in ("view", "convert"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "relative to the recording's start" in text and "not absolute" in text


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["info", "missing.h5"], "missing.h5: no such file"),
        (["info", "x.unknown"], "unknown event file suffix '.unknown'"),
        (["view", "in.h5", "-o", "out.bmp"], "output must be .png"),
    ],
)
def test_user_errors_print_one_line_and_exit_1(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    write_events(tmp_path / "in.h5", make_events([0], [0], [0], [1]), (2, 2))
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("edeflare: error: ") and message in err
    assert err.count("\n") == 1


def test_convert_error_leaves_no_output(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x,y,p\n10,1,1,1\n5,1,1,0\n")  # unsorted
    out = tmp_path / "out.h5"
    assert main(["convert", str(bad), str(out), "--sensor-size", "4x4"]) == 1
    assert "not sorted" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_bad_option_values_are_one_line_exit_1(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["info", "a.h5", "--sensor-size", "640by480"])
    assert exc.value.code == 1
    assert capsys.readouterr().err == (
        "edeflare: error: argument --sensor-size: sensor size must look like 640x480, "
        "got '640by480' (see edeflare info --help)\n"
    )


def parser_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """The one line a usage error prints (the exit status checked: 1, as every user error)."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith("\n")
    return err.rstrip("\n")


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (
            ["deflare", "in.h5", "out.h5", "--keep-treshold", "0.5"],
            "unrecognized option --keep-treshold; did you mean --keep-threshold? "
            "(see edeflare deflare --help)",
        ),
        (
            ["deflare", "in.h5", "out.h5", "-m", "efr", "--efr-merg-ms=5"],
            "unrecognized option --efr-merg-ms; did you mean --efr-merge-ms? "
            "(see edeflare deflare --help)",
        ),
        (
            ["simulate", "--sequnces", "4", "data"],
            "unrecognized option --sequnces; did you mean --sequences? "
            "(see edeflare simulate --help)",
        ),
        (  # an option of another command: nothing close in this one
            ["simulate", "data", "--keep-threshold", "0.5"],
            "unrecognized option --keep-threshold (see edeflare simulate --help)",
        ),
        (["info", "a.h5", "b.h5"], "unrecognized arguments: b.h5 (see edeflare info --help)"),
    ],
)
def test_an_unknown_option_is_named_with_the_closest_one(argv, line, capsys):
    assert parser_error(argv, capsys) == f"edeflare: error: {line}"


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (
            ["deflare"],
            "the following arguments are required: IN, OUT (see edeflare deflare --help)",
        ),
        (
            ["deflare", "a.h5", "b.h5", "--window-ms", "fast"],
            "argument --window-ms: invalid float value: 'fast' (see edeflare deflare --help)",
        ),
        (
            ["simulate", "data", "--variant", "nope"],
            "argument --variant: invalid choice: 'nope' (choose from 'physical', 'simple', "
            "'simple+random', 'physical+random', 'no-light', 'forward') "
            "(see edeflare simulate --help)",
        ),
        ([], "the following arguments are required: COMMAND (see edeflare --help)"),
    ],
)
def test_parser_errors_read_like_every_other_error(argv, line, capsys):
    assert parser_error(argv, capsys) == f"edeflare: error: {line}"


def test_a_folder_given_as_an_event_file_is_called_a_folder(small_h5, tmp_path, capsys):
    path, _ = small_h5
    folder = tmp_path / "recordings"
    folder.mkdir()
    assert main(["info", str(folder)]) == 1
    assert capsys.readouterr().err == f"edeflare: error: {folder}: is a folder, not an event file\n"
    assert main(["deflare", str(folder), str(tmp_path / "o.h5")]) == 1  # a folder of inputs
    assert capsys.readouterr().err == (
        f"edeflare: error: {tmp_path / 'o.h5'} names an event file, but the outputs of "
        "several inputs go to a folder: name a folder\n"
    )
    assert main(["convert", str(path), str(folder)]) == 1  # an output folder too
    assert capsys.readouterr().err == f"edeflare: error: {folder}: is a folder, not an event file\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.h5", "recordings"]
    assert not list(folder.iterdir())


@pytest.mark.parametrize(
    ("options", "line"),
    [
        (["--keep-threshold", "-3"], "--keep-threshold must be in (0, 1), got -3.0"),
        (["--batch-windows", "0"], "--batch-windows must be a positive int, got 0"),
        (
            ["-m", "efr", "--efr-merge-ms", "-5"],
            "--efr-merge-ms must be >= 0, got -5000 (in µs; --efr-merge-ms takes ms)",
        ),
        (
            ["-m", "efr", "--efr-frequency", "1e6"],
            "--efr-frequency=1000000.0 is too high: the delay d2 = d1/10 must be >= 1 µs "
            "(use at most 100000 Hz)",
        ),
        (
            ["-m", "voxel", "--voxel-bins", "100000"],
            "--voxel-window-ms (20000) must be at least --voxel-bins (100000) "
            "(in µs; --voxel-window-ms takes ms)",
        ),
        (["-m", "pfd-b", "--pfd-fifo-size", "300"], "--pfd-fifo-size must be at most 255, got 300"),
    ],
)
def test_value_errors_name_the_option_not_the_parameter(small_h5, tmp_path, capsys, options, line):
    path, _ = small_h5
    out = tmp_path / "out.h5"
    assert main(["deflare", str(path), str(out), *options]) == 1
    assert capsys.readouterr().err == f"edeflare: error: {line}\n"
    assert not out.exists()


def test_a_commands_own_options_are_named_too(tmp_path, capsys):
    out = tmp_path / "data"
    assert main(["simulate", str(out), "--workers", "0"]) == 1
    assert capsys.readouterr().err == "edeflare: error: --workers must be an int >= 1, got 0\n"
    assert main(["simulate", str(out), "--duration-ms", "-5"]) == 1
    assert capsys.readouterr().err == (
        "edeflare: error: --duration-ms must be an int >= 0, got -5000 "
        "(in µs; --duration-ms takes ms)\n"
    )
    assert not out.exists()


def test_parameter_names_map_to_the_options_of_the_method_run():
    from edeflare.cli import _subcommand, build_parser
    from edeflare.cli._common import user_message
    from edeflare.errors import EventFileError, ParameterError

    parser = build_parser()
    deflare = _subcommand(parser, "deflare")
    exc = ParameterError("window_us must be an int >= 1, got 0")
    for method, flag in (("voxel", "--voxel-window-ms"), ("pfd-a", "--pfd-window-ms")):
        args = parser.parse_args(["deflare", "a.h5", "b.h5", "-m", method])
        assert user_message(exc, args, deflare) == (
            f"{flag} must be an int >= 1, got 0 (in µs; {flag} takes ms)"
        )
    args = parser.parse_args(["deflare", "a.h5", "b.h5", "-m", "efr"])
    assert user_message(exc, args, deflare) == (  # efr has none: deflare's own --window-ms
        "--window-ms must be an int >= 1, got 0 (in µs; --window-ms takes ms)"
    )
    # words, paths and quoted values that spell a parameter stay as they are
    said = ParameterError("bias must hold finite numbers, see /data/bias/threshold.npy or 'rho1'")
    assert user_message(said, args, deflare) == (
        "--efr-bias must hold finite numbers, see /data/bias/threshold.npy or 'rho1'"
    )
    simulate = _subcommand(parser, "simulate")
    args = parser.parse_args(["simulate", "data"])
    plain = ParameterError("sequences must be >= 1; the seed of the sequences, not workers")
    assert user_message(plain, args, simulate) == (
        "--sequences must be >= 1; the seed of the sequences, not workers"
    )
    file_error = EventFileError("seed/workers.h5", "workers must be ...")  # not a parameter's
    assert user_message(file_error, args, simulate) == "seed/workers.h5: workers must be ..."


def test_console_script_runs_without_traceback(tmp_path):
    exe = shutil.which("edeflare") or str(
        __import__("pathlib").Path(sys.executable).with_name("edeflare")
    )
    done = subprocess.run([exe, "info", str(tmp_path / "nope.raw")], capture_output=True, text=True)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().endswith("nope.raw: no such file")


def test_group_option_opens_one_stream_of_a_paired_file(tmp_path, capsys, rng):
    from edeflare.io.dsec import write_dsec_groups

    inp = random_events(rng, 300, (16, 12), t0=0, span_us=40_000)
    gt = inp[::3]
    path = tmp_path / "seq.h5"
    write_dsec_groups(path, {"input": inp, "gt": gt}, (16, 12))
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err
    assert "several event groups" in err and "--group" in err and "'gt'" in err
    assert main(["info", str(path), "--group", "gt"]) == 0
    assert "events      100" in capsys.readouterr().out
    out = tmp_path / "gt.npz"
    assert main(["convert", str(path), str(out), "--group", "gt"]) == 0
    assert same_events(read_events(out).events, gt)
    clean = tmp_path / "clean.npz"
    assert main(["deflare", str(path), str(clean), "-m", "raw", "--group", "input/events"]) == 0
    assert same_events(read_events(clean).events, inp)
    assert main(["info", str(out), "--group", "gt"]) == 1
    assert "applies to HDF5 files only" in capsys.readouterr().err
    assert main(["info", str(path), "--group", "nope"]) == 1
    assert "no event group 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("option", ["--ghost-shift", "--halo-shift"])
def test_deflare_prior_shift_drops_a_subset_and_a_bad_one_is_a_clear_error(
    option, tmp_path, capsys
):
    size = (64, 64)
    # a light in the top-left cell (0.78 events per pixel and ms, over the lights' core
    # rate); sparse events around it and beyond
    k = np.arange(1000)
    light = make_events(k * 20, k % 8, k // 8 % 8, np.ones(1000))
    rng = np.random.default_rng(3)
    sparse = random_events(rng, 200, size, t0=0, span_us=20_000)
    src = tmp_path / "in.h5"
    write_events(src, np.sort(np.concatenate([light, sparse]), order="t"), size)
    plain, shifted = tmp_path / "plain.h5", tmp_path / "shifted.h5"
    # the other prior off, so this one alone makes the difference
    other = ["--ghost-shift" if option == "--halo-shift" else "--halo-shift", "0"]
    assert main(["deflare", str(src), str(plain), option, "0", *other]) == 0
    assert main(["deflare", str(src), str(shifted), option, "50", *other]) == 0
    a, b = read_events(plain).events, read_events(shifted).events
    assert np.isin(b, a).all() and len(b) < len(a)  # it only drops, and drops more
    capsys.readouterr()
    assert main(["deflare", str(src), str(tmp_path / "x.h5"), option, "-1"]) == 1
    assert capsys.readouterr().err == (
        f"edeflare: error: {option} must be a finite number >= 0, got -1.0\n"
    )
    assert not (tmp_path / "x.h5").exists()


def test_deflare_verbose_prints_speed_latency_and_memory(small_h5, tmp_path, capsys):
    path, events = small_h5
    assert main(["deflare", str(path), str(tmp_path / "o.h5"), "-m", "voxel", "-v"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("voxel: 5,000 events in")
    span_s = (int(events["t"][-1]) - int(events["t"][0])) / 1e6
    assert f"for {span_s:.3f} s of events (real-time factor" in lines[1]
    numbers = re.search(r"median ([\d.]+) ms, p95 ([\d.]+) ms, max ([\d.]+) ms", lines[1])
    assert numbers is not None
    p50, p95, worst = map(float, numbers.groups())
    assert 0 <= p50 <= p95 <= worst
    assert re.search(r"peak memory [\d,]+ MB$", lines[1])


@pytest.mark.slow
@pytest.mark.parametrize(
    "command",
    [
        ["deflare", "IN", "OUT", "-m", "pfd-a"],
        ["convert", "IN", "OUT"],
        ["deflare", "IN/", "OUT/", "-m", "pfd-a", "--workers", "2"],
    ],
    ids=["deflare", "convert", "deflare-batch"],
)
def test_runs_killed_at_random_moments_leave_no_partial_output_and_rerun_exactly(tmp_path, command):
    size = (640, 480)
    events = random_events(np.random.default_rng(8), 3_000_000, size, t0=0, span_us=3_000_000)
    batch = command[1] == "IN/"
    if batch:  # a folder of four recordings (two in a subfolder) into a folder
        src, out, reference = tmp_path / "rec", tmp_path / "out", tmp_path / "reference"
        for k, part in enumerate(np.array_split(events, 4)):
            write_events(src / ("night" if k % 2 else "") / f"r{k}.h5", part, size)
    else:
        src, out, reference = tmp_path / "in.h5", tmp_path / "out.npz", tmp_path / "reference.npz"
        write_events(src, events, size)
    args = [
        str(src) if a.startswith("IN") else str(out) if a.startswith("OUT") else a for a in command
    ]
    current = {"manifest.json": _manifest_holds_complete_outputs} if batch else None
    killed = kill_at_random_moments(args, out, reference, range(4), kept_current=current)
    assert killed >= 3  # most kills land before the end (start-up included)
    assert not [p.name for p in tmp_path.rglob("*") if ".partial" in p.name]  # rerun cleaned up
    if command[0] == "convert":
        assert same_events(read_events(out).events, events)


def _manifest_holds_complete_outputs(data: bytes, reference: bytes, finished: bool) -> None:
    """A batch manifest after a kill lists some of the straight run's outputs, each once;
    after the rerun all of them. (Times of writing differ: left out.)"""

    def entries(raw: bytes) -> list[str]:
        files = json.loads(raw)["files"]
        for e in files:
            del e["input"]["mtime_ns"], e["output"]["mtime_ns"]
        return [json.dumps(e, sort_keys=True) for e in files]

    got, want = entries(data), entries(reference)
    assert len(set(got)) == len(got) and set(got) <= set(want)
    if finished:
        assert got == want and json.loads(data)["complete"]
