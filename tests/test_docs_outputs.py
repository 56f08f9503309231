"""The documentation shows what the code prints: the pages are the single source.

Every ``$ edeflare ...`` line of a ``console`` block in the pages below is rerun, and
what it prints must be the lines under it (``...`` stands for any lines; run times, which
vary, are masked on both sides). Python blocks followed by a ``text`` block must print
that text. The README's and the benchmarks page's tables of scores, the demo's shares
and the model cards' numbers are parsed from the pages and compared with fresh runs or
with the files they name. A change to the code that moves a number fails here until the
page is updated.

Pages that read the real recordings (``../shared/data/real``) skip without them, and
fail under ``$CI`` (``conftest.real_data_dir``). Runs of more than about 20 s are
``slow``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import re
import shlex
import warnings
from pathlib import Path

import pytest

from conftest import real_data_dir, strip_fences

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
ASSETS = ROOT / "src" / "edeflare" / "assets"


# --- reading the pages ------------------------------------------------------------------


@dataclasses.dataclass
class Step:
    """One command of a page (``kind`` "shell") or one Python block ("python")."""

    page: str
    line: int
    kind: str
    text: str
    expected: list[str] | None  # None: nothing to compare (a Python block without output)

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}"


def _fences(text: str) -> list[tuple[int, str, list[str]]]:
    """``(line, info, lines)`` of every fenced block."""
    blocks, lines = [], text.splitlines()
    i = 0
    while i < len(lines):
        m = re.match(r"^\s*(```|~~~)(\S*)", lines[i])
        if not m:
            i += 1
            continue
        start, fence, info, body = i + 1, m.group(1), m.group(2), []
        i += 1
        while i < len(lines) and not lines[i].lstrip().startswith(fence):
            body.append(lines[i])
            i += 1
        blocks.append((start, info, body))
        i += 1
    return blocks


def page_steps(rel: str, python: bool) -> list[Step]:
    """The page's console commands and (with ``python``) its Python blocks, in order."""
    text = (ROOT / rel).read_text(encoding="utf-8")
    blocks = _fences(text)
    steps = []
    for k, (line, info, body) in enumerate(blocks):
        if info == "console":
            current = None
            for j, row in enumerate(body):
                if row.startswith("$ "):
                    current = Step(rel, line + j + 1, "shell", row[2:], [])
                    steps.append(current)
                elif current is not None:
                    current.expected.append(row)
        elif info == "python" and python:
            follow = blocks[k + 1] if k + 1 < len(blocks) else None
            expected = None
            if (
                follow
                and follow[1] == "text"
                and _only_blank_between(text, line + len(body), follow[0])
            ):
                expected = follow[2]
            steps.append(Step(rel, line, "python", "\n".join(body), expected))
    return steps


def _only_blank_between(text: str, end_line: int, next_start: int) -> bool:
    lines = text.splitlines()[end_line + 1 : next_start - 1]
    return all(not row.strip() for row in lines)


# --- running them -----------------------------------------------------------------------

# Values that vary from run to run, masked on both sides before comparing.
_VOLATILE = [
    (re.compile(r"\(\d+(\.\d+)? s\)"), "(# s)"),  # simulate's wall time
    (re.compile(r"^(\d+,\d+,[^,]+,[^,]+),[\d.]+$"), r"\1,#"),  # train_log.csv: seconds
    (re.compile(r"(% \|.*)\| [\d.]+ \| [\d.]+ \|$"), r"\1| # | # |"),  # score: time, RTF
    (re.compile(r"^(\| [\w.-]+) \| [\d.]+ \| [\d.]+ \|$"), r"\1 | # | # |"),  # windows/s, RTF
    (re.compile(r"max \|onnx - torch\| = [\d.e+-]+"), "max |onnx - torch| = #"),
    # deflare FOLDER's table: seconds
    (re.compile(r"^(\| \S+ \| [\d,]+ \| [\d,]+) \| [\d.]+ \| done \|$"), r"\1 | # | done |"),
]


