#!/usr/bin/env python3
"""Issue 34 item 3 on tuning seeds: do the particles buy robustness on a hand the planner never
modelled? Reads the episodes of scripts/particles-mujoco.sh (dips, dips-k1,
dips-max-likelihood on the MuJoCo hand, without and with tracker noise) and writes one JSON
with, per condition and method, the final yaws, valid counts, means and the paired
differences to dips with their standard errors.

Usage: scripts/particles-mujoco.py OUT.json CONDITION=DIR [CONDITION=DIR ...]
"""
import json
import math
import pathlib
import sys

METHODS = ["dips", "dips-k1", "dips-max-likelihood"]


def load(d):
    runs = {}
    for m in METHODS:
        for f in sorted((pathlib.Path(d) / "episodes" / m).glob("seed-*/result.json")):
            r = json.loads(f.read_text())
            runs.setdefault(m, {})[r["seed"]] = r
    return runs


def mean_se(xs):
    n = len(xs)
    if n == 0:
        return None, None
    m = sum(xs) / n
    if n < 2:
        return m, None
    var = sum((x - m) ** 2 for x in xs) / (n - 1)
    return m, math.sqrt(var / n)


def main():
    out = pathlib.Path(sys.argv[1])
    table = {}
    for arg in sys.argv[2:]:
        cond, d = arg.split("=", 1)
        runs = load(d)
        rows = {}
        for m in METHODS:
            eps = runs.get(m, {})
            yaws = {s: r["final_yaw"] for s, r in eps.items()}
            mean, se = mean_se(list(yaws.values()))
            row = {
                "episodes": len(eps),
                "valid": sum(r["valid"] for r in eps.values()),
                "success": sum(r["success"] for r in eps.values()),
                "final_yaw": {str(s): y for s, y in sorted(yaws.items())},
                "mean_final_yaw": mean,
                "se": se,
                "modes": {str(s): r["modes"] for s, r in sorted(eps.items())},
                "planning_s_mean": mean_se(
                    [t for r in eps.values() for t in r["planning_s"]]
                )[0],
            }
            if m != "dips":
                common = sorted(set(yaws) & set(runs.get("dips", {})))
                diffs = [runs["dips"][s]["final_yaw"] - yaws[s] for s in common]
                d_mean, d_se = mean_se(diffs)
                row["dips_minus_this"] = {"seeds": len(common), "mean": d_mean, "se": d_se}
            rows[m] = row
        table[cond] = {"dir": d, "methods": rows}
    out.write_text(json.dumps(table, indent=1) + "\n")
    for cond, t in table.items():
        for m, r in t["methods"].items():
            dm = r.get("dips_minus_this")
            print(
                f"{cond:6} {m:20} valid {r['valid']}/{r['episodes']} "
                f"mean {r['mean_final_yaw']:.3f}"
                + (f"  dips−this {dm['mean']:+.3f} ± {dm['se'] or 0:.3f}" if dm else "")
            )


if __name__ == "__main__":
    main()
