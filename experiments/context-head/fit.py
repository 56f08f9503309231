"""Fit a context head (or the plain head, --k 0) on the collected windows; score it on
the validation windows with train-head's threshold rule.

    python experiments/context-head/fit.py /work/runs-tmp/ctx --k 8 --epochs 12 --out RUN
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch
from common import LN3, ContextHead
from safetensors.torch import save_file

from edeflare.models.head_training import _group, choose_threshold


def load(path: Path) -> dict:
    z = np.load(path)
    n = len(z["sizes"])
    d = {k: z[k] for k in ("x", "y", "win", "cell", "source", "sizes", "files")}
    d["ctx"] = [z[f"ctx_{i:05d}"] for i in range(n)]
    files = [str(f) for f in d["files"]]
    d["group"] = np.array([_group(files, int(s)) for s in d["source"]])
    order = np.argsort(d["win"], kind="stable")
    for k in ("x", "y", "win", "cell", "source", "group"):
        d[k] = d[k][order]
    d["bounds"] = np.searchsorted(d["win"], np.arange(n + 1))
    return d


def load_all(paths: list[Path]) -> dict:
    parts = [load(p) for p in paths]
    d = {
        "ctx": [c for p in parts for c in p["ctx"]],
        "sizes": np.concatenate([p["sizes"] for p in parts]),
    }
    for k in ("x", "y", "cell", "group"):
        d[k] = np.concatenate([p[k] for p in parts])
    offsets = np.cumsum([0] + [len(p["ctx"]) for p in parts])
    d["win"] = np.concatenate([p["win"] + o for p, o in zip(parts, offsets, strict=False)])
    d["bounds"] = np.searchsorted(d["win"], np.arange(len(d["ctx"]) + 1))
    return d


def batches(d: dict, b: int, rng) -> list[list[int]]:
    by = defaultdict(list)
    for i, s in enumerate(map(tuple, d["sizes"])):
        by[s].append(i)
    out = []
    for ids in by.values():
        ids = list(rng.permutation(ids)) if rng is not None else ids
        out += [ids[j : j + b] for j in range(0, len(ids), b)]
    if rng is not None:
        out = [out[i] for i in rng.permutation(len(out))]
    return out


def batch_tensors(d: dict, ids: list[int]):
    c = torch.from_numpy(np.stack([d["ctx"][i] for i in ids]).astype(np.float32))
    sl = [slice(d["bounds"][i], d["bounds"][i + 1]) for i in ids]
    x = torch.from_numpy(np.concatenate([d["x"][s] for s in sl]))
    y = torch.from_numpy(np.concatenate([d["y"][s] for s in sl]).astype(np.float32))
    win = torch.from_numpy(np.concatenate([np.full(s.stop - s.start, j) for j, s in enumerate(sl)]))
    cell = torch.from_numpy(np.concatenate([d["cell"][s] for s in sl]).astype(np.int64))
    return c, x, y, win, cell


def logits_of(model: ContextHead, d: dict, b: int = 8) -> np.ndarray:
    out = np.empty(d["y"].size, np.float32)
    model.eval()
    with torch.no_grad():
        for ids in batches(d, b, None):
            c, x, _, win, cell = batch_tensors(d, ids)
            rows = model.rows(c, win, cell) if model.k else None
            v = model(x, rows).numpy()
            pos = np.concatenate([np.arange(d["bounds"][i], d["bounds"][i + 1]) for i in ids])
            out[pos] = v
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data", type=Path, nargs="+")
    ap.add_argument("--val", type=Path, nargs="+", help="test splits scored (default: data)")
    ap.add_argument("--ctx-drop", type=float, default=0.0)
    ap.add_argument("--gate", action="store_true", help="no context in light-free windows")
    ap.add_argument("--k", type=int, default=8)
    ap.add_argument("--hidden", default="64,32")
    ap.add_argument("--widths", default="16,32,64,64")
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--threads", type=int, default=1)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(a.seed)
    rng = np.random.default_rng(a.seed)
    tr = load_all([p / "train.npz" for p in a.data])
    va = load_all([p / "test.npz" for p in (a.val or a.data)])
    model = ContextHead(
        tr["x"].shape[1],
        a.k,
        tuple(map(int, a.hidden.split(","))),
        tuple(map(int, a.widths.split(","))),
        in_ch=tr["ctx"][0].shape[0],
    )
    model.gate_light_free = a.gate
    model.mean.copy_(torch.from_numpy(tr["x"].mean(0)))
    model.scale.copy_(torch.from_numpy(tr["x"].std(0) + 1e-6))
    sample = np.stack([c.astype(np.float32).reshape(c.shape[0], -1).mean(1) for c in tr["ctx"]])
    sq = np.stack([(c.astype(np.float32) ** 2).reshape(c.shape[0], -1).mean(1) for c in tr["ctx"]])
    model.cmean.copy_(torch.from_numpy(sample.mean(0))[:, None, None])
    std = np.sqrt(sq.mean(0) - sample.mean(0) ** 2) + 1e-3
    model.cscale.copy_(torch.from_numpy(std)[:, None, None])
    keep = float(tr["y"].mean())
    opt = torch.optim.Adam(model.parameters(), lr=a.lr)
    steps = a.epochs * len(batches(tr, a.batch, None))
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=a.lr, total_steps=steps)
    t0 = time.time()
    for ep in range(a.epochs):
        model.train()
        tot = 0.0
        for ids in batches(tr, a.batch, rng):
            c, x, y, win, cell = batch_tensors(tr, ids)
            rows = model.rows(c, win, cell) if a.k else None
            if a.k and a.ctx_drop > 0:
                keep_ctx = torch.rand(len(ids)) >= a.ctx_drop
                rows = rows * keep_ctx[win].float()[:, None]
            v = model(x, rows) + LN3
            w = torch.where(y > 0.5, 0.5 / keep, 0.5 / (1 - keep))
            loss = torch.nn.functional.binary_cross_entropy_with_logits(v, y, weight=w)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            tot += float(loss.detach())
        print(f"epoch {ep + 1}/{a.epochs} loss {tot:.2f} {time.time() - t0:.0f}s", flush=True)
    lv = logits_of(model, va)
    groups = va["group"]
    thr, table = choose_threshold(lv, va["y"], groups)
    prob = 1 / (1 + np.exp(-(lv + LN3)))
    per = {}
    for g in np.unique(groups):
        sel = groups == g
        kept = prob[sel] > thr
        yy = va["y"][sel]
        per[str(g)] = {
            "flare removed": float(1 - kept[~yy].mean()) if (~yy).any() else None,
            "scene kept": float(kept[yy].mean()),
        }
    score = max(r["score"] for r in table)
    a.out.mkdir(parents=True, exist_ok=True)
    save_file(model.state_dict(), a.out / "head.safetensors")
    summary = {
        "args": {k: str(v) for k, v in vars(a).items()},
        "threshold": thr,
        "score": score,
        "groups": per,
        "table": table,
    }
    (a.out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps({"threshold": thr, "score": round(score, 4), "groups": per}, indent=1))


if __name__ == "__main__":
    main()
