#!/usr/bin/env bash
# Score fitted arms: the half-rate probe and the four-phase real rows of each RUNS/ARM.
#   bash experiments/rate-thinning/score_arms.sh FAERY_DATA RUNS ARM...
set -euo pipefail
faery=$1 runs=$2; shift 2
for arm in "$@"; do
    python experiments/rate-thinning/thin_probe.py "$runs/$arm/model.safetensors" \
        "$runs/probe_$arm.json" 1 0.5 &
    python experiments/near-objects/score.py "$runs/$arm/model.safetensors" \
        "$runs/score_$arm.json" "$faery"
    wait
done
