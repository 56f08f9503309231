"""Residual head experiment: keep logit = network logit + MLP(features), folded into a
plain head."""

import dataclasses
import glob
import sys
import time

import numpy as np
import torch
from torch import nn

from edeflare.models.event_features import DEFAULT_FEATURES
from edeflare.models.event_head import EventHead, head_logits
from edeflare.models.head_training import LN3, choose_threshold
from edeflare.models.weights import load_model, save_model

lam = float(sys.argv[1])
out = sys.argv[2]
epochs = int(sys.argv[3]) if len(sys.argv) > 3 else 4
R = sys.argv[4] if len(sys.argv) > 4 else "runs/head-night2/"  # train-head's feature caches

tr = np.load(glob.glob(R + "/features-train-*.npz")[0])
te = np.load(glob.glob(R + "/features-test-*.npz")[0])
names = list(DEFAULT_FEATURES)
k = names.index("net_logit")
x = torch.from_numpy(tr["x"])
y = torch.from_numpy(tr["y"].astype(np.float32))
torch.manual_seed(0)
hid = (32, 16)
mlp = EventHead(names, hid)
mlp.standardise_on(x)
with torch.no_grad():
    mlp.layers[-1].weight.zero_()
    mlp.layers[-1].bias.zero_()
ks = y.mean().item()
w = torch.where(y > 0.5, 0.5 / ks, 0.5 / (1 - ks))
opt = torch.optim.Adam(mlp.parameters(), lr=3e-3)
bs = 4096
steps = epochs * (len(y) // bs + 1)
sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=3e-3, total_steps=steps)
g = torch.Generator().manual_seed(0)
t0 = time.time()
for ep in range(epochs):
    order = torch.randperm(len(y), generator=g)
    for lo in range(0, len(y), bs):
        b = order[lo : lo + bs]
        delta = mlp(x[b])
        logit = x[b, k] + delta + LN3
        loss = (
            nn.functional.binary_cross_entropy_with_logits(logit, y[b], weight=w[b])
            + lam * (delta**2).mean()
        )
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
    print("epoch", ep, float(loss.detach()), time.time() - t0, flush=True)
# fold: a plain head with two more units per hidden layer carrying relu(n), relu(-n)
p = mlp.numpy_params()
W = [wt.T.astype(np.float64) for wt in p["weights"]]  # (out, in)
B = [b.astype(np.float64) for b in p["biases"]]
n = len(names)
full = EventHead(names, tuple(h + 2 for h in hid))
with torch.no_grad():
    full.mean.zero_()
    full.scale.fill_(1.0)
    L = full.layers
    w0 = np.zeros((hid[0] + 2, n))
    w0[: hid[0]] = W[0]
    w0[hid[0], k] = 1
    w0[hid[0] + 1, k] = -1
    b0 = np.zeros(hid[0] + 2)
    b0[: hid[0]] = B[0]
    L[0].weight.copy_(torch.from_numpy(w0))
    L[0].bias.copy_(torch.from_numpy(b0))
    for i in range(1, len(hid)):
        wi = np.zeros((hid[i] + 2, hid[i - 1] + 2))
        wi[: hid[i], : hid[i - 1]] = W[i]
        wi[hid[i], hid[i - 1]] = 1
        wi[hid[i] + 1, hid[i - 1] + 1] = 1
        bi = np.zeros(hid[i] + 2)
        bi[: hid[i]] = B[i]
        L[i].weight.copy_(torch.from_numpy(wi))
        L[i].bias.copy_(torch.from_numpy(bi))
    wl = np.zeros((1, hid[-1] + 2))
    wl[0, : hid[-1]] = W[-1]
    wl[0, hid[-1]] = 1
    wl[0, hid[-1] + 1] = -1
    L[-1].weight.copy_(torch.from_numpy(wl))
    L[-1].bias.copy_(torch.from_numpy(B[-1]))
fp = full.numpy_params()
xs = te["x"][:5000]
ref = xs[:, k] + head_logits(p, xs)
assert np.allclose(head_logits(fp, xs), ref, atol=1e-3), np.abs(head_logits(fp, xs) - ref).max()
logits = head_logits(fp, te["x"])
thr, table = choose_threshold(logits, te["y"], te["source"] >= 0)
print("threshold", thr, max(r["score"] for r in table))
net, card = load_model("src/edeflare/assets/general.safetensors")
net.head = full
card = dataclasses.replace(
    card, head=full.spec(), keep_threshold=thr, notes=f"residual head lam={lam}"
)
save_model(out, net, card)
print("saved", out)
