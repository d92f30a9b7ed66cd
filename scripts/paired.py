#!/usr/bin/env python3
"""Paired comparison of `dips` with k = 1 and max-likelihood (either task).

Usage: scripts/paired.py [--all] RESULTS.json [RESULTS.json ...]

`--all` compares `dips` with every method in the files instead (the main table's paired column).

Reads the `results.json` of one or more `dips eval` runs (trials of the same method and seed
in a later file replace earlier ones) and prints, over the seeds every method ran: each method's
valid count, mean ± standard error and median of the outcome (screwdriver: final yaw in rad;
card: distance to the goal in cm; lower is better for both; every trial, valid or not, as
`results.md` counts it), then the per-seed paired difference `dips` − method (same seed,
same start, same world): its mean, standard error, its share of the method's mean, and on
how many seeds `dips` did better. The `paired*.txt` files of docs/results/ are its output.
"""
import json
import math
import statistics as st
import sys

METHODS = ["dips", "dips-k1", "dips-max-likelihood"]


def trials(paths, tool="paired.py"):
    """(method, seed) → trial over the files; a later file's trial replaces an earlier one.
    `tool` names the script in the error for a file that is not a results.json."""
    out = {}
    for path in paths:
        try:
            with open(path) as f:
                for t in json.load(f)["trials"]:
                    out[(t["method"], t["seed"])] = t
        except (OSError, ValueError, KeyError, TypeError) as e:
            sys.exit(f"{tool}: {path} is not a `dips eval` results.json ({e!r})")
    return out


def se(xs):
    return st.stdev(xs) / math.sqrt(len(xs))


def main(args):
    every = "--all" in args
    paths = [a for a in args if a != "--all"]
    if not paths:
        sys.exit("usage: scripts/paired.py [--all] RESULTS.json [RESULTS.json ...]")
    by = trials(paths)
    methods = METHODS
    if every:
        others = []
        for (m, _) in by:
            if m != "dips" and m not in others:
                others.append(m)
        methods = ["dips"] + others
    # Paired: only the seeds every method ran.
    seeds = sorted(s for (m, s) in by if m == methods[0] and all((o, s) in by for o in methods))
    if len(seeds) < 2:
        sys.exit("paired.py: fewer than two seeds that every method ran")
    print("seeds", seeds[0], "..", seeds[-1], len(seeds))
    out = {m: [by[(m, s)]["outcome"] for s in seeds] for m in methods}
    for m in methods:
        valid = sum(by[(m, s)]["valid"] for s in seeds)
        xs = out[m]
        print(f"{m:22s} valid {valid}/{len(xs)} mean {st.mean(xs):.4f} ± SE {se(xs):.4f} "
              f"median {st.median(xs):.4f}")
    for m in methods[1:]:
        diff = [a - b for a, b in zip(out[methods[0]], out[m])]
        mean = st.mean(diff)
        better = sum(d < -1e-9 for d in diff)
        equal = sum(abs(d) <= 1e-9 for d in diff)
        print(f"dips - {m}: {mean:+.4f} (SE {se(diff):.4f}) = {mean / se(diff):+.1f} SE, "
              f"{100 * mean / st.mean(out[m]):+.1f}% of its mean; dips better in {better} "
              f"of {len(diff)} ({equal} equal)")


if __name__ == "__main__":
    main(sys.argv[1:])
