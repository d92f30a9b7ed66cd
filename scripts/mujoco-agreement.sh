#!/usr/bin/env bash
# Issue 37 item 5, one-step agreement of our world with the MuJoCo hand along CSVTO episodes
# executed on MuJoCo (tuning seeds 0-2): the screwdriver's first four modes of the prior's
# sequence, the card's `both,both,both`. Each recorded step is replayed on our world from the
# state MuJoCo measured before it, with the command CSVTO sent (the dips-world example
# one_step_agreement). Writes docs/results/mujoco-agreement/agreement.json.
# Usage: scripts/mujoco-agreement.sh [OUT]   (episodes; default /tmp/mjagree). Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-/tmp/mjagree}
bin=target/release/dips-mujoco
[[ -x $bin ]] || { echo "error: $bin is missing: run scripts/mujoco-test.sh first" >&2; exit 1; }
cargo build --release -p dips-world --example one_step_agreement
files=()
for s in 0 1 2; do
    d=$out/screwdriver-$s
    [[ -f $d/result.json ]] || "$bin" episode --task screwdriver --method csvto-sampled \
        --max-modes 4 --hand mujoco --seed "$s" --out "$d"
    files+=("$d/result.json")
    d=$out/card-$s
    [[ -f $d/result.json ]] || "$bin" episode --task card --method csvto-sampled \
        --modes both,both,both --hand mujoco --seed "$s" --out "$d"
    files+=("$d/result.json")
done
mkdir -p docs/results/mujoco-agreement
target/release/examples/one_step_agreement docs/results/mujoco-agreement/agreement.json "${files[@]}"
