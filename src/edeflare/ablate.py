"""The ablation of Table 3: the same network trained on each way of composing the training pairs.

Section 4.4 of the paper asks what the physics-driven composition (PNL-ES)
buys. Five training sets are simulated from the *same* scenes (scripts and
backgrounds depend only on the dataset seed and the sequence index, see
:mod:`edeflare.data.generate`) and differ only in how the flare, the light
source and the background are fused into the input / ground-truth pair:

========================  ================================================
row (``variant``)         training pairs
========================  ================================================
Simple (``simple``)       input = merge of the streams (no suppression)
Simple + Random           as Simple, flare timestamps jittered
Physical + Random         PNL-ES, flare timestamps jittered
No Light (``no-light``)   PNL-ES input, ground truth without the light source
Full (``physical``)       PNL-ES (the paper's method)
========================  ================================================

One model per variant is trained with the same preset, iterations, batch,
crops and seed (equal budgets), then every model is scored on one test set
that none of them was trained on: by default an optics-based paired set
(recipes ``eflare-r-sim`` / ``eflare-r-sim-mini``: star-filter observation,
clean-lens ground truth), the stand-in for the paper's real captures
(E-Flare-R); ``test_split`` takes real pairs made with ``edeflare pair``. The
table has the raw input row (unranked) and an improvement row giving the
full configuration's gain over the best ablated variant.

Every step resumes: datasets and training runs pick up where a killed run
stopped, and the table is recomputed from the trained models. The output
folder holds ``ablation.json`` (the configuration; a rerun with another one
is refused), ``data/<variant>/``, ``test/``, ``runs/<variant>/`` and the
table as ``table.md``, ``table.csv`` and ``table.json``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ._registry import Registry
from .data.generate import RECIPES, FlareConfig, Recipe, generate_dataset
from .errors import ParameterError
from .eval.benchmark import BenchmarkResult, benchmark
from .eval.tables import ResultsTable
from .io._atomic import atomic_path
from .io.sequence import list_sequences
from .sim.background import SceneConfig
from .sim.optics_scene import OpticsSceneConfig
from .sim.script import ScriptConfig
from .train import TRAIN_PRESETS, TrainConfig, train

__all__ = [
    "ABLATIONS",
    "VARIANT_ROWS",
    "AblationConfig",
    "AblationResult",
    "list_ablations",
    "run_ablation",
]

VARIANT_ROWS: dict[str, str] = {
    "simple": "Simple",
    "simple+random": "Simple + Random",
    "physical+random": "Physical + Random",
    "no-light": "No Light",
    "physical": "Full",
}
"""Composition variant -> row name in the table (the paper's Table 3 names)."""

FULL = "physical"


@dataclass(frozen=True)
class AblationConfig:
    """What an ablation trains and where it is tested.

    Parameters
    ----------
    name : str
    train_recipe : Recipe
        The training data; its ``variant`` is replaced by each variant in turn.
        Only its ``train`` split is used.
    test_recipe : Recipe
        The test data (its ``test`` split), generated once.
    training : TrainConfig
        The same for every variant (equal budgets).
    variants : tuple of str
        Keys of :data:`VARIANT_ROWS`; ``physical`` (Full) must be among them.

    Examples
    --------
    >>> cfg = ABLATIONS["small"]
    >>> cfg.training.preset, len(cfg.variants)
    ('unet2d.tiny', 5)
    """

    name: str
    train_recipe: Recipe
    test_recipe: Recipe
    training: TrainConfig
    variants: tuple[str, ...] = tuple(VARIANT_ROWS)

    def __post_init__(self) -> None:
        unknown = [v for v in self.variants if v not in VARIANT_ROWS]
        if unknown:
            raise ParameterError(f"unknown variant(s) {unknown}; known: {list(VARIANT_ROWS)}")
        if FULL not in self.variants:
            raise ParameterError(f"the variants must include {FULL!r} (the full configuration)")
        if len(set(self.variants)) != len(self.variants):
            raise ParameterError(f"repeated variants in {list(self.variants)}")
        if self.train_recipe.sequences == self.train_recipe.test_sequences:
            raise ParameterError("the training recipe has no training sequences")
        if self.test_recipe.test_sequences < 1:
            raise ParameterError("the test recipe has no test sequences")

    def recipe_for(self, variant: str) -> Recipe:
        """The training recipe of one variant."""
        name = f"{self.train_recipe.name}-{variant}"
        return self.train_recipe.replace(name=name, variant=variant)

    def replace(self, **changes: Any) -> AblationConfig:
        """A copy with some fields changed (``iterations`` and ``sequences`` are shortcuts).

        Examples
        --------
        >>> ABLATIONS["small"].replace(iterations=5, sequences=3).training.iterations
        5
        """
        iterations = changes.pop("iterations", None)
        sequences = changes.pop("sequences", None)
        for key, value in (("iterations", iterations), ("sequences", sequences)):
            if value is not None and (isinstance(value, bool) or int(value) != value or value < 1):
                raise ParameterError(f"{key} must be an int >= 1, got {value!r}")
        out = dataclasses.replace(self, **changes)
        if iterations is not None:
            out = dataclasses.replace(
                out, training=dataclasses.replace(out.training, iterations=int(iterations))
            )
        if sequences is not None:
            recipe = dataclasses.replace(
                out.train_recipe, sequences=int(sequences), test_sequences=0
            )
            out = dataclasses.replace(out, train_recipe=recipe)
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (recorded in ``ablation.json``)."""
        return {
            "name": self.name,
            "train_recipe": self.train_recipe.identity(),
            "test_recipe": self.test_recipe.identity(),
            "training": json.loads(json.dumps(self.training.to_dict())),
            "variants": list(self.variants),
        }


def _ablations() -> dict[str, AblationConfig]:
    small_recipe = Recipe(
        name="ablate-small",
        sequences=8,
        test_sequences=0,
        duration_us=40_000,
        sensor_size=(64, 48),
        seed=2026,
        scene=SceneConfig(fps=1000.0),
        config=FlareConfig(script=ScriptConfig(psf_grid=128)),
    )
    small_test = dataclasses.replace(
        RECIPES["eflare-r-sim-mini"],
        name="ablate-small-test",
        sequences=3,
        duration_us=20_000,
        sensor_size=(64, 48),
        seed=9999,
        config=OpticsSceneConfig(psf_grid=128),
    )
    cpu = TRAIN_PRESETS["cpu"]
    return {
        "small": AblationConfig(
            "small",
            small_recipe,
            small_test,
            dataclasses.replace(
                cpu,
                preset="unet2d.tiny",
                iterations=30,
                batch_size=4,
                crop=(32, 32),
                val_every=10**9,
                checkpoint_every=10,
            ),
        ),
        "cpu": AblationConfig(
            "cpu",
            RECIPES["eflare-mini"].replace(test_sequences=0, seed=2026),
            RECIPES["eflare-r-sim-mini"],
            dataclasses.replace(cpu, iterations=2000, val_every=10**9),
        ),
        "paper": AblationConfig(
            "paper",
            RECIPES["eflare-2.7k"].replace(test_sequences=0),
            RECIPES["eflare-r-sim"],
            TRAIN_PRESETS["paper"],
        ),
    }


ABLATIONS: Registry[AblationConfig] = Registry("ablation")
for _name, _config in _ablations().items():
    ABLATIONS.register(_name, _config)
"""Named ablations: ``small`` (a minute on a CPU; for tests and CI; too small to
rank the variants), ``cpu`` (eflare-mini, ``unet2d.lite``, 2000 iterations per
variant: a few hours on 2 cores) and ``paper`` (E-Flare-2.7K and the paper's
training, for GPUs)."""


@dataclass(frozen=True)
class AblationResult:
    """The table (``table``: raw row, one row per variant, improvement of Full)."""

    table: ResultsTable
    benchmark: BenchmarkResult
    models: dict[str, Path]


def _check_config(path: Path, config: AblationConfig) -> None:
    wanted = config.to_dict()
    if path.exists():
        try:
            saved = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ParameterError(f"{path}: unreadable ablation record ({exc})") from None
        if saved != wanted:
            diff = sorted(k for k in wanted if saved.get(k) != wanted[k])
            raise ParameterError(
                f"{path}: this folder holds an ablation with other values of {diff}; "
                "use a new output folder"
            )
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(wanted, indent=2) + "\n", encoding="utf-8")


def run_ablation(
    config: AblationConfig,
    out: str | os.PathLike[str],
    *,
    test_split: str | os.PathLike[str] | None = None,
    workers: int = 1,
    seed: int = 0,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
) -> AblationResult:
    """Run (or resume) an ablation and write its table into ``out``.

    Parameters
    ----------
    config : AblationConfig
        E.g. ``ABLATIONS["cpu"]``.
    out : path-like
        Output folder (see the module docstring).
    test_split : path-like, optional
        A folder of paired sequence files to test on instead of generating
        ``config.test_recipe`` (e.g. real captures prepared with ``edeflare pair``).
    workers : int
        Processes for data generation.
    seed : int
        Seeds the model decoders in the evaluation.
    log : callable, optional
        Receives one line per step.

    Examples
    --------
    >>> import tempfile
    >>> cfg = ABLATIONS["small"].replace(iterations=2, sequences=2, variants=("physical",))
    >>> result = run_ablation(cfg, tempfile.mkdtemp(), progress=False)
    >>> list(result.table.values)
    ['raw', 'Full']
    """
    say = log or (lambda _line: None)
    out = Path(out)
    _check_config(out / "ablation.json", config)
    if test_split is None:
        say(f"test data: {config.test_recipe.name} -> {out / 'test'}")
        generate_dataset(config.test_recipe, out / "test", workers=workers, progress=progress)
        test_split = out / "test" / "test"
    test_paths = list_sequences(test_split)

    models: dict[str, Path] = {}
    for variant in config.variants:
        recipe = config.recipe_for(variant)
        data = out / "data" / variant
        say(f"[{variant}] training data: {recipe.name} -> {data}")
        generate_dataset(recipe, data, workers=workers, progress=progress)
        run = out / "runs" / variant
        say(f"[{variant}] training {config.training.preset} -> {run}")
        training = dataclasses.replace(
            config.training, data=f"{recipe.name} (seed {recipe.seed}, {recipe.sequences} seq.)"
        )
        models[variant] = train(
            training,
            list_sequences(data / "train"),
            run,
            command=f"edeflare ablate ({config.name}, variant {variant})",
            progress=progress,
        )

    say(f"evaluating {len(models)} models on {len(test_paths)} test sequences")
    rows: dict[str, str] = {"raw": "raw"}
    params: dict[str, Mapping[str, Any]] = {}
    for variant, weights in models.items():
        rows[VARIANT_ROWS[variant]] = "model"
        params[VARIANT_ROWS[variant]] = {"weights": weights}
    result = benchmark(test_paths, rows, params=params, seed=seed, progress=progress)
    values = {row: s.means for row, s in result.evaluation.methods.items()}
    table = ResultsTable(values, reference=VARIANT_ROWS[FULL])
    _write_table(out / "table", table, result, config)
    return AblationResult(table, result, models)


def _write_table(
    stem: Path, table: ResultsTable, result: BenchmarkResult, config: AblationConfig
) -> None:
    note = (
        f"Ablation `{config.name}`: {config.training.preset}, "
        f"{config.training.iterations} iterations per variant, trained on "
        f"`{config.train_recipe.name}` ({config.train_recipe.sequences} sequences), "
        f"tested on `{config.test_recipe.name}`. The improvement row is Full's gain "
        "over the best ablated variant.\n\n"
    )
    table.save(
        stem,
        markdown=note + table.to_markdown(),
        details={"config": config.to_dict(), "benchmark": result.to_dict()},
        json_newline=True,
    )


def list_ablations() -> Sequence[str]:
    """Names of :data:`ABLATIONS`.

    Examples
    --------
    >>> list(list_ablations())
    ['cpu', 'paper', 'small']
    """
    return sorted(ABLATIONS)
