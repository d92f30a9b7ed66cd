#!/usr/bin/env bash
# Issue 38 item 2, on tuning seeds only (500-509, docs/results/PROTOCOL.md): the card under the
# paper's goals (onnx/models/card-paper, trained on `dips datagen --card-goals paper` demos),
# with the card's search settings from either source:
#   code:  the authors' code's, the card's default (alpha 1e5, beta 0, last-segment g)
#   paper: the paper's (alpha 1e4, beta 1e3, cumulative g; --alpha --beta --cost-to-come)
# Usage: scripts/card-paper-tuning.sh [DIPS_BINARY] [VARIANT [METHODS]]
#   VARIANT: code or paper (default both); METHODS: a --methods list (default dips).
# Results: docs/results/card/paper-tuning-500-<variant>/ (resumes where it stopped).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/dips}
variants=${2:-code paper}
methods=${3:-dips}
[[ -x $bin ]] || { echo "error: $bin is missing: cargo build --release -p dips-cli" >&2; exit 1; }
for variant in $variants; do
    case $variant in
    code) search=() ;;
    paper) search=(--alpha 10000 --beta 1000 --cost-to-come cumulative) ;;
    *) echo "error: variant $variant: expected code or paper" >&2; exit 2 ;;
    esac
    "$bin" eval --task card --models onnx/models/card-paper --methods "$methods" \
        --first-seed 500 --trials 10 "${search[@]}" --jobs 1 --model-threads 1 \
        --animate none --episode-reports medians \
        --out "docs/results/card/paper-tuning-500-$variant"
done
