#!/usr/bin/env bash
# The fourth question's head I: H with rate_window, on D's rows (run from the project root):
#   nohup bash experiments/relative-rates/fit_window_rate.sh FAERY_DATA RUNS > RUNS/i.log 2>&1 &
set -euo pipefail
faery=$1 runs=$2
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since,rate_window
python experiments/rate-thinning/columns.py "$runs/D" "$runs/I" "$features"
edeflare train-head "$runs"/s0/* --weights night --out "$runs/I" --hidden 64,32 \
    --epochs 12 --context 8 --no-progress --features "$features" --relative-context
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" I
