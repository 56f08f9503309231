#!/usr/bin/env bash
# Make M (LW's heads, learned's where no light is found) and score it as gated-rates scores
# its runs (run from the project root):
#   nohup bash experiments/gated-experts/score.sh LW_WEIGHTS FAERY_DATA FORWARD RUNS > RUNS/m.log 2>&1 &
#   python experiments/relative-rates/rule_s.py RUNS M
set -euo pipefail
lw=$1 faery=$2 forward=$3 runs=$4
mkdir -p "$runs/M"
edeflare bundle "$lw" "$runs/M/model.safetensors" --card unlit_model=learned > /dev/null
cp "$(dirname "$lw")/head.json" "$runs/M/head.json"
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" M
edeflare benchmark "$forward/test" --methods raw --model "M=$runs/M/model.safetensors" \
    --report "$runs/forward_M.md"
