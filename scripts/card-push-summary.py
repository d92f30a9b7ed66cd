#!/usr/bin/env python3
"""How far the card's pushes move it, per run (docs/mujoco.md, "Friction that sticks"):
for every card episode of `dips eval` runs, the card's y change per executed mode (two-finger
`both` pushes, one-finger `index`/`middle` pushes), pushes that moved it back by more than
2 mm, steps where a fingertip pressed the table with more than 1 N, the final distances, the
modes where a regrasping finger came within 2 mm of the card before its last step (early
touch-downs), the steps the regrasp guard changed (`--regrasp-guard`), the planning calls whose
first mode was limited (`--first-mode touching`) and the card y change of the modes they
chose; for every run after
the first, the paired difference of final distances to the first on the seeds both ran.

Usage: scripts/card-push-summary.py OUT.json NAME=RUN_DIR...
"""
import glob
import json
import os
import statistics as st
import sys

from paired import se

# The regrasping fingers of each card mode (task order: index, middle).
REGRASPING = {"index": [1], "middle": [0], "regrasp": [0, 1], "both": []}


def summary(run):
    both, single, back, table_steps, steps, finals, valid = [], [], 0, 0, 0, [], 0
    early, guarded, by_seed, limited = 0, 0, {}, []
    files = sorted(glob.glob(os.path.join(run, "episodes", "*", "seed-*", "result.json")))
    for f in files:
        r = json.load(open(f))
        finals.append(100 * r["final_distance_m"])
        by_seed[r["seed"]] = 100 * r["final_distance_m"]
        valid += bool(r["valid"])
        for p in r.get("plans", []):
            if p.get("first_modes") and p["executed"] < len(r["mode_runs"]):
                m = r["mode_runs"][p["executed"]]
                limited.append(100 * (m["end_state"][-2] - m["start_state"][-2]))
        for m in r["mode_runs"]:
            dy = 100 * (m["end_state"][-2] - m["start_state"][-2])
            if m["mode"] == "both":
                both.append(dy)
            elif m["mode"] in ("index", "middle"):
                single.append(dy)
            if m["mode"] != "regrasp" and dy > 0.2:
                back += 1
            fingers = REGRASPING[m["mode"]]
            early += any(s["tip_sdf"][i] < 0.002 for s in m["steps"][:-1] for i in fingers)
            guarded += sum(1 for s in m["steps"] if s.get("guarded"))
            for s in m["steps"]:
                steps += 1
                for c in s.get("contacts") or []:
                    if c["finger"] != "card" and c["part"] == "table":
                        if sum(x * x for x in c["force"]) ** 0.5 > 1.0:
                            table_steps += 1
                            break
    mean = lambda v: st.mean(v) if v else None
    return {
        "episodes": len(files),
        "valid": valid,
        "final_distance_cm": {"mean": mean(finals), "median": st.median(finals) if finals else None,
                              "within_1cm": sum(d <= 1.0 for d in finals)},
        "both_push_dy_cm": {"n": len(both), "mean": mean(both)},
        "single_push_dy_cm": {"n": len(single), "mean": mean(single)},
        "pushes_moving_back_over_2mm": back,
        "steps_pressing_the_table_over_1N": table_steps,
        "steps": steps,
        "early_touch_downs": early,
        "guarded_steps": guarded,
        "limited_first_modes": {"calls": len(limited), "mean_dy_cm": mean(limited),
                                "moving_back_over_2mm": sum(d > 0.2 for d in limited)},
        "by_seed": by_seed,
    }


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = sys.argv[1]
    runs = {}
    for a in sys.argv[2:]:
        name, d = a.split("=", 1)
        runs[name] = summary(d)
    first = next(iter(runs.values()))
    for s in list(runs.values())[1:]:
        seeds = sorted(set(first["by_seed"]) & set(s["by_seed"]))
        d = [s["by_seed"][k] - first["by_seed"][k] for k in seeds]
        if len(d) > 1:
            s["paired_minus_first_cm"] = {"seeds": len(d), "mean": st.mean(d), "se": se(d)}
    with open(out + ".tmp", "w") as f:
        json.dump(runs, f, indent=1)
        f.write("\n")
    os.replace(out + ".tmp", out)
    for name, s in runs.items():
        print(f"{name:10} final {s['final_distance_cm']['mean']:.2f} cm "
              f"({s['final_distance_cm']['within_1cm']}/{s['episodes']} within 1 cm, {s['valid']} valid); "
              f"both {s['both_push_dy_cm']['mean']:.2f} cm ({s['both_push_dy_cm']['n']}); "
              f"single {s['single_push_dy_cm']['mean']:.2f} cm ({s['single_push_dy_cm']['n']}); "
              f"back {s['pushes_moving_back_over_2mm']}; table {s['steps_pressing_the_table_over_1N']}/{s['steps']}; "
              f"early touch-downs {s['early_touch_downs']}; guarded steps {s['guarded_steps']}; "
              f"limited first modes {s['limited_first_modes']['calls']}"
              + (f"; paired − first {s['paired_minus_first_cm']['mean']:+.2f} ± "
                 f"{s['paired_minus_first_cm']['se']:.2f} cm" if "paired_minus_first_cm" in s else ""))


main()
