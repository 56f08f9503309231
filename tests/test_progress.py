"""Progress bars: drawn on a terminal only, never into a log, a pipe or a captured stream."""

from __future__ import annotations

import io

import pytest

import edeflare._progress as progress_module
from conftest import random_events
from edeflare._progress import is_terminal, progress_bar
from edeflare.cli import main
from edeflare.io import write_events


class Terminal(io.StringIO):
    """A text stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_a_bar_is_drawn_on_a_terminal_only():
    log, tty = io.StringIO(), Terminal()
    for stream in (log, tty):
        with progress_bar(total=3, file=stream, desc="work", mininterval=0) as bar:
            for _ in range(3):
                bar.update(1)
    assert log.getvalue() == ""
    drawn = tty.getvalue()
    assert drawn.startswith("\rwork:   0%") and "\rwork: 100%" in drawn and "3/3" in drawn


def test_a_bar_turned_off_stays_off_on_a_terminal():
    tty = Terminal()
    assert list(progress_bar(range(3), file=tty, enabled=False, desc="work")) == [0, 1, 2]
    assert tty.getvalue() == ""
    assert list(progress_bar(range(3), file=tty, enabled=None, desc="work")) == [0, 1, 2]
    assert "work: 100%" in tty.getvalue()  # None: the terminal decides


def test_what_is_not_a_terminal():
    closed = io.StringIO()
    closed.close()
    with pytest.raises(ValueError):
        closed.isatty()
    assert not is_terminal(closed)
    assert not is_terminal(None) and not is_terminal(object())  # type: ignore[arg-type]
    assert is_terminal(Terminal()) and not is_terminal(io.StringIO())


def test_the_cli_bars_follow_the_terminal(tmp_path, rng, monkeypatch, capsys):
    src, out = tmp_path / "in.h5", tmp_path / "out.npz"
    write_events(src, random_events(rng, 2000, (32, 24), t0=0, span_us=50_000), (32, 24))
    assert main(["convert", str(src), str(out)]) == 0
    assert capsys.readouterr().err == ""  # captured: not a terminal, no bar
    monkeypatch.setattr(progress_module, "is_terminal", lambda stream: True)
    assert main(["convert", str(src), str(out)]) == 0
    assert "\r" in capsys.readouterr().err  # the same command on a terminal draws its bar


@pytest.mark.parametrize("enabled", [True, False])
def test_simulate_draws_no_bar_into_a_log(tmp_path, capsys, enabled):
    from edeflare.data.generate import Recipe, generate_dataset
    from edeflare.sim.background import SceneConfig

    recipe = Recipe(
        name="tiny",
        sequences=1,
        test_sequences=0,
        sensor_size=(32, 24),
        duration_us=20_000,
        scene=SceneConfig(fps=1000.0),
    )
    generate_dataset(recipe, tmp_path, progress=enabled)
    assert capsys.readouterr().err == ""
