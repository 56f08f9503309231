#!/usr/bin/env bash
# The third question's run R: learned's full command with H's form (run from the project root):
#   nohup bash experiments/relative-rates/full.sh TRAIN FAERY_DATA FORWARD RUNS > RUNS/r.log 2>&1 &
# FORWARD: edeflare simulate FORWARD --recipe eflare-forward
set -euo pipefail
train=$1 faery=$2 forward=$3 runs=$4
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
edeflare train-head "$train" --weights night --out "$runs/R" --hidden 64,32 --epochs 12 \
    --context 8 --members 3 --no-progress --features "$features" --relative-context
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" R
edeflare benchmark "$forward/test" --methods raw --model R="$runs/R/model.safetensors" \
    --report "$runs/forward_R.md"
