#!/usr/bin/env python3
"""The transfer experiment's table (issue 37 item 6, seeds 10100-10109, registered in
docs/results/PROTOCOL.md): reads the `results.json` of the six runs of
scripts/transfer-10100.sh (docs/results/{screwdriver,card}/transfer-10100-{world,mujoco,
mujoco-noisy}/), writes docs/results/transfer-10100.json and prints the markdown tables that
docs/mujoco.md and docs/results/README.md quote.

Outcomes as `dips eval` scores them: screwdriver final yaw (rad, lower is better: turned
further), card distance to the goal (cm, lower is better), both on the true object pose.
Per arm and method: valid and success counts, mean ± SE over all trials, mean over valid
executions (the paper reports valid executions), median. Then, over seeds where both ran:
paired differences dips − method in each arm; the cost of tracker noise per method (noisy −
clean MuJoCo); and the paper's transfer figures: DIPS's lead over dips-sampled (screwdriver:
how much further it turns, on valid executions, as the paper's +41 %) and DIPS's MuJoCo turn
as a share of its turn in our world on the same seeds (the paper kept 74 %).

The same table for a later transfer run with other settings and seeds (the paper's hardware
CSVTO settings, screwdriver only: docs/results/screwdriver/hardware-10600-<arm>/):
`--run hardware-10600 --seeds 10600-10609`; the tasks without such a run are skipped.

A run whose arms are named otherwise (the pose estimates of 10800-10809:
docs/results/screwdriver/pose-10800-{world,mujoco-noisy-contacts,mujoco-noisy-tracker}/) gives
them with `--arms world,mujoco-noisy-contacts,mujoco-noisy-tracker` (`world` is our world's;
every other arm's turn is put beside it), and `--pair A:B` adds the paired differences B − A
per method (positive: B worse).

Usage: scripts/transfer-table.py [RESULTS_DIR] [OUT_JSON] [--run NAME] [--seeds FIRST-LAST]
       [--arms ARM,...] [--pair A:B]
"""
import json
import math
import statistics as st
import sys
from pathlib import Path

from paired import se, trials as read_trials

args = sys.argv[1:]
run_name, seeds = "transfer-10100", "10100-10109"
ARMS = ["world", "mujoco", "mujoco-noisy"]
PAIR = ("mujoco", "mujoco-noisy")
for flag in ("--run", "--seeds", "--arms", "--pair"):
    if flag in args:
        i = args.index(flag)
        value = args[i + 1]
        del args[i : i + 2]
        if flag == "--run":
            run_name = value
        elif flag == "--seeds":
            seeds = value
        elif flag == "--arms":
            ARMS = value.split(",")
        else:
            PAIR = tuple(value.split(":"))
            if len(PAIR) != 2:
                sys.exit(f"error: --pair takes A:B (two arm names), not {value}")
root = Path(args[0] if len(args) > 0 else "docs/results")
dest = Path(args[1] if len(args) > 1 else root / f"{run_name}.json")
TASKS = ["screwdriver", "card"]
METHODS = ["dips", "dips-sampled", "csvto-sampled", "dips-k1", "dips-max-likelihood"]
PAPER = {
    "screwdriver": "hardware (paper §V-D, 4 modes, 10 trials): DIPS 10/10 valid, "
    "dips-sampled 8/10; DIPS turns 41 % further; 74 % of its simulated turn",
    "card": "not run on hardware in the paper",
}


def load(task, arm):
    path = root / task / f"{run_name}-{arm}" / "results.json"
    if not path.exists():
        return None, {}
    status = json.loads(path.read_text()).get("registration", {}).get("status", "unregistered")
    return status, read_trials([path], "transfer-table.py")


def fmt(x, nd=3):
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


