#!/usr/bin/env bash
# The third question's head E (run from the project root, after fit_context.sh):
#   nohup bash experiments/rate-thinning/fit_no_rates.sh TRAIN FAERY_DATA RUNS > RUNS/e.log 2>&1 &
# RUNS/E gets D's drawn rows with the rate columns left out, under train-head's cache names.
set -euo pipefail
train=$1 faery=$2 runs=$3
here=experiments/rate-thinning
features=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance
python $here/columns.py "$runs/D" "$runs/E" "$features"
edeflare train-head "$runs"/s0/* --weights night --out "$runs/E" --hidden 64,32 \
    --epochs 12 --context 8 --no-progress --features "$features"
bash $here/score_arms.sh "$faery" "$runs" E
