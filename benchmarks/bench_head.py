"""What a learned head's perceptrons cost per event, and how near the CPU's BLAS they run.

A context head (the bundled `learned-absolute`: three members of 64 and 32 units over 21 features,
each with 8 context maps) decides every event with about 10,300 multiply-adds: the first
layers side by side (21 x 192), then per member 64 x 32 and 32 x 1. The context's share of
the first layer is one product per cell, added to its events' rows
(:func:`edeflare.models.event_head.head_logits_at_cells`). This script times that path
(``reference``) on random features, one thread, against the same arithmetic in torch in
float32 and in bfloat16 (the float32 result's largest difference is reported) and
against the first two products alone (``products only``, no bias, ReLU or per-member
slicing: what a fused kernel could at best approach). Random values cost what real ones
do: every product is dense.

Run: ``python benchmarks/bench_head.py [--model learned-absolute] [--events N] [--repeat K]``;
writes ``results/head.json``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np
import torch
from _common import best_of, report
from threadpoolctl import threadpool_limits

from edeflare.models.event_head import _StackedHead
from edeflare.models.infer import ModelDeflarer, resolve_weights

CELLS = 4_800
"""A 640x480 window's 8x8 cells."""


def multiply_adds(params: dict) -> int:
    """Multiply-adds per event of a head's layers (the context's per-cell share aside)."""
    n = len(params["features"])
    total = 0
    for m in params["members"]:
        w = m["weights"]
        total += n * w[0].shape[1] + sum(x.shape[0] * x.shape[1] for x in w[1:])
    return total


def torch_logits(layers: _StackedHead, dtype: torch.dtype) -> Callable[..., torch.Tensor]:
    """The same computation as ``layers.logits`` in torch, in ``dtype``."""
    w1 = torch.from_numpy(layers.first_features).to(dtype)
    b1 = torch.from_numpy(layers.first_bias).to(dtype)
    deeper = [
        [(torch.from_numpy(w).to(dtype), torch.from_numpy(b).to(dtype)) for w, b in member]
        for member in layers.deeper
    ]
    spans = layers.spans

    def run(f: torch.Tensor, rows: torch.Tensor, cells: torch.Tensor) -> torch.Tensor:
        a = torch.relu(f @ w1 + rows[cells] + b1)
        total = torch.zeros(f.shape[0], dtype=dtype)
        for (i, j), member in zip(spans, deeper, strict=True):
            z = a[:, i:j]
            for k, (w, b) in enumerate(member):
                z = (torch.relu(z) if k else z) @ w + b
            total += z[:, 0]
        return total / len(deeper)

    return run


def main() -> None:
    """Time the head's paths and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="learned-absolute", help="a bundled model with a head")
    parser.add_argument("--events", type=int, default=200_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    head = ModelDeflarer(resolve_weights(args.model), runtime="torch").model.head
    if head is None:
        raise SystemExit(f"{args.model}: this model has no head")
    params = head.numpy_params()
    layers = _StackedHead(params)
    n_features = len(params["features"])
    rng = np.random.default_rng(0)
    features = rng.standard_normal((args.events, n_features)).astype(np.float32)
    cells = rng.integers(0, CELLS, args.events)
    maps = rng.standard_normal((max(layers.context, 1), CELLS)).astype(np.float32)
    rows = (
        maps.T @ layers.first_context
        if layers.context
        else np.zeros((CELLS, layers.first_features.shape[1]), np.float32)
    )
    flops = 2 * multiply_adds(params) * args.events
    second = [member[0][0] for member in layers.deeper if member]

    def products_only() -> None:
        a = features @ layers.first_features
        for (i, j), w in zip(layers.spans, second, strict=True):
            _ = a[:, i:j] @ w

    torch.set_num_threads(1)
    out_rows = []
    with threadpool_limits(1), torch.inference_mode():
        reference = layers.logits(features, rows=rows, cells=cells)
        cases = {
            "reference (numpy, the product's path)": lambda: layers.logits(
                features, rows=rows, cells=cells
            ),
            "products only (numpy)": products_only,
        }
        diffs = {}
        for label, dtype in (("torch float32", torch.float32), ("torch bfloat16", torch.bfloat16)):
            run = torch_logits(layers, dtype)
            f, r = torch.from_numpy(features).to(dtype), torch.from_numpy(rows).to(dtype)
            c = torch.from_numpy(cells)
            cases[label] = lambda run=run, f=f, r=r, c=c: run(f, r, c)
            diffs[label] = float(np.abs(run(f, r, c).float().numpy() - reference).max())
        times = {label: best_of(fn, args.repeat) for label, fn in cases.items()}
    base = times["reference (numpy, the product's path)"]
    for label, seconds in times.items():
        out_rows.append(
            {
                "path": label,
                "ms": round(seconds * 1e3, 1),
                "M events/s": round(args.events / seconds / 1e6, 2),
                "GFLOP/s": round(flops / seconds / 1e9, 1),
                "ratio": round(seconds / base, 2),
                "max |logit diff|": f"{diffs[label]:.2g}" if label in diffs else "",
            }
        )
    print(
        f"{args.model}: {multiply_adds(params):,} multiply-adds per event, "
        f"{args.events:,} events, one thread; ratio: time over the reference"
    )
    report(
        "head",
        out_rows,
        ["path", "ms", "M events/s", "GFLOP/s", "ratio", "max |logit diff|"],
    )


if __name__ == "__main__":
    main()
