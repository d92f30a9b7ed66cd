#!/usr/bin/env bash
# Issue 37, a first look at transfer: dips and dips-sampled executed on the MuJoCo hand and
# on our world, same TUNING seeds (500-504; seeds >= 1000 are reserved for registered
# evaluations), screwdriver limited to 4 modes (the paper's hardware) and card (5 modes, node
# budget 8). Resumable (dips-mujoco eval). Then scripts/mujoco-tuning.py writes
# docs/results/mujoco-tuning/results.json and prints the table of docs/mujoco.md.
# Usage: scripts/mujoco-tuning.sh [OUT]   (default OUT: /tmp/mjtune)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/mjtune}
bin=target/release/dips-mujoco
[[ -x $bin ]] || (cd host/mujoco && cargo build --release --bins)
for hand in mujoco world; do
    "$bin" eval --task screwdriver --methods dips,dips-sampled --seeds 500..505 --hand "$hand" \
        --max-modes 4 --threads 1 --out "$out/screwdriver-$hand"
    "$bin" eval --task card --methods dips,dips-sampled --seeds 500..505 --hand "$hand" \
        --node-budget 8 --threads 1 --out "$out/card-$hand"
done
python3 scripts/mujoco-tuning.py "$out" docs/results/mujoco-tuning/results.json
