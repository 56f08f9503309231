#!/usr/bin/env bash
# The heads F (no absolute rate feature, six relative ones) and G (the defaults and the six),
# on rate-thinning's subset and D's drawn rows (run from the project root, after
# rate-thinning's fit_context.sh has fitted D):
#   nohup bash experiments/relative-rates/fit.sh FAERY_DATA RUNS > RUNS/rel.log 2>&1 &
set -euo pipefail
faery=$1 runs=$2
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
relative=rel_pixel,rel_8,rel_32,rel_128,rel_support,rel_since
no_rates=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance
defaults=$(python -c "from edeflare.models.event_features import DEFAULT_FEATURES as d; print(','.join(d))")
fit() {  # fit NAME FEATURES
    python experiments/rate-thinning/columns.py "$runs/D" "$runs/$1" "$2"
    edeflare train-head "$runs"/s0/* --weights night --out "$runs/$1" --hidden 64,32 \
        --epochs 12 --context 8 --no-progress --features "$2"
}
fit F "$no_rates,$relative" & fit G "$defaults,$relative" & wait
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" F G
