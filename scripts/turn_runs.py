#!/usr/bin/env python3
"""What each executed screwdriver turn turned, by what came before it.

Usage: scripts/turn_runs.py EVAL_DIR [EVAL_DIR ...]
       scripts/turn_runs.py --probe PROBE.txt

Reads every episode's `result.json` under `EVAL_DIR/episodes/` of one or more screwdriver
`dips eval` runs (every method) and groups the executed turns by the mode that last reset the
grasp (`start`, `thumb-middle-regrasp` or `index-regrasp`) and by how many turns ran since it.
Per group it prints the number of turns, the mean and median yaw change in the world (rad;
negative is turning the right way) and how many of those turns left the object invalid
(tipped). The table "What a turn yields" of the old results notebook
(`git show 4a962a2:docs/results/README.md`) is its output.

With `--probe` it reads instead what the `mode_probe` example printed for episodes
(`cargo run --release -p dips-cli --example mode_probe -- RESULT.json ...`) and groups its
turns the same way: per group the executed and the diffused (model's) mean yaw change and Ψ's
mean score. When the probe ran with `--all-modes` (every mode probed at every executed start,
the executed one marked `*`), the groups are the executed starts, turn or not, keyed by the
turns executed before them, and each mode gets its mean diffused yaw change; with `--profile`
also split into row 1's change (the level the model put its segment at) and the change after
row 1 (what the segment turned).
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
    r"\s+(\*\s+)?(\S+)\s+start \S+: executed (\S+), diffused (\S+);.*Ψ (\S+)"
)

MODES = (("turn", "turn"), ("thumb-middle-regrasp", "TM regrasp"), ("index-regrasp", "index regrasp"))


def probe_records(lines):
    """mode_probe's lines of episodes, one list per episode in its order, each probe a list
    [executed (marked `*`), mode, executed change, diffused change, Ψ, row 1's change (with
    `--profile`, else None)]."""
    episodes = []
    for line in lines:
        if line.rstrip().endswith(".json:"):
            episodes.append([])
            continue
        m = PROBE_LINE.match(line)
        if m and episodes:
            values = [float(m.group(i)) for i in (3, 4, 5)]
            episodes[-1].append([m.group(1) is not None, m.group(2), *values, None])
        elif "profile, diffused:" in line and episodes and episodes[-1]:
            rows = [float(v) for v in line.split(":", 1)[1].split()]
            episodes[-1][-1][5] = rows[1] if len(rows) > 1 else None
    return episodes


def probe(path):
    try:
        with open(path) as f:
            lines = f.readlines()
    except OSError as e:
        sys.exit(f"turn_runs.py: cannot read {path} ({e!r})")
    episodes = probe_records(lines)
    if any(p[0] for probes in episodes for p in probes):
        probe_all_modes(path, episodes)
        return
    groups = defaultdict(list)
    for probes in episodes:
        modes = [(mode, (change, diffused, psi)) for _, mode, change, diffused, psi, _ in probes]
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


def probe_all_modes(path, episodes):
    """`mode_probe --all-modes [--profile]` output: one group per executed start."""
    groups = defaultdict(list)
    for probes in episodes:
        # mode_probe prints every mode once per start, in the task's order: a start's block
        # ends where a mode comes again.
        blocks = []
        for executed, mode, change, diffused, _, row1 in probes:
            if not blocks or mode in blocks[-1][1]:
                blocks.append([None, {}])
            blocks[-1][1][mode] = (diffused, row1)
            if executed:
                blocks[-1][0] = (mode, change)
        starts = [(ex[0], (ex[1], block)) for ex, block in blocks if ex is not None]
        since, reset = 0, "start"
        for mode, value in starts:
            groups[(reset, since)].append((mode, value))
            if mode == "turn":
                since += 1
            else:
                since, reset = 0, mode
    if not groups:
        sys.exit(f"turn_runs.py: {path} holds no mode_probe --all-modes lines")
    profiled = all(
        block.get(m, (0, None))[1] is not None
        for v in groups.values()
        for _, (_, block) in v
        for m, _ in MODES
        if m in block
    )
    cell = "diffused / row 1 / after row 1" if profiled else "diffused"
    print(f"{len(episodes)} episodes; per mode the mean yaw change (rad): {cell}")
    head = " | ".join(f"{name}: {cell}" for _, name in MODES)
    print(f"| last grasp reset | turns since | starts | executed turn (n) | {head} |")
    print("|---" * (4 + len(MODES)) + "|")
    for key in sorted(groups):
        v = groups[key]
        turns = [change for mode, (change, _) in v if mode == "turn"]
        ex = f"{st.mean(turns):+.3f} ({len(turns)})" if turns else "–"
        cells = []
        for mode, _ in MODES:
            got = [block[mode] for _, (_, block) in v if mode in block]
            if not got:
                cells.append("–")
                continue
            total = st.mean(d for d, _ in got)
            if profiled:
                level = st.mean(r for _, r in got)
                cells.append(f"{total:+.3f} / {level:+.3f} / {total - level:+.3f}")
            else:
                cells.append(f"{total:+.3f}")
        print(f"| {key[0]} | {key[1]} | {len(v)} | {ex} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__.strip())
    if sys.argv[1] == "--probe":
        if len(sys.argv) != 3:
            sys.exit("usage: scripts/turn_runs.py --probe PROBE.txt")
        probe(sys.argv[2])
    else:
        main(sys.argv[1:])