def _normalise(lines: list[str]) -> list[str]:
    out = []
    for row in lines:
        row = row.rstrip()
        for pattern, replacement in _VOLATILE:
            row = pattern.sub(replacement, row)
        out.append(row)
    while out and not out[-1]:
        out.pop()
    return out


# Decimal numbers (a point in them) in a page's output may differ from a run's by
# FLOAT_RTOL of their size plus one unit of their last printed digit: torch's CPU kernels
# differ by processor (AVX2, AVX-512, AMX), and a few training iterations carry a 1e-7
# difference to about 1 %. Integers (counts, iterations) and every other character must match.
FLOAT_RTOL = 0.02
_DECIMAL = re.compile(r"-?\d+\.\d+(?:e[+-]?\d+)?")


def _same_line(expected: str, actual: str) -> bool:
    if expected == actual:
        return True
    want, got = _DECIMAL.findall(expected), _DECIMAL.findall(actual)
    if len(want) != len(got) or _DECIMAL.sub("#", expected) != _DECIMAL.sub("#", actual):
        return False
    for w, g in zip(want, got, strict=True):
        mantissa, _, exponent = w.partition("e")
        unit = 10.0 ** (int(exponent or 0) - len(mantissa.partition(".")[2]))
        if abs(float(w) - float(g)) > FLOAT_RTOL * max(abs(float(w)), abs(float(g))) + unit:
            return False
    return True


def _same_lines(expected: list[str], actual: list[str]) -> bool:
    return len(expected) == len(actual) and all(map(_same_line, expected, actual))


def matches(expected: list[str], actual: list[str]) -> bool:
    """``actual`` is ``expected``, where a line ``...`` stands for any lines (decimal
    numbers within :data:`FLOAT_RTOL`)."""
    parts, part = [], []
    for row in expected:
        if row.strip() == "...":
            parts.append(part)
            part = []
        else:
            part.append(row)
    parts.append(part)
    if len(parts) == 1:
        return _same_lines(expected, actual)
    pos = 0
    for k, part in enumerate(parts):
        if not part:
            continue
        if k == 0:
            if not _same_lines(part, actual[: len(part)]):
                return False
            pos = len(part)
            continue
        last = k == len(parts) - 1
        starts = [len(actual) - len(part)] if last else range(pos, len(actual) - len(part) + 1)
        for s in starts:
            if s >= pos and _same_lines(part, actual[s : s + len(part)]):
                pos = s + len(part)
                break
        else:
            return False
    return True


def test_matches():
    assert matches(["a", "b"], ["a", "b"]) and not matches(["a"], ["a", "b"])
    assert matches(["loss 0.11886"], ["loss 0.11888"]) and matches(["| -0.5% |"], ["| -0.4% |"])
    assert not matches(["loss 0.118"], ["loss 0.125"]) and not matches(["n 100"], ["n 101"])
    assert not matches(["| *3.7289* |"], ["| 3.7271 |"]) and not matches(["1.5"], ["1.5 s"])
    assert matches(["...", "events 3", "..."], ["x", "events 3", "y"])
    assert not matches(["...", "events 3", "..."], ["x", "events 4", "y"])
    assert matches(["a", "...", "c"], ["a", "b", "b", "c"]) and not matches(
        ["a", "...", "c"], ["a"]
    )