summary = {"run": run_name, "seeds": seeds, "paper": PAPER, "tasks": {}}
for task in TASKS:
    unit = "rad" if task == "screwdriver" else "cm"
    nd = 3 if task == "screwdriver" else 2
    arms = {}
    for arm in ARMS:
        status, trials = load(task, arm)
        if status is None:
            continue
        rows = {}
        for m in METHODS:
            ts = sorted((t for (mm, _), t in trials.items() if mm == m), key=lambda t: t["seed"])
            if not ts:
                continue
            xs = [t["outcome"] for t in ts]
            valid = [t["outcome"] for t in ts if t["valid"]]
            rows[m] = {
                "trials": len(ts),
                "valid": sum(t["valid"] for t in ts),
                "success": sum(bool(t["success"]) for t in ts),
                "mean": st.mean(xs),
                "se": se(xs),
                "mean_valid": st.mean(valid) if valid else None,
                "median": st.median(xs),
                "by_seed": {str(t["seed"]): t["outcome"] for t in ts},
                "valid_by_seed": {str(t["seed"]): t["valid"] for t in ts},
            }
        paired = {}
        for m in METHODS[1:]:
            seeds = sorted(set(rows.get("dips", {}).get("by_seed", {}))
                           & set(rows.get(m, {}).get("by_seed", {})))
            if len(seeds) > 1:
                d = [rows["dips"]["by_seed"][s] - rows[m]["by_seed"][s] for s in seeds]
                paired[m] = {"seeds": len(seeds), "mean": st.mean(d), "se": se(d),
                             "dips_better": sum(x < 0 for x in d)}
        arms[arm] = {"status": status, "methods": rows, "dips_minus": paired}
    if not arms:
        continue
    # Tracker noise's cost per method (noisy − clean, same seeds; positive: worse), or the
    # difference between the two arms --pair names.
    noise = {}
    if PAIR[0] in arms and PAIR[1] in arms:
        for m in METHODS:
            a = arms[PAIR[0]]["methods"].get(m, {}).get("by_seed", {})
            b = arms[PAIR[1]]["methods"].get(m, {}).get("by_seed", {})
            seeds = sorted(set(a) & set(b))
            if len(seeds) > 1:
                d = [b[s] - a[s] for s in seeds]
                noise[m] = {"seeds": len(seeds), "mean": st.mean(d), "se": se(d)}
    # The paper's figures: lead over dips-sampled on valid executions, and the transfer ratio.
    paper_figures = {}
    for arm, a in arms.items():
        d, s = a["methods"].get("dips"), a["methods"].get("dips-sampled")
        if d and s and d["mean_valid"] is not None and s["mean_valid"] is not None:
            if task == "screwdriver":
                lead = d["mean_valid"] / s["mean_valid"] - 1.0  # turns (negative yaw) further
            else:
                lead = 1.0 - d["mean_valid"] / s["mean_valid"]  # ends closer to the goal
            paper_figures[f"dips_lead_over_dips_sampled_{arm}"] = lead
    if task == "screwdriver" and "world" in arms:
        for arm in [a for a in arms if a != "world"]:
            for m in METHODS:
                w = arms["world"]["methods"].get(m, {}).get("by_seed", {})
                j = arms[arm]["methods"].get(m, {}).get("by_seed", {})
                seeds = sorted(set(w) & set(j))
                if seeds:
                    paper_figures[f"{m}_{arm}_share_of_world_turn"] = (
                        sum(j[s] for s in seeds) / sum(w[s] for s in seeds))
                # On valid executions of both hands (the paper's 74 % is over valid ones).
                vw = arms["world"]["methods"].get(m, {}).get("valid_by_seed", {})
                vj = arms[arm]["methods"].get(m, {}).get("valid_by_seed", {})
                both = [s for s in seeds if vw.get(s) and vj.get(s)]
                if both:
                    paper_figures[f"{m}_{arm}_share_of_world_turn_valid"] = (
                        sum(j[s] for s in both) / sum(w[s] for s in both))
    summary["tasks"][task] = {"unit": unit, "arms": arms, "pair": list(PAIR), "noise_cost": noise,
                              "paper_figures": paper_figures}

    print(f"\n### {task} ({unit}; lower is better)\n")
    print("mean ± SE over all trials (valid, success); median\n")
    print("| method | " + " | ".join(arms) + " |")
    print("|---|" + "---|" * len(arms))
    for m in METHODS:
        cells = []
        for arm, a in arms.items():
            r = a["methods"].get(m)
            cells.append("—" if r is None else
                         f"{fmt(r['mean'], nd)} ± {fmt(r['se'], nd)} ({r['valid']}/{r['trials']}, "
                         f"{r['success']}/{r['trials']}); {fmt(r['median'], nd)}")
        print(f"| {m} | " + " | ".join(cells) + " |")
    print("\npaired dips − method (mean ± SE, seeds dips did better):")
    for arm, a in arms.items():
        print(f"- {arm} ({a['status']}): " + "; ".join(
            f"{m} {fmt(p['mean'], nd)} ± {fmt(p['se'], nd)} ({p['dips_better']}/{p['seeds']})"
            for m, p in a["dips_minus"].items()))
    if noise:
        print(f"paired {PAIR[1]} − {PAIR[0]}: " + "; ".join(
            f"{m} {fmt(p['mean'], nd)} ± {fmt(p['se'], nd)}" for m, p in noise.items()))
    for k, v in paper_figures.items():
        print(f"- {k}: {v * 100:.1f} %")
    print(f"- the paper: {PAPER[task]}")

tmp = dest.with_suffix(".json.partial")
tmp.write_text(json.dumps(summary, indent=1) + "\n")
tmp.replace(dest)
print(f"\nwrote {dest}")
