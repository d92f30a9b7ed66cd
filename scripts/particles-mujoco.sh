#!/usr/bin/env bash
# Issue 34 item 3 on TUNING seeds (500-509): dips, dips-k1 and dips-max-likelihood executed on
# the MuJoCo hand, 4 modes (the paper's hardware), without and with tracker noise (1 mm and
# 0.02 rad per axis, about an Aruco tag's). Resumable (dips-mujoco eval). Then
#   scripts/particles-mujoco.py docs/particles/mujoco.json clean=OUT/clean noisy=OUT/noisy
# Usage: scripts/particles-mujoco.sh [OUT] [BIN]   (defaults: target/particles/mujoco,
# target/release/dips-mujoco)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/particles/mujoco}
bin=${2:-target/release/dips-mujoco}
[[ -x $bin ]] || (cd host/mujoco && cargo build --release --bins)
common=(--task screwdriver --methods dips,dips-k1,dips-max-likelihood --seeds 500..510
        --hand mujoco --max-modes 4 --threads 1)
"$bin" eval "${common[@]}" --out "$out/clean"
"$bin" eval "${common[@]}" --noise-position 0.001 --noise-rotation 0.02 --out "$out/noisy"
