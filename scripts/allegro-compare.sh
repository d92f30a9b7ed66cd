#!/usr/bin/env bash
# The Allegro driver measured (docs/allegro.md, "Measured"): DIPS episodes through the driver
# and the emulated hand beside the hand the emulator stands in for, on the same tuning seeds
# (below 1000: a diagnosis, not a registered evaluation), then one summary JSON.
#   scripts/allegro-compare.sh [SEEDS...]       (default 500 501 502)
# Needs target/release/dips; with target/release/dips-mujoco also the MuJoCo pairs
# (allegro:emulated,plant=mujoco beside --hand mujoco). Resumable: an episode whose
# result.json exists is not run again. Writes out/allegro-compare/ (ignored) and
# docs/results/allegro/compare.json.
set -euo pipefail
cd "$(dirname "$0")/.."
seeds=("$@")
[[ $# -eq 0 ]] && seeds=(500 501 502)
dips=target/release/dips
out=out/allegro-compare
hands=("world" "allegro:emulated")
if [[ -x target/release/dips-mujoco ]]; then
    hands+=("mujoco" "allegro:emulated,plant=mujoco")
fi
for task in card screwdriver; do
    for hand in "${hands[@]}"; do
        tag=${hand//[:,=]/-}
        for seed in "${seeds[@]}"; do
            dir=$out/$task/$tag/seed-$seed
            [[ -f $dir/result.json ]] && continue
            mkdir -p "$(dirname "$dir")"
            echo "== $task $hand seed $seed" >&2
            "$dips" episode --task "$task" --method dips --seed "$seed" --hand "$hand" \
                --out "$dir" >/dev/null 2>"$dir.log" || echo "   failed: $dir.log" >&2
        done
    done
done
python3 scripts/allegro-summary.py "$out" docs/results/allegro/compare.json
