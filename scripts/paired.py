#!/usr/bin/env python3
"""Paired comparison of `dips` with k = 1 and max-likelihood (either task).

Usage: scripts/paired.py RESULTS.json [RESULTS.json ...]

Reads the `results.json` of one or more `dips eval` runs (trials of the same method and seed
in a later file replace earlier ones) and prints, over the seeds every method ran: each method's
valid count, mean ± standard error and median of the outcome (screwdriver: final yaw in rad;
card: distance to the goal in cm; lower is better for both; every trial, valid or not, as
`results.md` counts it), then the per-seed paired difference `dips` − method (same seed,
same start, same world): its mean, standard error, its share of the method's mean, and on
how many seeds `dips` did better. The tables of docs/results/README.md ("Twenty more
seeds", "Thirty more seeds") are its output.
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


def main(paths):
    if not paths:
        sys.exit("usage: scripts/paired.py RESULTS.json [RESULTS.json ...]")
    by = trials(paths)
    # Paired: only the seeds every method ran.
    seeds = sorted(s for (m, s) in by if m == METHODS[0] and all((o, s) in by for o in METHODS))
    if len(seeds) < 2:
        sys.exit("paired.py: fewer than two seeds that every method ran")
    print("seeds", seeds[0], "..", seeds[-1], len(seeds))
    out = {m: [by[(m, s)]["outcome"] for s in seeds] for m in METHODS}
    for m in METHODS:
        valid = sum(by[(m, s)]["valid"] for s in seeds)
        xs = out[m]
        print(f"{m:22s} valid {valid}/{len(xs)} mean {st.mean(xs):.4f} ± SE {se(xs):.4f} "
              f"median {st.median(xs):.4f}")
    for m in METHODS[1:]:
        diff = [a - b for a, b in zip(out[METHODS[0]], out[m])]
        mean = st.mean(diff)
        better = sum(d < -1e-9 for d in diff)
        equal = sum(abs(d) <= 1e-9 for d in diff)
        print(f"dips - {m}: {mean:+.4f} (SE {se(diff):.4f}) = {mean / se(diff):+.1f} SE, "
              f"{100 * mean / st.mean(out[m]):+.1f}% of its mean; dips better in {better} "
              f"of {len(diff)} ({equal} equal)")


if __name__ == "__main__":
    main(sys.argv[1:])
