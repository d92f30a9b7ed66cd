#!/usr/bin/env bash
# The paper's experiments (issue "DIPS end to end", item 4): `dips eval` for both tasks, every
# method, 10 trials each on seeds 1000–1009 (no model or setting was tuned on them), with the
# shipped models and the default sampler (ddim:16:1), with a 10 s planning budget per call
# (the paper's is 300 s; BUDGET overrides) so that both tasks fit about an hour on 2 cores.
#
# Every episode's result.json stays under $WORK/<task>/episodes (not committed); the tables,
# results.json and plots are copied to docs/results/<task>/. Resumable: rerun after a kill.
# Environment: WORK (default target/eval-work), TRIALS (default 10), BUDGET (default 10),
# METHODS (default: all), TASKS (default: card screwdriver), JOBS (episodes at once,
# default 1), SAMPLER (default: the CLI's, ddim:16:1).
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${WORK:-target/eval-work}
TRIALS=${TRIALS:-10}
BUDGET=${BUDGET:-10}
cargo build --release -p dips-cli
DIPS=target/release/dips
for task in ${TASKS:-card screwdriver}; do
  out="$WORK/$task"
  # One episode at a time on every core (model calls split their batch, CSVTO its
  # particles): the search gets the most expansions out of its time budget.
  args=(eval --task "$task" --trials "$TRIALS" --time-budget-s "$BUDGET" --jobs "${JOBS:-1}" --out "$out")
  if [[ -n "${METHODS:-}" ]]; then args+=(--methods "$METHODS"); fi
  if [[ -n "${SAMPLER:-}" ]]; then args+=(--sampler "$SAMPLER"); fi
  start=$(date +%s)
  "$DIPS" "${args[@]}"
  echo "== $task: $(( $(date +%s) - start )) s"
  mkdir -p "docs/results/$task"
  cp "$out"/results.json "$out"/results.md "$out"/eval.json "docs/results/$task/"
  cp "$out"/*.svg "$out"/*.png "docs/results/$task/" 2>/dev/null || true
done
