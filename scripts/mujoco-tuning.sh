#!/usr/bin/env bash
# Issue 37, a first look at transfer: dips and dips-sampled executed on the MuJoCo hand and
# on our world, same TUNING seeds (500-504; seeds >= 1000 are reserved for registered
# evaluations), screwdriver limited to 4 modes (the paper's hardware) and card (5 modes, node
# budget 8). `dips eval --hand mujoco|world`, one episode at a time on one model thread, run
# by dips-mujoco (the dips command line with the MuJoCo hand); resumable. Then
# scripts/mujoco-tuning.py writes
# docs/results/mujoco-tuning/results.json and prints the table of docs/mujoco.md.
# Usage: scripts/mujoco-tuning.sh [OUT]   (default OUT: /tmp/mjtune)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/mjtune}
bin=target/release/dips-mujoco
[[ -x $bin ]] || (cd host/mujoco && cargo build --release --bins)
common=(--methods dips,dips-sampled --first-seed 500 --trials 5 --jobs 1 --model-threads 1
        --animate none --episode-reports medians --quiet)
for hand in mujoco world; do
    "$bin" eval --task screwdriver "${common[@]}" --hand "$hand" --max-modes 4 \
        --out "$out/screwdriver-$hand"
    "$bin" eval --task card "${common[@]}" --hand "$hand" --node-budget 8 --out "$out/card-$hand"
done
python3 scripts/mujoco-tuning.py "$out" docs/results/mujoco-tuning/results.json
