#!/usr/bin/env bash
# H's form again at seed 1, its rows drawn anew (run from the project root, after
# fit_relative_context.sh):
#   nohup bash experiments/relative-rates/fit_seed1.sh FAERY_DATA RUNS > RUNS/h1.log 2>&1 &
set -euo pipefail
faery=$1 runs=$2
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
edeflare train-head "$runs"/s0/* --weights night --out "$runs/H1" --hidden 64,32 \
    --epochs 12 --context 8 --no-progress --features "$features" --relative-context --seed 1
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" H1
