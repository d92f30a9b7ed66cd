#!/usr/bin/env bash
# Runs registered protocols one after the other (docs/results/PROTOCOL.md), one episode at a
# time, each into docs/results/<task>/<name without the task>/ with the models the protocol
# names. Every run is `dips eval --protocol`: it resumes where it stopped and refuses settings
# that differ from the protocol; a run whose directory has results.json is finished and skipped
# (finished runs keep only their median episodes in git: resuming would run the others again).
# Usage: scripts/run-protocols.sh DIPS_BINARY NAME...
#   NAME: a protocol's name, docs/results/protocols/NAME.json (run two copies with different
#   names to use two cores).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:?usage: scripts/run-protocols.sh DIPS_BINARY NAME...}
shift
[[ $# -gt 0 ]] || { echo "error: no protocol named" >&2; exit 2; }
[[ -x $bin ]] || { echo "error: $bin is missing: cargo build --release -p dips-cli" >&2; exit 1; }
for name in "$@"; do
    protocol=docs/results/protocols/$name.json
    [[ -f $protocol ]] || { echo "error: $protocol does not exist" >&2; exit 1; }
    # The run's flags from the protocol's settings: a run must give the protocol's values.
    mapfile -t flags < <(python3 - "$protocol" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))["eval"]["episode"]
print(e["task"])
for key in ("models", "sampler", "time_budget_s", "node_budget", "max_modes", "cost_to_come",
            "search_depth", "alpha", "beta", "engine", "card_goals", "hand", "stop_rule", "first_mode",
            "planner_size", "exec_profile", "pose_estimate", "regrasp_guard", "press"):
    if e.get(key) is not None:
        print("--" + key.replace("_", "-"))
        print(e[key])
for key in ("position", "rotation"):
    if (e.get("tracker_noise") or {}).get(key) is not None:
        print("--noise-" + key)
        print(e["tracker_noise"][key])
PY
)
    task=${flags[0]}
    flags=("${flags[@]:1}")
    out=docs/results/$task/${name#"$task"-}
    if [[ -f $out/results.json ]]; then
        echo "$name: finished ($out/results.json), skipped"
        continue
    fi
    "$bin" eval --protocol "$protocol" --out "$out" --jobs 1 --model-threads 1 \
        --animate none --episode-reports medians "${flags[@]}"
done
