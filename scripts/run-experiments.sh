#!/usr/bin/env bash
# The paper's experiments (issue "DIPS end to end", item 4): `dips eval` for both tasks, every
# method, 10 trials each on seeds 1000–1009 (no model or setting was tuned on them), with the
# shipped models and the default settings (sampler ddim:8, 300 s planning budget).
#
# Every episode's result.json stays under $WORK/<task>/episodes (not committed); the tables,
# results.json and plots are copied to docs/results/<task>/. Resumable: rerun after a kill.
# Environment: WORK (default target/eval-work), TRIALS (default 10), METHODS (default: all).
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${WORK:-target/eval-work}
TRIALS=${TRIALS:-10}
cargo build --release -p dips-cli
DIPS=target/release/dips
for task in card screwdriver; do
  out="$WORK/$task"
  args=(eval --task "$task" --trials "$TRIALS" --out "$out")
  if [[ -n "${METHODS:-}" ]]; then args+=(--methods "$METHODS"); fi
  start=$(date +%s)
  "$DIPS" "${args[@]}"
  echo "== $task: $(( $(date +%s) - start )) s"
  mkdir -p "docs/results/$task"
  cp "$out"/results.json "$out"/results.md "$out"/eval.json "docs/results/$task/"
  cp "$out"/*.svg "$out"/*.png "docs/results/$task/" 2>/dev/null || true
done