def _edeflare(argv: list[str]) -> str:
    from edeflare.cli import main

    out = io.StringIO()
    with (
        contextlib.redirect_stdout(out),
        contextlib.redirect_stderr(out),
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("ignore")
        try:
            main(argv)
        except SystemExit:  # argparse's usage errors
            pass
    return out.getvalue()


def _shell(command: str) -> str:
    """The few shell commands the pages use besides edeflare."""
    if " | sort" in command:  # find DIR -type f | sort
        args = shlex.split(command.split(" | ")[0])
        assert args[0] == "find" and args[2:] == ["-type", "f"], command
        return "\n".join(sorted(str(p) for p in Path(args[1]).rglob("*") if p.is_file()))
    args = shlex.split(command)
    if args[0] == "edeflare":
        return _edeflare(args[1:])
    if args[0] == "head":
        n = int(args[1].lstrip("-"))
        return "\n".join(Path(args[2]).read_text().splitlines()[:n])
    if args[0] == "cat":
        return "".join(Path(a).read_text() for a in args[1:])
    if args[0] == "ls":
        return "  ".join(sorted(os.listdir(args[1])))
    raise AssertionError(f"the docs test cannot run {command!r}: add it to the page's skips")


def _python(code: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        exec(compile(code, "<docs>", "exec"), {"__name__": "__main__"})
    return out.getvalue()


class Workspace:
    """A folder where a page's steps run in order; each step runs once, when first needed."""

    def __init__(self, folder: Path, steps: list[Step], skip: dict[str, str]):
        self.folder, self.steps, self.skip = folder, steps, skip
        self.outputs: dict[str, str] = {}

    def output(self, step: Step) -> str:
        for earlier in self.steps[: self.steps.index(step) + 1]:
            if earlier.id in self.outputs or self.skipped(earlier):
                continue
            if earlier.id != step.id and earlier.text.startswith(SLOW_STEPS):
                continue  # a slow step's output is no later step's input
            cwd = Path.cwd()
            os.chdir(self.folder)
            try:
                run = _shell if earlier.kind == "shell" else _python
                self.outputs[earlier.id] = run(earlier.text)
            finally:
                os.chdir(cwd)
        return self.outputs[step.id]

    def skipped(self, step: Step) -> str | None:
        return next((why for key, why in self.skip.items() if step.text.startswith(key)), None)


def check(workspace: Workspace, step: Step) -> None:
    why = workspace.skipped(step)
    if why:
        pytest.skip(why)
    actual = _normalise(workspace.output(step).splitlines())
    if step.expected is None:
        return
    expected = _normalise(step.expected)
    assert matches(expected, actual), (
        f"{step.id}: `{step.text[:80]}` printed\n"
        + "\n".join(actual)
        + "\n\nwhere the page shows\n"
        + "\n".join(expected)
    )


def _link(folder: Path, name: str, target: Path) -> None:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists():
        path.symlink_to(target)


# --- the tutorials and reference pages ----------------------------------------------------

PROPHESEE = "docs/tutorials/deflare-prophesee.md"
DEFLARING = "docs/deflaring.md"
SIMULATE = "docs/tutorials/simulate-dataset.md"
TRAIN = "docs/tutorials/train-torchrun.md"
PAIRED = "docs/tutorials/paired-benchmark.md"
ABLATION = "docs/ablation.md"
EVALUATION = "docs/evaluation.md"

SKIPS = {
    SIMULATE: {
        "timeout ": "an interrupted run: its outcome depends on the machine's speed",
        "ls data/resume": "follows the interrupted run",
        "edeflare simulate data/resume": "follows the interrupted run",
    },
    TRAIN: {
        "torchrun ": "DDP runs: tests/test_train.py checks them",
        "cat runs/ddp": "follows a DDP run",
        "cat runs/multinode": "follows a DDP run",
        "...": "elided output",
    },
    PAIRED: {
        "edeflare pair scene02": "scene02 (a periodic strobe) is not made by the page's script",
        "mkdir -p pred": "a shell loop",
        "edeflare evaluate --gt bench/test/gt --pred raw=bench/test/input --pred pfd-a=pred": (
            "follows the shell loop"
        ),
    },
}


# Steps of the fast pages that take more than about 20 s on a loaded 2-core machine.
SLOW_STEPS = ("edeflare deflare rotating_light.raw paper.h5 --model eflare",)


def _steps(page: str, python: bool) -> list[Step]:
    return page_steps(page, python)


def _params(page: str, python: bool) -> list:
    return [
        pytest.param(
            step,
            id=step.id,
            marks=[pytest.mark.slow] if step.text.startswith(SLOW_STEPS) else [],
        )
        for step in page_steps(page, python)
    ]


@pytest.fixture(scope="module")
def prophesee(tmp_path_factory) -> Workspace:
    real = real_data_dir()
    folder = tmp_path_factory.mktemp("prophesee")
    _link(folder, "rotating_light.raw", real / "prophesee_gen3_rotating_light.raw")
    _link(folder, "street_gen4.raw", real / "prophesee_gen41_street.raw")
    _link(folder, "src", ROOT / "src")
    return Workspace(folder, _steps(PROPHESEE, python=True), SKIPS.get(PROPHESEE, {}))


@pytest.mark.parametrize("step", _params(PROPHESEE, python=True))
def test_prophesee_tutorial(prophesee, step):
    check(prophesee, step)


@pytest.fixture(scope="module")
def deflaring(tmp_path_factory) -> Workspace:
    real = real_data_dir()
    folder = tmp_path_factory.mktemp("deflaring")
    _link(folder, "lamps.aedat4", real / "davis346_flicker_lamps.aedat4")
    _link(folder, "src", ROOT / "src")
    return Workspace(folder, _steps(DEFLARING, python=False), {})


@pytest.mark.parametrize("step", _params(DEFLARING, python=False))
def test_deflaring_page(deflaring, step):
    check(deflaring, step)


@pytest.fixture(scope="module")
def datasets(tmp_path_factory) -> Path:
    """One folder for the simulation and training tutorials (training reads data/tiny)."""
    real = real_data_dir()
    folder = tmp_path_factory.mktemp("datasets")
    _link(folder, "street_cars.aedat4", real / "davis346_street_cars.aedat4")
    return folder


@pytest.fixture(scope="module")
def simulate(datasets) -> Workspace:
    return Workspace(datasets, _steps(SIMULATE, python=True), SKIPS[SIMULATE])


@pytest.fixture(scope="module")
def training(datasets, simulate) -> Workspace:
    simulate.output(_steps(SIMULATE, python=True)[0])  # data/tiny
    return Workspace(datasets, _steps(TRAIN, python=True), SKIPS[TRAIN])


@pytest.mark.slow
@pytest.mark.parametrize("step", _steps(SIMULATE, python=True), ids=lambda s: s.id)
def test_simulation_tutorial(simulate, step):
    check(simulate, step)


@pytest.mark.slow
@pytest.mark.parametrize("step", _steps(TRAIN, python=True), ids=lambda s: s.id)
def test_training_tutorial(training, step):
    check(training, step)


@pytest.fixture(scope="module")
def paired(tmp_path_factory) -> Workspace:
    folder = tmp_path_factory.mktemp("paired")
    return Workspace(folder, _steps(PAIRED, python=True), SKIPS[PAIRED])


@pytest.mark.slow
@pytest.mark.parametrize("step", _steps(PAIRED, python=True), ids=lambda s: s.id)
def test_paired_benchmark_tutorial(paired, step):
    check(paired, step)


@pytest.mark.slow
@pytest.mark.parametrize("step", _steps(ABLATION, python=False), ids=lambda s: s.id)
def test_ablation_page(tmp_path_factory, step):
    check(Workspace(tmp_path_factory.mktemp("ablation"), [step], {}), step)


@pytest.fixture(scope="module")
def evaluation(tmp_path_factory) -> Workspace:
    folder = tmp_path_factory.mktemp("evaluation")
    return Workspace(folder, _steps(EVALUATION, python=False), {})


@pytest.mark.slow
@pytest.mark.parametrize("step", _steps(EVALUATION, python=False), ids=lambda s: s.id)
def test_evaluation_page(evaluation, step):
    """The two conventions side by side on a simulated split."""
    check(evaluation, step)


def test_every_page_with_commands_is_checked():
    """A page that shows an `edeflare` command's output is in this module."""
    checked = {PROPHESEE, DEFLARING, SIMULATE, TRAIN, PAIRED, ABLATION, EVALUATION}
    for path in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        rel = str(path.relative_to(ROOT))
        shown = [s for s in page_steps(rel, python=False) if s.expected]
        assert not shown or rel in checked, f"{rel} shows command output no test checks"


# --- numbers in tables and prose -----------------------------------------------------------


def _section(text: str, heading: str) -> str:
    """The text under a heading, up to the next heading of the same or a higher level."""
    text = strip_fences(text)
    m = re.search(rf"^(#+) {re.escape(heading)}\s*$", text, re.M)
    assert m, f"no heading {heading!r}"
    level = len(m.group(1))
    end = re.compile(rf"^#{{1,{level}}} ", re.M).search(text, m.end())
    return text[m.end() : end.start() if end else len(text)]


def _rows(text: str) -> list[list[str]]:
    """The cells of every table row (header and rule rows left out)."""
    rows = []
    for line in text.splitlines():
        if line.startswith("|") and not re.match(r"^\|[-:| ]+\|$", line):
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows[1:] if rows else rows


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


@pytest.fixture(scope="module")
def real_scores(tmp_path_factory) -> dict[str, dict[str, dict]]:
    """``edeflare score`` of every method at four phases on both annotated recordings,
    as the benchmarks page's command runs it: {recording: {method: scores}}."""
    real = real_data_dir()
    folder = tmp_path_factory.mktemp("scores")
    scores = {}
    for name, suffix in (
        ("prophesee_gen3_rotating_light", ".raw"),
        ("davis346_flicker_lamps", ".aedat4"),
    ):
        rec = real / f"{name}{suffix}"
        eflare = folder / f"eflare_{name}.h5"
        _edeflare(["deflare", str(rec), str(eflare), "--model", "eflare"])
        out = folder / f"{name}.json"
        methods = ("raw", "efr", "pfd-a", "pfd-b", "dv-fastdecay", "dv-bafilter", "dv-knoise")
        methods += ("model",)
        argv = ["score", str(rec), "--lights", str(ASSETS / "lights" / f"{name}.json")]
        argv += [a for m in methods for a in ("-m", m)]
        argv += ["--pred", f"eflare={eflare}", "--phases", "4", "--json", str(out)]
        _edeflare(argv)
        scores[name] = {m["method"]: m for m in json.loads(out.read_text())["methods"]}
    return scores


def _score_cells(m: dict, background: bool) -> list[str]:
    cells = [_pct(m["flare_removed"]), _pct(m["light_kept"])]
    if background:
        cells.append(_pct(m["background_kept"]))
    return [*cells, f"{m['combined']:.3f}"]


_README_NAMES = {"night (default)": "model", "raw (input)": "raw"}


@pytest.mark.slow
def test_readme_table_is_todays(real_scores):
    """The README's one table: every method's scores on both recordings."""
    table = _rows(_section((ROOT / "README.md").read_text(), "Where the default stands"))
    assert len(table) >= 8
    for method, gen3, davis in table:
        name = _README_NAMES.get(method.replace("*", ""), method.replace("*", ""))
        g = _score_cells(real_scores["prophesee_gen3_rotating_light"][name], False)
        d = _score_cells(real_scores["davis346_flicker_lamps"][name], True)
        assert gen3.replace("*", "") == " / ".join(g), (method, gen3, g)
        assert davis.replace("*", "") == " / ".join(d), (method, davis, d)


@pytest.mark.slow
def test_benchmarks_real_tables_are_todays(real_scores):
    text = _section((DOCS / "benchmarks.md").read_text(), "Real recordings")
    tables = text.split("**DAVIS346 flickering lamps**")
    for name, part in zip(
        ("prophesee_gen3_rotating_light", "davis346_flicker_lamps"), tables, strict=True
    ):
        rows = _rows(part)
        assert {r[0] for r in rows} == set(real_scores[name]), name
        for row in rows:
            m = real_scores[name][row[0]]
            ghost = "-" if m["ghost_removed"] is None else _pct(m["ghost_removed"])
            worst = "-" if m["combined_worst"] is None else f"{m['combined_worst']:.3f}"
            want = [
                row[0], _pct(m["halo_removed"]), ghost, _pct(m["flare_removed"]),
                _pct(m["light_kept"]), _pct(m["background_kept"]), f"{m['combined']:.3f}",
                worst, f"{m['events_out']:,}",
            ]  # fmt: skip
            assert row == want, (name, row, want)


@pytest.mark.slow
def test_night_card_scores_are_todays(real_scores):
    text = (ASSETS / "night.md").read_text()
    rows = {r[0]: r for r in _rows(_section(text, "Evaluation"))}
    for label, name in (
        ("Prophesee Gen3 rotating light", "prophesee_gen3_rotating_light"),
        ("DAVIS346 flickering lamps", "davis346_flicker_lamps"),
    ):
        m, row = real_scores[name]["model"], rows[label]
        assert row[1:3] == [_pct(m["flare_removed"]), _pct(m["light_kept"])]
        scene = _pct(m["background_kept"]) if name.startswith("davis") else "-"
        assert row[3] == scene
        assert row[4] == f"{m['combined']:.3f} ({m['combined_worst']:.3f})"
        front = text.split("---")[1]
        assert f"{{type: combined, value: {m['combined']:.3f}}}" in front


SCENES = {
    "davis346_street_cars.aedat4": None,
    "davis346_lowlight_cradle.aedat4": None,
    "prophesee_gen41_street.raw": None,
}


def _scenes_table() -> dict[str, list[str]]:
    table = _rows(_section((DOCS / "benchmarks.md").read_text(), "Scenes without a bright light"))
    return {re.search(r"`([^`]+)`", row[0]).group(1): row[1:] for row in table}


def _kept(line: str) -> str:
    m = re.search(r"events in, [\d,]+ out \(([\d.]+)%\)", line)
    assert m, line
    return f"{m.group(1)} %"


@pytest.mark.parametrize("recording", sorted(SCENES))
def test_scenes_without_a_light_are_todays(recording, tmp_path):
    """benchmarks.md's table, the README's sentence and the index's limit."""
    real = real_data_dir()
    table = _scenes_table()
    default = _kept(_edeflare(["deflare", str(real / recording), str(tmp_path / "a.h5")]))
    fastdecay = _kept(
        _edeflare(["deflare", str(real / recording), str(tmp_path / "b.h5"), "-m", "dv-fastdecay"])
    )
    assert table[recording] == [default, fastdecay], (recording, table[recording])


def test_scenes_without_a_light_agree_across_pages():
    """The README and the index quote the benchmarks page's table, in its order."""
    table = _scenes_table()
    readme = " ".join((ROOT / "README.md").read_text().split())
    sentence = re.search(r"On recordings without a bright light.*?\)\.", readme).group(0)
    found = re.findall(r"[\d.]+ %", sentence)
    assert found == [v for row in table.values() for v in row], (sentence, table)
    limits = " ".join(_section((DOCS / "index.md").read_text(), "Limits").split())
    assert f"keeps {table['prophesee_gen41_street.raw'][0]} of the events" in limits


@pytest.mark.slow
def test_readme_demo_shares_are_todays(tmp_path):
    _edeflare(["demo", "--out", str(tmp_path / "demo")])
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text())
    readme = " ".join((ROOT / "README.md").read_text().split())
    m = re.search(
        r"removes ([\d.]+) % of the flare events and keeps ([\d.]+) % of the true", readme
    )
    assert m, "the README's demo sentence"
    removed, kept = summary["flare_removed"]["night"], summary["true_kept"]["night"]
    assert (m.group(1), m.group(2)) == (f"{100 * removed:.1f}", f"{100 * kept:.1f}")


# --- the model cards ---------------------------------------------------------------------

CARDS = ("night", "general", "learned", "learned-absolute", "eflare", "paper", "firenet")
PRESETS = {"night": "mask.pixel", "eflare": "unet2d.lite", "paper": "unet3d.paper"}


@pytest.mark.parametrize("name", CARDS)
def test_card_has_the_model_card_form(name):
    text = (ASSETS / f"{name}.md").read_text()
    assert len(text.splitlines()) <= 100, f"{name}.md: a card is at most 100 lines"
    assert text.startswith("---\n")
    front = text.split("---\n")[1]
    for key in ("library_name: edeflare", "license: mit", "tags:", "pipeline_tag:", "model-index:"):
        assert key in front, f"{name}.md lacks {key}"
    for section in ("Intended use", "Model details", "Evaluation", "Limitations"):
        assert f"## {section}\n" in text, f"{name}.md lacks ## {section}"
    assert "## Training data and how to rebuild it\n" in text


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_card_parameter_count_is_the_presets(name):
    import edeflare

    model = edeflare.create_model(PRESETS[name])
    count = sum(p.numel() for p in model.parameters())
    text = (ASSETS / f"{name}.md").read_text()
    assert f"{count:,} parameters" in text, (name, count)


def test_firenet_card_numbers_are_its_weights():
    from edeflare.recon.network import FireNet
    from edeflare.recon.weights import bundled_path, read_metadata

    text = (ASSETS / "firenet.md").read_text()
    count = sum(p.numel() for p in FireNet().parameters())
    assert f"{count:,}\nparameters" in text or f"{count:,} parameters" in text
    metrics = json.loads(read_metadata(bundled_path())["edeflare_recon_card"])["metrics"]
    rows = {r[0]: r[1] for r in _rows(_section(text, "Evaluation"))}
    assert rows["firenet"] == f"{metrics['held_out_l1']:.4f}"
    assert rows["a flat gray image"] == f"{metrics['flat_gray_l1']:.4f}"
    assert rows["ratio"] == f"{metrics['ratio']:.3f}"


def test_paper_card_numbers_are_its_weights():
    from edeflare.models.weights import read_card

    metrics = read_card(ASSETS / "paper.safetensors").metrics
    text = (ASSETS / "paper.md").read_text()
    row = next(r for r in _rows(_section(text, "Evaluation")) if r[0] == "**paper**")
    keys = ("chamfer", "gaussian", "mse", "pmse_2", "pmse_4", "r_f1", "t_f1", "tp_f1")
    want = [f"{metrics[f'eflare_r_sim_{k}']:.4f}" for k in keys]
    want += [
        f"{metrics['eflare_r_sim_recon_psnr']:.2f}",
        f"{metrics['eflare_r_sim_recon_ssim']:.4f}",
    ]
    assert row[1:] == want
    for k in ("chamfer", "mse", "r_f1"):
        assert f"{metrics[f'eflare_mini_{k}']:.4f}" in text


def test_eflare_card_numbers_are_the_benchmarks():
    """eflare.md's row is the eflare row of flare_targets_mini.json, as benchmarks.md's is."""
    rows = json.loads((ROOT / "benchmarks" / "results" / "flare_targets_mini.json").read_text())
    run = {r["method"]: r for r in rows["rows"]}["eflare"]
    keys = ("chamfer", "gaussian", "mse", "pmse_2", "pmse_4", "r_f1", "t_f1", "tp_f1")
    want = [f"{run[k]:.4f}" for k in keys]
    card = next(r for r in _rows((ASSETS / "eflare.md").read_text()) if r[0] == "**eflare**")
    assert [c.strip("*") for c in card[1:]] == want
    page = _section((DOCS / "benchmarks.md").read_text(), "The `eflare-mini` test split")
    assert next(r for r in _rows(page) if r[0] == "`eflare`")[1:] == want


def test_night_recording_table_is_the_benchmarks():
    """benchmarks.md's night-recording rows are night_recording.json's, in its units."""
    rows = json.loads((ROOT / "benchmarks" / "results" / "night_recording.json").read_text())
    run = {r["method"]: r for r in rows["rows"]}
    page = _section((DOCS / "benchmarks.md").read_text(), "The real night recording, whole")
    table = _rows(page)
    assert len(table) >= 4
    keys = ("halo removed", "ghost removed", "flare removed", "light kept", "background kept")
    for row in table:
        got = run[row[0].split()[0].strip("`")]
        want = [f"{got[k]:.1f} %" for k in keys] + [f"{got['combined']:.3f}"]
        assert [c.strip("*") for c in row[1:]] == want, row[0]


def test_leave_one_out_numbers_are_the_benchmarks():
    """benchmarks.md's held-out numbers of `night` are flare_targets_leave_one_out.json's:
    threshold / every knob (card) of each recording with a light."""
    path = ROOT / "benchmarks" / "results" / "flare_targets_leave_one_out.json"
    rows = json.loads(path.read_text())["rows"]
    page = _section((DOCS / "benchmarks.md").read_text(), "Goals of a de-flarer for every flare")
    text = " ".join(page.replace("**", "").split())
    lit = [r for r in rows if r["light"] == "yes"]
    assert {r["recording"] for r in lit} >= {"night_recording", "reference_window"}
    for r in lit:
        want = (
            f"{r['held out (threshold)']:.3f} / {r['held out (every knob)']:.3f} ({r['card']:.3f})"
        )
        assert want in text, (r["recording"], want)


# --- what the README must keep -------------------------------------------------------------


def test_readme_quickstart_commands():
    """.ci/run and the users rely on these two lines, verbatim."""
    text = (ROOT / "README.md").read_text()
    for command in (
        "python3 -m venv .venv && .venv/bin/pip install -q torch==2.13.0 -e . && "
        ".venv/bin/edeflare demo",
        "python3 -m venv .venv && .venv/bin/pip install -q torch==2.13.0 -e '.[test]' && "
        ".venv/bin/python -m pytest",
    ):
        assert f"\n{command}\n" in text
    assert len(text.splitlines()) <= 250


def test_readme_summarises_every_command():
    from edeflare.cli import build_parser

    sub = next(a for a in build_parser()._actions if hasattr(a, "choices") and a.choices)
    text = (ROOT / "README.md").read_text()
    block = text[text.index("\n## Commands\n") :].split("\n## ")[1]  # the fenced summary
    missing = [name for name in sub.choices if f"edeflare {name} " not in block]
    assert not missing, f"the README's command summary lacks {missing}"


# Product pages state what is; history lives in CHANGELOG.md.
_PRODUCT = [
    "README.md", "docs/index.md", "docs/benchmarks.md", "docs/deflaring.md", "docs/formats.md",
    "docs/baselines.md", "docs/scoring.md", "docs/evaluation.md", "docs/simulator.md",
    "docs/training.md", "docs/models.md", *[f"src/edeflare/assets/{c}.md" for c in CARDS],
]  # fmt: skip
_HISTORY = re.compile(
    r"\bissue \d+|\bissues?\b|\bsessions?\b|\b20\d\d-\d\d-\d\d\b|previous default|card before",
    re.I,
)


@pytest.mark.parametrize("page", _PRODUCT)
def test_product_pages_hold_no_history(page):
    text = (ROOT / page).read_text()
    found = sorted({m.group(0) for m in _HISTORY.finditer(text)})
    assert not found, f"{page} mentions {found}: history belongs in CHANGELOG.md"
    assert len(text.splitlines()) <= 400 or page != "docs/benchmarks.md"


def test_codec_decoders_table_is_todays():
    """docs/concepts/codec.md: the two decoders on one window of the Gen3 recording."""
    import edeflare
    from edeflare.eval.metrics import segment_metrics
    from edeflare.voxel import decode, decode_keep, encode

    events, size = edeflare.read_events(real_data_dir() / "prophesee_gen3_rotating_light.raw")
    t0 = 1_320_000
    window = events[(events["t"] >= t0) & (events["t"] < t0 + 20_000)]
    grid = encode(window, size, t0, 20_000)
    rows = {r[0]: r for r in _rows((DOCS / "concepts" / "codec.md").read_text())}
    out = decode(grid, t0, 20_000, rng=0)
    m = segment_metrics(window, out, size, t0)
    assert rows["`paper`"][1:] == [
        f"{out.size:,}", f"{m.chamfer:.4f}", f"{m.gaussian:.4f}", f"{m.mse:.0f}",
        f"{m.pmse_2:.4f}", f"{m.pmse_4:.4f}", f"{m.r_f1:.3f}", f"{m.t_f1:.3f}", f"{m.tp_f1:.3f}",
    ]  # fmt: skip
    kept = decode_keep(grid, window, t0, 20_000, rng=0)
    assert rows["`keep`"][1] == f"{kept.size:,} (the input)" and kept.size == window.size
