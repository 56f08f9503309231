#!/usr/bin/env bash
# The fifth question's head J: H with light dropout, on F's rows so changed (run from the
# project root, after fit.sh):
#   nohup bash experiments/relative-rates/fit_light_dropout.sh FAERY_DATA RUNS > RUNS/j.log 2>&1 &
set -euo pipefail
faery=$1 runs=$2
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
python experiments/relative-rates/drop_lights.py "$runs/F" "$runs/J"
edeflare train-head "$runs"/s0/* --weights night --out "$runs/J" --hidden 64,32 \
    --epochs 12 --context 8 --no-progress --features "$features" --relative-context
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" J
