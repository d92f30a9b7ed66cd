#!/usr/bin/env python3
"""What each executed screwdriver turn turned, by what came before it.

Usage: scripts/turn_runs.py EVAL_DIR [EVAL_DIR ...]

Reads every episode's `result.json` under `EVAL_DIR/episodes/` of one or more screwdriver
`dips eval` runs (every method) and groups the executed turns by the mode that last reset the
grasp (`start`, `thumb-middle-regrasp` or `index-regrasp`) and by how many turns ran since it.
Per group it prints the number of turns, the mean and median yaw change in the world (rad;
negative is turning the right way) and how many of those turns left the object invalid
(tipped). The table "What a turn yields" of docs/results/README.md is its output.
"""
import glob
import json
import os
import statistics as st
import sys
from collections import defaultdict


def episodes(dirs):
    """Every episode's result.json under the evaluation directories."""
    for d in dirs:
        paths = sorted(glob.glob(os.path.join(d, "episodes", "*", "seed-*", "result.json")))
        if not paths:
            sys.exit(f"turn_runs.py: {d} holds no episodes/<method>/seed-N/result.json")
        for path in paths:
            try:
                with open(path) as f:
                    r = json.load(f)
                runs = r["mode_runs"]
                if r["task"] != "screwdriver":
                    sys.exit(f"turn_runs.py: {path} is a {r['task']} episode, not a screwdriver one")
            except (OSError, ValueError, KeyError, TypeError) as e:
                sys.exit(f"turn_runs.py: {path} is not an episode result.json ({e!r})")
            yield path, runs


def main(dirs):
    yaws = defaultdict(list)
    tipped = defaultdict(int)
    count = 0
    for path, runs in episodes(dirs):
        count += 1
        since, reset = 0, "start"
        for run in runs:
            if run["mode"] != "turn":
                since, reset = 0, run["mode"]
                continue
            try:
                change = run["end_state"][-1] - run["start_state"][-1]
                valid = all(s["valid"] for s in run["steps"])
            except (KeyError, IndexError, TypeError) as e:
                sys.exit(f"turn_runs.py: {path}: a mode run without states or steps ({e!r})")
            yaws[(reset, since)].append(change)
            tipped[(reset, since)] += not valid
            since += 1
    print(f"{count} episodes")
    print("| last grasp reset | turns since | turns | yaw change mean (rad) | median | tipped |")
    print("|---|---|---|---|---|---|")
    for key in sorted(yaws):
        v = yaws[key]
        print(
            f"| {key[0]} | {key[1]} | {len(v)} | {st.mean(v):+.3f} | {st.median(v):+.3f} "
            f"| {tipped[key]} |"
        )


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__.strip())
    main(sys.argv[1:])
