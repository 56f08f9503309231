"""python experiments/gpu-paper/bundle.py: run1's weights as the bundled ``paper`` model.

Copies ``run1/paper_fp16.safetensors`` (float16) to ``src/edeflare/assets/paper.safetensors``
with its card's scores (``run1/eval_r_sim.json``, ``run1/eval_mini.json``) and the
command that made it. The tensors are unchanged. Run once, at commit 11fb71b, where
``run1/paper_fp16.safetensors`` was; it was removed from the tree afterwards (the same
tensors are the bundled file's: ``git show 11fb71b:experiments/gpu-paper/run1/paper_fp16.safetensors``).
"""

import dataclasses
import json
from pathlib import Path

from edeflare.models.weights import load_model, save_model

HERE = Path(__file__).parent
r_sim = json.loads((HERE / "run1/eval_r_sim.json").read_text())
mini = json.loads((HERE / "run1/eval_mini.json").read_text())
model, card = load_model(HERE / "run1/paper_fp16.safetensors")
metrics = {
    **card.metrics,
    **{f"eflare_r_sim_{k}": round(v, 4) for k, v in r_sim["means"]["paper"].items()},
    **{f"eflare_r_sim_recon_{k}": round(v, 4) for k, v in r_sim["downstream"]["paper"].items()
       if k != "windows"},
    **{f"eflare_mini_{k}": round(v, 4) for k, v in mini["means"]["paper"].items()},
}
card = dataclasses.replace(
    card,
    command="PYTHONPATH=.devsite:src python3 experiments/gpu-paper/run_device.py --out $OUT "
    "--physical 80 --forward 40 --val 8 --train-s 280 --deadline-s 545 (one NVIDIA H100, "
    "2026-11-26; stopped by its time limit at iteration 1252)",
    metrics=metrics,
)
save_model("src/edeflare/assets/paper.safetensors", model.half(), card)
print(json.dumps(metrics, indent=1))
