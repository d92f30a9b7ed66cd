#!/usr/bin/env bash
# A finished `dips eval --episode-reports medians` run keeps only its median episodes in git
# (the ones with report.html, which the run's report.html links; results.json holds every
# trial's figures). This moves the other episodes out of the tree, to
# target/kept-episodes/<task>/<run>/episodes/ (a local copy: every episode regenerates bit for bit from
# the protocol and the commit in registration.json).
# Usage: scripts/keep-medians.sh RUN_DIR...   (e.g. docs/results/card/paper-10300-seed0)
set -euo pipefail
cd "$(dirname "$0")/.."
[[ $# -gt 0 ]] || { echo "usage: scripts/keep-medians.sh RUN_DIR..." >&2; exit 2; }
for run in "$@"; do
    run=${run%/}
    [[ -f $run/results.json ]] || { echo "error: $run has no results.json: the run is not finished" >&2; exit 1; }
    task=$(basename "$(dirname "$run")")
    dest=target/kept-episodes/$task/$(basename "$run")
    moved=0
    for episode in "$run"/episodes/*/*/; do
        episode=${episode%/}
        [[ -f $episode/report.html ]] && continue
        method=$(basename "$(dirname "$episode")")
        mkdir -p "$dest/episodes/$method"
        rm -rf "${dest:?}/episodes/$method/$(basename "$episode")"
        mv "$episode" "$dest/episodes/$method/"
        moved=$((moved + 1))
    done
    echo "$run: kept $(find "$run/episodes" -name report.html | wc -l) median episodes, moved $moved to $dest"
done
