#!/usr/bin/env bash
# The two fits side by side (one core each), then their scores. Run from the project root:
#   nohup bash experiments/rate-thinning/run.sh TRAIN FAERY_DATA RUNS > RUNS/run.log 2>&1 &
set -euo pipefail
train=$1 faery=$2 runs=$3
here=experiments/rate-thinning
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
python $here/subset.py "$train" "$runs/s0"
fit() {  # fit NAME [OPTIONS...]
    local name=$1; shift
    edeflare tune-head learned "$runs"/s0/* --out "$runs/$name" --no-progress \
        --real ../shared/data/real/atis_ncars_crop.dat --real-weight 1e-6 "$@"
}
fit A & fit B --thin 0.25 & wait
bash $here/score_arms.sh "$faery" "$runs" A B
