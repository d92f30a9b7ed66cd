#!/usr/bin/env python3
"""Paired comparison of two `dips eval` runs of the same seeds (two settings, two binaries).

Usage: scripts/compare.py A/results.json B/results.json

For every method and seed in both files it prints one line: the outcome in A and in B
(screwdriver: final yaw in rad; card: distance to the goal in cm; `!` marks an invalid trial)
and each run's executed mode sequence (`t` turn, `m` thumb-middle regrasp, `r` index regrasp;
card modes by their initials); then per method the mean paired difference A − B and its
standard error. The `paired-*-vs-*.txt` files of the runs in docs/decisions.md are its output.
"""
import statistics as st
import sys

from paired import se, trials

SHORT = {"turn": "t", "thumb-middle-regrasp": "m", "index-regrasp": "r"}


def sequence(trial):
    return "".join(SHORT.get(m) or "".join(w[0] for w in m.split("-")) for m in trial["modes"])


def cell(trial):
    return f"{trial['outcome']:+.3f}{'' if trial['valid'] else '!'} {sequence(trial)}"


def main(a_path, b_path):
    a, b = trials([a_path], "compare.py"), trials([b_path], "compare.py")
    shared = sorted(k for k in a if k in b)
    if not shared:
        sys.exit("compare.py: the two files share no (method, seed) trial")
    for method in sorted({m for m, _ in shared}):
        diffs = []
        for key in (k for k in shared if k[0] == method):
            diffs.append(a[key]["outcome"] - b[key]["outcome"])
            print(f"{method} {key[1]} {cell(a[key])}   {cell(b[key])}")
        if len(diffs) > 1:
            print(f"{method} mean diff {st.mean(diffs):.3f} SE {se(diffs):.3f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip())
    main(sys.argv[1], sys.argv[2])
