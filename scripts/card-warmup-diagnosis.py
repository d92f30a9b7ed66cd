#!/usr/bin/env python3
"""Card pushes whose first CSVTO solve did not converge (docs/mujoco.md, "The card's
regrasping finger"): for every card episode of the given `dips eval` runs, each non-`regrasp`
mode's card y change, split by the largest equality violation of the mode's first solve (the
warm-up, after its retries) above or below 1; how many of each moved the card back by more
than 2 mm; and the same pushes binned by how far their contact fingers were from the card
when they started (the largest tip distance of the previous mode's last step, the
`--first-mode touching` tolerance's evidence, docs/online.md "The first mode"). Reads
`episodes/*/seed-*/result.json` under each RUN_DIR (a finished run keeps
only its medians in git: point at target/kept-episodes/card/<run> as well, or rerun).

Usage: scripts/card-warmup-diagnosis.py OUT.json NAME=RUN_DIR[,RUN_DIR...]...
"""
import glob
import json
import os
import statistics as st
import sys

LIMIT = 1.0
CONTACT = {"index": [0], "middle": [1], "both": [0, 1], "regrasp": []}
BINS_MM = [(None, 1.0), (1.0, 4.0), (4.0, 6.0), (6.0, None)]


def summary(dirs):
    out = {"episodes": 0, "unconverged": [], "converged": []}
    by_start = []
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
            runs = r["mode_runs"]
            for prev, m in zip(runs, runs[1:]):
                fingers = CONTACT[m["mode"]]
                if not fingers or not m["steps"] or not prev["steps"]:
                    continue
                tip = prev["steps"][-1]["tip_sdf"]
                by_start.append((1e3 * max(tip[i] for i in fingers),
                                 m["steps"][0]["max_eq_violation"] > LIMIT,
                                 100 * (m["end_state"][-2] - m["start_state"][-2])))
    for key in ("unconverged", "converged"):
        dys = out[key]
        out[key] = {"modes": len(dys), "mean_dy_cm": st.mean(dys) if dys else None,
                    "moving_back_over_2mm": sum(d > 0.2 for d in dys)}
    out["by_start_distance_mm"] = []
    for lo, hi in BINS_MM:
        rows = [b for b in by_start if (lo is None or b[0] > lo) and (hi is None or b[0] <= hi)]
        out["by_start_distance_mm"].append({
            "above": lo, "up_to": hi, "pushes": len(rows),
            "unconverged": sum(b[1] for b in rows),
            "mean_dy_cm": st.mean(b[2] for b in rows) if rows else None})
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
        for b in s["by_start_distance_mm"]:
            print(f"    start distance ({b['above']}, {b['up_to']}] mm: {b['pushes']} pushes, "
                  f"{b['unconverged']} unconverged, mean dy {fmt(b['mean_dy_cm'])} cm")


main()
