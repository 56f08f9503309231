#!/usr/bin/env bash
# P3: L's command with --seed 3, paired and scored as P (the paths are this run's: /work/data
# holds eflare-train, eflare-forward and faery's test data; /work/runs the runs).
#   nohup bash experiments/lit-flicker/run_seed.sh > /work/runs/p3.log 2>&1 &
set -euo pipefail
cd /work/main
export PATH=/work/main/.venv/bin:$PATH
runs=/work/runs
ratios=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,rel_support,rel_since
gated=free_support,free_rate_pixel,free_rate_8,free_rate_32,free_rate_128,free_rate_window,free_since_pixel
edeflare train-head /work/data/eflare-train --weights night --out $runs/L3 --hidden 64,32 --epochs 12 \
    --context 8 --members 3 --no-progress --features "$ratios,$gated,rate_window,since_same,sync_64" \
    --relative-context --workers 2 --seed 3
edeflare bundle $runs/L3/model.safetensors $runs/P3/model.safetensors --card unlit_model=learned-absolute > /dev/null
bash experiments/rate-thinning/score_arms.sh /work/data/faery-0.7.1/tests/data $runs P3
edeflare benchmark /work/data/eflare-forward/test --methods raw --model "P3=$runs/P3/model.safetensors" --report $runs/forward_P3.md
