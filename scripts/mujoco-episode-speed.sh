#!/usr/bin/env bash
# Issue 37 item 7, a whole episode's cost on the MuJoCo hand against our world: `dips` on
# tuning seed 500 (screwdriver 4 modes, card node budget 8), the two hands' episodes of a
# task run at the same time so that they share the machine's load alike; CPU time (user) and
# wall time from /usr/bin/time. Writes docs/results/mujoco-speed/episode-speed.json.
# Usage: scripts/mujoco-episode-speed.sh [OUT]   (episodes; default /tmp/mjspeed)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/mjspeed}
bin=target/release/dips-mujoco
[[ -x $bin ]] || { echo "error: $bin is missing: run scripts/mujoco-test.sh first" >&2; exit 1; }
mkdir -p "$out" docs/results/mujoco-speed
for task in screwdriver card; do
    case $task in screwdriver) extra=(--max-modes 4) ;; card) extra=(--node-budget 8) ;; esac
    pids=()
    for hand in world mujoco; do
        /usr/bin/time -f '{"wall_s": %e, "user_s": %U}' -o "$out/$task-$hand.time" \
            "$bin" episode --task "$task" --method dips --seed 500 "${extra[@]}" --hand "$hand" \
            --out "$out/$task-$hand" > "$out/$task-$hand.log" 2>&1 &
        pids+=($!)
    done
    for p in "${pids[@]}"; do wait "$p"; done
done
python3 - "$out" <<'PY'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
res = {"command": "scripts/mujoco-episode-speed.sh", "method": "dips", "seed": 500, "tasks": {}}
for task in ["screwdriver", "card"]:
    t = {h: json.loads((out / f"{task}-{h}.time").read_text()) for h in ["world", "mujoco"]}
    t["user_ratio_mujoco_over_world"] = t["mujoco"]["user_s"] / t["world"]["user_s"]
    t["wall_ratio_mujoco_over_world"] = t["mujoco"]["wall_s"] / t["world"]["wall_s"]
    res["tasks"][task] = t
    print(task, t)
dest = pathlib.Path("docs/results/mujoco-speed/episode-speed.json")
dest.write_text(json.dumps(res, indent=1) + "\n")
PY
