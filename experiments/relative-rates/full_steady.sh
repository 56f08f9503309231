#!/usr/bin/env bash
# The sixth question's run S: R's command (full.sh) on eflare-train and the steady lamps
# (run from the project root):
#   python experiments/steady-lamps/simulate.py STEADY
#   nohup bash experiments/relative-rates/full_steady.sh TRAIN STEADY FAERY_DATA FORWARD RUNS > RUNS/s.log 2>&1 &
# FORWARD: edeflare simulate FORWARD --recipe eflare-forward
set -euo pipefail
train=$1 steady=$2 faery=$3 forward=$4 runs=$5
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
edeflare train-head "$train" "$steady/steady-640" "$steady/steady-1280" --weights night \
    --out "$runs/S" --hidden 64,32 --epochs 12 --context 8 --members 3 --no-progress \
    --features "$features" --relative-context
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" S
edeflare benchmark "$forward/test" --methods raw --model S="$runs/S/model.safetensors" \
    --report "$runs/forward_S.md"
