#!/usr/bin/env bash
# The second question's head H: F with a context reading counts relative to its window, on
# F's rows (run from the project root, after fit.sh):
#   nohup bash experiments/relative-rates/fit_relative_context.sh FAERY_DATA RUNS > RUNS/h.log 2>&1 &
set -euo pipefail
faery=$1 runs=$2
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
mkdir -p "$runs/H"
ln -f "$runs"/F/features-*.npz "$runs/H/"  # the rows do not depend on the context's input
edeflare train-head "$runs"/s0/* --weights night --out "$runs/H" --hidden 64,32 \
    --epochs 12 --context 8 --no-progress --features "$features" --relative-context
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" H
