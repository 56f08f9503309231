"""Results tables as in the paper (Tables 1-2): methods x metrics, best marked, improvement row.

The raw input row (method ``raw``) is shown but not ranked, as in the paper.
Among the other methods, the best value of each metric is marked in bold and
the second best in italics; the "Improvement (%)" row gives the best
method's relative gain over the second best, for lower-is-better metrics
``(second - best) / second`` and for higher-is-better ones
``(best - second) / second``. With Table 1 of the paper: Chamfer
``(1.2496 - 0.4477) / 1.2496 = 64.2 %``. With a ``reference`` row (Table 3:
the full configuration against the ablated variants) the row gives that
row's gain over the best of the others instead, negative where it loses.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..io._atomic import atomic_path
from .metrics import HIGHER_IS_BETTER, METRICS

__all__ = ["METRIC_LABELS", "ResultsTable"]

METRIC_LABELS = {
    "chamfer": "Chamfer↓",
    "gaussian": "Gaussian↓",
    "mse": "MSE↓",
    "pmse_2": "PMSE-2↓",
    "pmse_4": "PMSE-4↓",
    "r_f1": "R-F1↑",
    "t_f1": "T-F1↑",
    "tp_f1": "TP-F1↑",
}
"""Column headers, with the direction of each metric."""

RAW = "raw"


@dataclass(frozen=True)
class ResultsTable:
    """Methods x metrics with ranking and the improvement row.

    Parameters
    ----------
    values : mapping
        Method name -> {metric name -> value}; NaN for missing values.
    metrics : sequence of str
        Columns (default: the paper's eight).
    raw : str
        Name of the unranked raw-input row.
    reference : str, optional
        Give the improvement of this row over the best other ranked row
        (Table 3) instead of the best over the second best (Tables 1-2).

    Examples
    --------
    >>> t = ResultsTable({"raw": {"chamfer": 1.3555}, "PFD-B": {"chamfer": 1.2496},
    ...                   "Ours": {"chamfer": 0.4477}}, metrics=["chamfer"])
    >>> t.best["chamfer"], t.second["chamfer"], round(t.improvement["chamfer"], 1)
    ('Ours', 'PFD-B', 64.2)
    >>> t = ResultsTable({"Simple": {"r_f1": 0.2703}, "Full": {"r_f1": 0.3498}},
    ...                  metrics=["r_f1"], reference="Full")
    >>> round(t.improvement["r_f1"], 1)
    29.4
    """

    values: Mapping[str, Mapping[str, float]]
    metrics: Sequence[str] = METRICS
    raw: str = RAW
    reference: str | None = None

    def __post_init__(self) -> None:
        if self.reference is not None and self.reference not in self.values:
            raise ValueError(f"reference row {self.reference!r} is not in the table")

    def _ranked(self, metric: str) -> list[tuple[float, str]]:
        cells = [
            (v, name)
            for name, row in self.values.items()
            if name != self.raw and not math.isnan(v := float(row.get(metric, math.nan)))
        ]
        higher = HIGHER_IS_BETTER.get(metric, False)
        return sorted(cells, key=lambda c: -c[0] if higher else c[0])

    @property
    def best(self) -> dict[str, str | None]:
        """Metric -> best ranked method (None without any value)."""
        return {m: (r[0][1] if (r := self._ranked(m)) else None) for m in self.metrics}

    @property
    def second(self) -> dict[str, str | None]:
        """Metric -> second-best ranked method (None with fewer than two values)."""
        return {m: (r[1][1] if len(r := self._ranked(m)) > 1 else None) for m in self.metrics}

    @property
    def improvement(self) -> dict[str, float]:
        """Metric -> gain (%) of the best over the second best (NaN if undefined).

        With ``reference``: the gain of that row over the best of the others.
        """
        out = {}
        for m in self.metrics:
            ranked = self._ranked(m)
            if self.reference is not None:
                own = [v for v, n in ranked if n == self.reference]
                others = [v for v, n in ranked if n != self.reference]
                pair = (own[0], others[0]) if own and others else None
            else:
                pair = (ranked[0][0], ranked[1][0]) if len(ranked) > 1 else None
            if pair is None or pair[1] == 0:
                out[m] = math.nan
                continue
            best, second = pair
            gain = best - second if HIGHER_IS_BETTER.get(m, False) else second - best
            out[m] = 100.0 * gain / abs(second)
        return out

    def _rows(self) -> list[str]:
        names = [n for n in self.values if n == self.raw] + [
            n for n in self.values if n != self.raw
        ]
        return names

    def to_markdown(self, digits: int = 4) -> str:
        """Markdown table: raw row first, best **bold**, second best *italic*, improvement last."""
        best, second = self.best, self.second
        header = ["Method", *(METRIC_LABELS.get(m, m) for m in self.metrics)]
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for name in self._rows():
            cells = [f"{name} (input)" if name == self.raw else name]
            for m in self.metrics:
                v = float(self.values[name].get(m, math.nan))
                text = "–" if math.isnan(v) else f"{v:.{digits}f}"
                if name != self.raw and name == best[m]:
                    text = f"**{text}**"
                elif name != self.raw and name == second[m]:
                    text = f"*{text}*"
                cells.append(text)
            lines.append("| " + " | ".join(cells) + " |")
        imp = self.improvement
        if any(not math.isnan(v) for v in imp.values()):
            cells = ["Improvement (%)"] + [
                "–" if math.isnan(imp[m]) else f"{imp[m]:.1f}%" for m in self.metrics
            ]
            lines.append("| " + " | ".join(cells) + " |")
        return "\n".join(lines) + "\n"

    def to_csv(self) -> str:
        """CSV: one row per method, then ``best``, ``second`` and ``improvement_percent`` rows."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["method", *self.metrics])
        for name in self._rows():
            writer.writerow(
                [name, *(_num(self.values[name].get(m, math.nan)) for m in self.metrics)]
            )
        best, second, imp = self.best, self.second, self.improvement
        writer.writerow(["best", *(best[m] or "" for m in self.metrics)])
        writer.writerow(["second", *(second[m] or "" for m in self.metrics)])
        writer.writerow(["improvement_percent", *(_num(imp[m]) for m in self.metrics)])
        return buf.getvalue()

    def to_json(self) -> str:
        """JSON with values, directions, best, second and improvement (NaN as null)."""
        payload = {
            "metrics": list(self.metrics),
            "higher_is_better": {m: HIGHER_IS_BETTER.get(m, False) for m in self.metrics},
            "raw": self.raw if self.raw in self.values else None,
            "values": {
                n: {m: _none(self.values[n].get(m, math.nan)) for m in self.metrics}
                for n in self._rows()
            },
            "best": self.best,
            "second": self.second,
            "improvement_percent": {m: _none(v) for m, v in self.improvement.items()},
        }
        return json.dumps(payload, indent=2, ensure_ascii=False) + "\n"

    def save(
        self,
        path: str | os.PathLike[str],
        *,
        markdown: str | None = None,
        details: Mapping[str, Any] | None = None,
        json_newline: bool = False,
    ) -> list[Path]:
        """Write the table as ``STEM.md``, ``STEM.csv`` and ``STEM.json``, each atomically.

        The one writer of results tables (``edeflare evaluate --report``,
        ``edeflare benchmark --report``, the ablation).

        Parameters
        ----------
        path : path-like
            ``STEM`` or ``STEM.md`` (the suffix is replaced).
        markdown : str, optional
            The Markdown file's text (default :meth:`to_markdown`; callers add
            notes or the speed table).
        details : mapping, optional
            Extra keys merged into the JSON (e.g. the full evaluation).
        json_newline : bool
            End the JSON file with a newline.

        Returns
        -------
        list of Path
            The files written (``.md``, ``.csv``, ``.json``).

        Examples
        --------
        >>> import tempfile, pathlib
        >>> t = ResultsTable({"raw": {"chamfer": 2.0}, "efr": {"chamfer": 1.0}})
        >>> paths = t.save(pathlib.Path(tempfile.mkdtemp()) / "table")
        >>> [p.name for p in paths]
        ['table.md', 'table.csv', 'table.json']
        """
        stem = Path(path).with_suffix(".md")
        payload = json.loads(self.to_json())
        payload.update(details or {})
        text = json.dumps(payload, indent=2, ensure_ascii=False) + ("\n" if json_newline else "")
        files = {
            stem: self.to_markdown() if markdown is None else markdown,
            stem.with_suffix(".csv"): self.to_csv(),
            stem.with_suffix(".json"): text,
        }
        for target, content in files.items():
            with atomic_path(target) as tmp:
                tmp.write_text(content, encoding="utf-8")
        return list(files)


def _num(v: float) -> str:
    v = float(v)
    return "" if math.isnan(v) else repr(v)


def _none(v: float) -> float | None:
    v = float(v)
    return None if math.isnan(v) else v
