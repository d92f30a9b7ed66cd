#!/usr/bin/env python3
"""Card pushes whose first CSVTO solve did not converge (docs/mujoco.md, "The card's
regrasping finger"): for every card episode of the given `dips eval` runs, each non-`regrasp`
mode's card y change, split by the largest equality violation of the mode's first solve (the
warm-up, after its retries) above or below 1; how many of each moved the card back by more
than 2 mm. Reads `episodes/*/seed-*/result.json` under each RUN_DIR (a finished run keeps
only its medians in git: point at target/kept-episodes/card/<run> as well, or rerun).

Usage: scripts/card-warmup-diagnosis.py OUT.json NAME=RUN_DIR[,RUN_DIR...]...
"""
import glob
import json
import os
import statistics as st
import sys

LIMIT = 1.0


def summary(dirs):
    out = {"episodes": 0, "unconverged": [], "converged": []}
    for d in dirs:
        for f in sorted(glob.glob(os.path.join(d, "episodes", "*", "seed-*", "result.json"))):
            r = json.load(open(f))
            out["episodes"] += 1
            for m in r["mode_runs"]:
                if m["mode"] == "regrasp" or not m["steps"]:
                    continue
                dy = 100 * (m["end_state"][-2] - m["start_state"][-2])
                key = "unconverged" if m["steps"][0]["max_eq_violation"] > LIMIT else "converged"
                out[key].append(dy)
    for key in ("unconverged", "converged"):
        dys = out[key]
        out[key] = {"modes": len(dys), "mean_dy_cm": st.mean(dys) if dys else None,
                    "moving_back_over_2mm": sum(d > 0.2 for d in dys)}
    return out


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    runs = {}
    for a in sys.argv[2:]:
        name, dirs = a.split("=", 1)
        runs[name] = summary(dirs.split(","))
    runs["violation_limit"] = LIMIT
    with open(sys.argv[1] + ".tmp", "w") as f:
        json.dump(runs, f, indent=1)
        f.write("\n")
    os.replace(sys.argv[1] + ".tmp", sys.argv[1])
    for name, s in runs.items():
        if name == "violation_limit":
            continue
        u, c = s["unconverged"], s["converged"]
        fmt = lambda v: "—" if v is None else f"{v:+.2f}"
        print(f"{name:22} {s['episodes']} episodes; first solve > {LIMIT}: {u['modes']} modes, "
              f"mean dy {fmt(u['mean_dy_cm'])} cm, {u['moving_back_over_2mm']} back; "
              f"others: {c['modes']}, {fmt(c['mean_dy_cm'])} cm, {c['moving_back_over_2mm']} back")


main()
