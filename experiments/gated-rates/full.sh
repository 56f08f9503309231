#!/usr/bin/env bash
# Run LF: learned's full command with R's form (experiments/relative-rates) and the seven
# light-free features (run from the project root):
#   nohup bash experiments/gated-rates/full.sh TRAIN FAERY_DATA FORWARD RUNS > RUNS/lf.log 2>&1 &
# TRAIN: edeflare simulate TRAIN --recipe eflare-train; FORWARD: --recipe eflare-forward
# With a fifth argument "absolute": run LFA, the same without --relative-context (its
# context reads absolute counts, as learned's does):
#   nohup bash experiments/gated-rates/full.sh TRAIN FAERY_DATA FORWARD RUNS absolute > RUNS/lfa.log 2>&1 &
# With "every": run LE, LF's relative context with learned's seven absolute features read in
# every window in place of their light-free twins:
#   nohup bash experiments/gated-rates/full.sh TRAIN FAERY_DATA FORWARD RUNS every > RUNS/le.log 2>&1 &
# With "window": run LW, LF with rate_window read in every window:
#   nohup bash experiments/gated-rates/full.sh TRAIN FAERY_DATA FORWARD RUNS window > RUNS/lw.log 2>&1 &
# With "every-thin": run LET, LE trained on thinned windows (--thin 0.25):
#   nohup bash experiments/gated-rates/full.sh TRAIN FAERY_DATA FORWARD RUNS every-thin > RUNS/let.log 2>&1 &
# With "relative-thin": run LFT, LF trained on windows thinned over two decades (--thin 0.01):
#   nohup bash experiments/gated-rates/full.sh TRAIN FAERY_DATA FORWARD RUNS relative-thin > RUNS/lft.log 2>&1 &
set -euo pipefail
train=$1 faery=$2 forward=$3 runs=$4 form=${5:-relative}
ratios=net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,\
balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,\
rel_support,rel_since
gated=free_support,free_rate_pixel,free_rate_8,free_rate_32,free_rate_128,free_rate_window,\
free_since_pixel
ungated=support,rate_pixel,rate_8,rate_32,rate_128,rate_window,since_pixel
thin=()
case $form in
    relative) arm=LF context=(--relative-context) rates=$gated ;;
    absolute) arm=LFA context=() rates=$gated ;;
    every) arm=LE context=(--relative-context) rates=$ungated ;;
    window) arm=LW context=(--relative-context) rates=$gated,rate_window ;;
    every-thin) arm=LET context=(--relative-context) rates=$ungated thin=(--thin 0.25) ;;
    relative-thin) arm=LFT context=(--relative-context) rates=$gated thin=(--thin 0.01) ;;
    *) echo "form must be relative, absolute, every, window, every-thin or relative-thin," \
        "got $form" >&2; exit 2 ;;
esac
features=$ratios,$rates
# --workers 2: the rows of one process, drawn by two (LF, LFA and LE drew theirs in one)
edeflare train-head "$train" --weights night --out "$runs/$arm" --hidden 64,32 --epochs 12 \
    --context 8 --members 3 --no-progress --features "$features" "${context[@]}" "${thin[@]}" \
    --workers 2
bash experiments/rate-thinning/score_arms.sh "$faery" "$runs" "$arm"
edeflare benchmark "$forward/test" --methods raw --model "$arm=$runs/$arm/model.safetensors" \
    --report "$runs/forward_$arm.md"
