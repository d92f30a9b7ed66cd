#!/usr/bin/env bash
# Issue 37 item 6, the transfer experiment (registered: docs/results/PROTOCOL.md, seeds
# 10100-10109): both tasks, five methods, three arms on the same seeds: our world, the MuJoCo
# hand, the MuJoCo hand with tracker noise. Two lanes (one per task) run at once, each one
# episode at a time on one model thread; every run is `dips eval --protocol`, so it resumes
# where it stopped and refuses settings that differ from the protocol. Needs dips-mujoco
# (scripts/mujoco-test.sh builds it). Then scripts/transfer-table.py writes the table.
# Usage: scripts/transfer-10100.sh [ARM...]   (default: mujoco world mujoco-noisy)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=target/release/dips-mujoco
[[ -x $bin ]] || { echo "error: $bin is missing: run scripts/mujoco-test.sh first" >&2; exit 1; }
arms=("$@")
[[ ${#arms[@]} -gt 0 ]] || arms=(mujoco world mujoco-noisy)
# The run's flags must resolve to the protocol's settings (the tool checks them).
hand_flags() {
    case $1 in
        world) echo "--hand world" ;;
        mujoco) echo "--hand mujoco" ;;
        mujoco-noisy) echo "--hand mujoco --noise-position 0.001 --noise-rotation 0.02" ;;
        *) echo "error: unknown arm $1 (world, mujoco, mujoco-noisy)" >&2; exit 2 ;;
    esac
}
lane() {
    local task=$1 arm
    shift
    for arm in "${arms[@]}"; do
        # A finished run keeps only its median episodes in git; resuming it would run the
        # others again, so a run with results.json is skipped.
        if [[ -f docs/results/$task/transfer-10100-$arm/results.json ]]; then
            echo "$task transfer-10100-$arm: finished, skipped"
            continue
        fi
        # shellcheck disable=SC2046
        "$bin" eval --protocol "docs/results/protocols/$task-transfer-10100-$arm.json" \
            --out "docs/results/$task/transfer-10100-$arm" --jobs 1 --model-threads 1 \
            --animate none --episode-reports medians $(hand_flags "$arm") "$@"
    done
}
lane screwdriver --max-modes 4 &
lane card --node-budget 8 &
wait
