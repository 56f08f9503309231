#!/usr/bin/env bash
# Fit L (LW's command with the two flicker features), pair it with learned-absolute as P
# and score P as gated-experts scored M (run from the project root):
#   nohup bash experiments/lit-flicker/run.sh TRAIN FAERY_DATA FORWARD RUNS > RUNS/p.log 2>&1 &
#   python experiments/lit-flicker/rule_p.py RUNS
set -euo pipefail
train=$1 faery=$2 forward=$3 runs=$4
ratios=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
gated=free_support,free_rate_pixel,free_rate_8,free_rate_32,free_rate_128,free_rate_window,\
free_since_pixel
mkdir -p "$runs/L" "$runs/P"
edeflare train-head "$train" --weights night --out "$runs/L" --hidden 64,32 --epochs 12 \
    --context 8 --members 3 --no-progress --features "$ratios,$gated,rate_window,since_same,sync_64" \
    --relative-context --workers 2
edeflare bundle "$runs/L/model.safetensors" "$runs/P/model.safetensors" \
    --card unlit_model=learned-absolute > /dev/null
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" P
edeflare benchmark "$forward/test" --methods raw --model "P=$runs/P/model.safetensors" \
    --report "$runs/forward_P.md"
