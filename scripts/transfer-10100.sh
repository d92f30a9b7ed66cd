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
# One lane per task; scripts/run-protocols.sh takes every flag (hand, tracker noise, max
# modes, node budget) from the protocol and skips a finished run.
lane() {
    local task=$1 arm names=()
    for arm in "${arms[@]}"; do
        case $arm in
            world | mujoco | mujoco-noisy) names+=("$task-transfer-10100-$arm") ;;
            *) echo "error: unknown arm $arm (world, mujoco, mujoco-noisy)" >&2; exit 2 ;;
        esac
    done
    scripts/run-protocols.sh "$bin" "${names[@]}"
}
lane screwdriver &
lane card &
wait
