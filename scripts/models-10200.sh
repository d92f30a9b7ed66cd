#!/usr/bin/env bash
# Issue 38 items 3-4, the training-seed experiment (registered: docs/results/PROTOCOL.md):
# the screwdriver's three trained models (onnx/models/screwdriver, -seed1, -seed2), all seven
# methods on seeds 10200-10209, then dips, dips-k1 and dips-max-likelihood on 10210-10229.
# Every run is `dips eval --protocol`: it resumes where it stopped and refuses settings that
# differ from the protocol. Usage: scripts/models-10200.sh [DIPS_BINARY] [SET...]
#   SET: 10200 and/or 10210 (default both, in that order); one model after the other, one
#   episode at a time (run two copies with different SETs to use two cores).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/dips}
shift || true
sets=("$@")
[[ ${#sets[@]} -gt 0 ]] || sets=(10200 10210)
names=()
for set in "${sets[@]}"; do
    for seed in 0 1 2; do names+=("screwdriver-models-$set-seed$seed"); done
done
exec scripts/run-protocols.sh "$bin" "${names[@]}"
