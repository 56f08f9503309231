"""Speed and memory of the networks on this machine.

For each model preset: 20 ms windows per second at 640x480 (forward pass
only, batch 1, float32), the real-time factor (processing time / stream
duration; 1.0 is real time), training iterations per second on 128x128
crops (batch 8), and the peak RSS of each measurement (a fresh subprocess
per preset, so the figures do not mix). The reference in the same run is
the paper preset ``unet3d.paper``: the ratio column is its time over the
preset's.

Where CUDA is present, every preset is measured on the GPU too, with
automatic mixed precision off and on (``device`` ``cuda`` / ``cuda+amp``):
windows per second at batch 1 and 8 (synchronised timings), real-time factor,
and the peak GPU memory (``torch.cuda.max_memory_allocated``).

Run: ``python benchmarks/bench_models.py [--windows 3] [--no-cuda]``
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

from _common import report

_CHILD = r"""
import json, sys, time
import torch
from edeflare.models import create_model
name, windows = sys.argv[1], int(sys.argv[2])
torch.manual_seed(0)
model = create_model(name).eval()
x = torch.randn(1, 1, 8, 480, 640)
with torch.no_grad():
    model(x)
    t0 = time.perf_counter()
    for _ in range(windows):
        model(x)
infer = (time.perf_counter() - t0) / windows
model.train()
opt = torch.optim.Adam(model.parameters(), lr=1e-4)
xb, yb = torch.randn(8, 1, 8, 128, 128), torch.randn(8, 1, 8, 128, 128)
def step():
    loss = torch.nn.functional.mse_loss(model(xb), yb)
    opt.zero_grad(); loss.backward(); opt.step()
step()
t0 = time.perf_counter()
for _ in range(windows):
    step()
it = (time.perf_counter() - t0) / windows
hwm = next(l for l in open("/proc/self/status") if l.startswith("VmHWM")).split()[1]
print(json.dumps({"params": sum(p.numel() for p in model.parameters()), "infer_s": infer,
                  "train_s": it, "peak_rss_mib": int(hwm) / 1024,
                  "threads": torch.get_num_threads()}))
"""


_CUDA_CHILD = r"""
import json, sys, time
import torch
from edeflare.models import create_model
name, windows, amp = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"
torch.manual_seed(0)
dev = torch.device("cuda")
model = create_model(name).to(dev).eval()
out = {}
for batch in (1, 8):
    x = torch.randn(batch, 1, 8, 480, 640, device=dev)
    torch.cuda.reset_peak_memory_stats()
    with torch.inference_mode(), torch.autocast("cuda", enabled=amp):
        for _ in range(2):
            model(x)
        torch.cuda.synchronize()
        t0 = time.perf_counter()
        for _ in range(windows):
            model(x)
        torch.cuda.synchronize()
    out[f"s_per_window_b{batch}"] = (time.perf_counter() - t0) / (windows * batch)
    out[f"peak_gpu_mib_b{batch}"] = torch.cuda.max_memory_allocated() / 2**20
out["gpu"] = torch.cuda.get_device_name()
print(json.dumps(out))
"""


def _cuda_rows(windows: int) -> list[dict[str, object]]:
    import torch

    from edeflare.models import list_models

    if not torch.cuda.is_available():
        return []
    rows = []
    for name in list_models():
        for amp in (False, True):
            r = json.loads(
                subprocess.run(
                    [sys.executable, "-c", _CUDA_CHILD, name, str(max(windows, 10)), str(int(amp))],
                    check=True,
                    capture_output=True,
                    text=True,
                ).stdout
            )
            rows.append(
                {
                    "preset": name,
                    "device": "cuda+amp" if amp else "cuda",
                    "gpu": r["gpu"],
                    "windows_per_s_b1": 1 / r["s_per_window_b1"],
                    "windows_per_s_b8": 1 / r["s_per_window_b8"],
                    "real_time_factor_b1": r["s_per_window_b1"] / 0.020,
                    "real_time_factor_b8": r["s_per_window_b8"] / 0.020,
                    "peak_gpu_mib_b1": r["peak_gpu_mib_b1"],
                    "peak_gpu_mib_b8": r["peak_gpu_mib_b8"],
                }
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--windows", type=int, default=3, help="timed repetitions per preset")
    parser.add_argument("--no-cuda", action="store_true", help="skip the GPU measurements")
    args = parser.parse_args()
    from edeflare.models import list_models

    results = {}
    for name in list_models():
        out = subprocess.run(
            [sys.executable, "-c", _CHILD, name, str(args.windows)],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        results[name] = json.loads(out)
    ref = results["unet3d.paper"]["infer_s"]
    rows = []
    for name, r in results.items():
        rows.append(
            {
                "preset": name,
                "parameters": r["params"],
                "s_per_window": r["infer_s"],
                "windows_per_s": 1 / r["infer_s"],
                "real_time_factor": r["infer_s"] / 0.020,
                "speedup_vs_paper": ref / r["infer_s"],
                "train_it_per_s": 1 / r["train_s"],
                "peak_RSS_MiB": r["peak_rss_mib"],
                "threads": r["threads"],
            }
        )
    report("models", rows, list(rows[0]))
    gpu_rows = [] if args.no_cuda else _cuda_rows(args.windows)
    if gpu_rows:
        print()
        report("models_cuda", gpu_rows, list(gpu_rows[0]))


if __name__ == "__main__":
    main()
