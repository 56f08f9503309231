#!/usr/bin/env bash
# Study fast-head, end to end (run from the project root, .venv active):
#   nohup bash experiments/fast-head/run.sh TRAIN FORWARD FAERY_DATA RUNS > RUNS/fast.log 2>&1 &
# TRAIN: edeflare simulate TRAIN --recipe eflare-train; FORWARD: --recipe eflare-forward;
# FAERY_DATA: faery-0.7.1/tests/data (benchmarks/night_recording.py says how to fetch it).
# A step whose output exists is skipped, so a killed run resumes where it stopped.
set -euo pipefail
train=$1 forward=$2 faery=$3 runs=$4
out=experiments/fast-head/results
mkdir -p "$out" "$runs"
student=$runs/fast/model.safetensors
if [ ! -f "$student" ]; then
    edeflare train-head "$train" --weights night --out "$runs/fast" --hidden 16 --epochs 12 \
        --context 8 --context-widths 8,16,32,32 --no-progress \
        --teacher src/edeflare/assets/learned.safetensors
fi
cp "$runs/fast/head.json" "$out/head.json" 2>/dev/null || true
[ -f "$out/score.json" ] || python experiments/near-objects/score.py "$student" \
    "$out/score.json" "$faery"
[ -f "$out/forward.md" ] || edeflare benchmark "$forward/test" --methods raw \
    --model fast="$student" --report "$out/forward.md"
if [ ! -f "$out/realtime.json" ]; then
    python benchmarks/bench_realtime.py --model "$student" --model learned \
        --only "model mask.pixel (onnx)" "model model" "model learned" raw \
        --name realtime_fast_head
    mv benchmarks/results/realtime_fast_head.json "$out/realtime.json"
fi
