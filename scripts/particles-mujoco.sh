#!/usr/bin/env bash
# Issue 34 item 3 on TUNING seeds (500-509): dips, dips-k1 and dips-max-likelihood executed on
# the MuJoCo hand, 4 modes (the paper's hardware), without and with tracker noise (1 mm and
# 0.02 rad per axis, about an Aruco tag's). Resumable (dips eval). Then
#   scripts/particles-mujoco.py docs/particles/mujoco.json clean=OUT/clean noisy=OUT/noisy
# Usage: scripts/particles-mujoco.sh [OUT]   (default OUT: target/particles/mujoco)
# Needs target/release/dips-mujoco (scripts/mujoco-test.sh builds it); `dips --hand mujoco`
# hands the run to it.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/particles/mujoco}
bin=target/release/dips-mujoco
[[ -x $bin ]] || scripts/mujoco-test.sh
common=(--task screwdriver --methods dips,dips-k1,dips-max-likelihood --first-seed 500
        --trials 10 --hand mujoco --max-modes 4 --jobs 1 --model-threads 1
        --episode-reports medians --animate none)
"$bin" eval "${common[@]}" --out "$out/clean"
"$bin" eval "${common[@]}" --noise-position 0.001 --noise-rotation 0.02 --out "$out/noisy"
