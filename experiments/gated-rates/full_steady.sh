#!/usr/bin/env bash
# Run LFS: LF's command (full.sh) on eflare-train and the steady lamps of study steady-lamps
# (run from the project root):
#   python experiments/steady-lamps/simulate.py STEADY
#   nohup bash experiments/gated-rates/full_steady.sh TRAIN STEADY FAERY_DATA FORWARD RUNS > RUNS/lfs.log 2>&1 &
# With a sixth argument PREFIX (e.g. steady-quiet) it fits on STEADY/PREFIX-640 and
# STEADY/PREFIX-1280 instead, as run LFQ (the quiet parts: steady-lamps/README.md):
#   nohup bash experiments/gated-rates/full_steady.sh TRAIN STEADY FAERY_DATA FORWARD RUNS steady-quiet > RUNS/lfq.log 2>&1 &
set -euo pipefail
train=$1 steady=$2 faery=$3 forward=$4 runs=$5 prefix=${6:-steady}
arm=$([ "$prefix" = steady ] && echo LFS || echo LFQ)
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since,free_support,free_rate_pixel,free_rate_8,free_rate_32,free_rate_128,\
free_rate_window,free_since_pixel
edeflare train-head "$train" "$steady/$prefix-640" "$steady/$prefix-1280" --weights night \
    --out "$runs/$arm" --hidden 64,32 --epochs 12 --context 8 --members 3 --no-progress \
    --features "$features" --relative-context
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" "$arm"
edeflare benchmark "$forward/test" --methods raw --model "$arm=$runs/$arm/model.safetensors" \
    --report "$runs/forward_$arm.md"
