#!/usr/bin/env python3
"""What each executed screwdriver turn turned, by what came before it.

Usage: scripts/turn_runs.py EVAL_DIR [EVAL_DIR ...]
       scripts/turn_runs.py --probe PROBE.txt

Reads every episode's `result.json` under `EVAL_DIR/episodes/` of one or more screwdriver
`dips eval` runs (every method) and groups the executed turns by the mode that last reset the
grasp (`start`, `thumb-middle-regrasp` or `index-regrasp`) and by how many turns ran since it.
Per group it prints the number of turns, the mean and median yaw change in the world (rad;
negative is turning the right way) and how many of those turns left the object invalid
(tipped). The table "What a turn yields" of docs/results/README.md is its output.

With `--probe` it reads instead what the `mode_probe` example printed for episodes
(`cargo run --release -p dips-cli --example mode_probe -- RESULT.json ...`) and groups its
turns the same way: per group the executed and the diffused (model's) mean yaw change and Ψ's
mean score.
"""
import glob
import json
import os
import re
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


def keyed_turns(modes):
    """For a sequence of (mode, value) in execution order, yield ((reset, since), value) for
    every turn: the mode that last reset the grasp (`start` before any regrasp) and the turns
    run since it."""
    since, reset = 0, "start"
    for mode, value in modes:
        if mode != "turn":
            since, reset = 0, mode
            continue
        yield (reset, since), value
        since += 1


def main(dirs):
    yaws = defaultdict(list)
    tipped = defaultdict(int)
    count = 0
    for path, runs in episodes(dirs):
        count += 1
        try:
            turns = [
                (
                    run["mode"],
                    (
                        run["end_state"][-1] - run["start_state"][-1],
                        all(s["valid"] for s in run["steps"]),
                    ),
                )
                for run in runs
            ]
        except (KeyError, IndexError, TypeError) as e:
            sys.exit(f"turn_runs.py: {path}: a mode run without states or steps ({e!r})")
        for key, (change, valid) in keyed_turns(turns):
            yaws[key].append(change)
            tipped[key] += not valid
    print(f"{count} episodes")
    print("| last grasp reset | turns since | turns | yaw change mean (rad) | median | tipped |")
    print("|---|---|---|---|---|---|")
    for key in sorted(yaws):
        v = yaws[key]
        print(
            f"| {key[0]} | {key[1]} | {len(v)} | {st.mean(v):+.3f} | {st.median(v):+.3f} "
            f"| {tipped[key]} |"
        )


PROBE_LINE = re.compile(
    r"\s+(\S+)\s+start \S+: executed (\S+), diffused (\S+);.*Ψ (\S+)"
)


def probe(path):
    try:
        with open(path) as f:
            lines = f.readlines()
    except OSError as e:
        sys.exit(f"turn_runs.py: cannot read {path} ({e!r})")
    # One (mode, (executed, diffused, Ψ)) list per episode, in mode_probe's order.
    episodes = []
    for line in lines:
        if line.rstrip().endswith(".json:"):
            episodes.append([])
            continue
        m = PROBE_LINE.match(line)
        if m and episodes:
            episodes[-1].append((m.group(1), tuple(float(m.group(i)) for i in (2, 3, 4))))
    groups = defaultdict(list)
    for modes in episodes:
        for key, value in keyed_turns(modes):
            groups[key].append(value)
    if not groups:
        sys.exit(f"turn_runs.py: {path} holds no mode_probe lines of episode turns")
    print(f"{len(episodes)} episodes")
    print("| last grasp reset | turns since | turns | executed mean (rad) | diffused mean | Ψ mean |")
    print("|---|---|---|---|---|---|")
    for key in sorted(groups):
        v = groups[key]
        ex, di, psi = (st.mean(x[i] for x in v) for i in range(3))
        print(f"| {key[0]} | {key[1]} | {len(v)} | {ex:+.3f} | {di:+.3f} | {psi:.3f} |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__.strip())
    if sys.argv[1] == "--probe":
        if len(sys.argv) != 3:
            sys.exit("usage: scripts/turn_runs.py --probe PROBE.txt")
        probe(sys.argv[2])
    else:
        main(sys.argv[1:])
