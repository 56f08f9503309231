#!/usr/bin/env bash
# Fit A (LW's command on the lit windows) and B (learned-absolute's on the unlit ones), pair
# them as N and score N as gated-experts scored M (run from the project root):
#   nohup bash experiments/own-windows/run.sh TRAIN FAERY_DATA FORWARD RUNS > RUNS/n.log 2>&1 &
#   python experiments/own-windows/rule_n.py RUNS
# A reuses LW's drawn rows where RUNS/LW holds them (the same rows: the filter acts after
# the draw); B draws learned-absolute's rows again.
set -euo pipefail
train=$1 faery=$2 forward=$3 runs=$4
ratios=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
gated=free_support,free_rate_pixel,free_rate_8,free_rate_32,free_rate_128,free_rate_window,\
free_since_pixel
mkdir -p "$runs/A" "$runs/B" "$runs/N"
for f in "$runs"/LW/features-*.npz; do
    [ -e "$f" ] && ln -f "$f" "$runs/A/"
done
edeflare train-head "$train" --weights night --out "$runs/A" --hidden 64,32 --epochs 12 \
    --context 8 --members 3 --no-progress --features "$ratios,$gated,rate_window" \
    --relative-context --workers 2 --windows lit
edeflare train-head "$train" --weights night --out "$runs/B" --hidden 64,32 --epochs 12 \
    --context 8 --members 3 --no-progress --workers 2 --windows unlit
cp "$runs/B/model.safetensors" "$runs/N/unlit.safetensors"
edeflare bundle "$runs/A/model.safetensors" "$runs/N/model.safetensors" \
    --card unlit_model=unlit.safetensors > /dev/null
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" N
edeflare benchmark "$forward/test" --methods raw --model "N=$runs/N/model.safetensors" \
    --report "$runs/forward_N.md"
