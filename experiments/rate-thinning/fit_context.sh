#!/usr/bin/env bash
# The second question's two single context heads (run from the project root, after run.sh):
#   nohup bash experiments/rate-thinning/fit_context.sh TRAIN FAERY_DATA RUNS > RUNS/ctx.log 2>&1 &
# RUNS/D and RUNS/C get A's and B's drawn rows, linked under train-head's cache names.
set -euo pipefail
train=$1 faery=$2 runs=$3
here=experiments/rate-thinning
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
fit() {  # fit NAME [OPTIONS...]
    local name=$1; shift
    edeflare train-head "$runs"/s0/* --weights night --out "$runs/$name" --hidden 64,32 \
        --epochs 12 --context 8 --no-progress "$@"
}
python $here/link_rows.py "$runs/A" "$runs/D" 1
python $here/link_rows.py "$runs/B" "$runs/C" 0.25
fit D & fit C --thin 0.25 & wait
bash $here/score_arms.sh "$faery" "$runs" D C
