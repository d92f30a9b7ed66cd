#!/usr/bin/env python3
"""Why DIPS overshoots the card under the paper's goals (issue 38 item 2), from the tuning runs
of scripts/card-paper-tuning.sh (seeds 500-509) and the card-paper demos.

Usage: scripts/card-paper-diagnosis.py [DATA_DIR] > docs/results/card/paper-tuning-500-diagnosis.json
       scripts/card-paper-diagnosis.py --registered > docs/results/card/paper-10300-diagnosis.json
  DATA_DIR: the demos (default target/models-work/data/card-paper, `dips datagen --task card
  --card-goals paper --demos 128`); left out when absent.
  --registered: the same figures for the registered runs (docs/results/card/paper-10300-seed<S>,
  paper-10310-seed<S>, paper-code-10300-seed0, capped-10300-seed0: those that exist), without
  the demos.
  paper-tuning-500-nogain-host is `--stop-rule no-gain --planner-size host` on the same seeds
  (dips and dips-no-replan; docs/online.md, "Stopping and the planner's size").
       scripts/card-paper-diagnosis.py --start > docs/results/card/paper-start-diagnosis.json
  --start: the same figures for the card-paper models trained in the segment-start object frame
  (onnx/models/card-paper-start*): the tuning runs paper-start-tuning-500 (the paper's setting)
  and paper-start-tuning-500-nogain, and the registered paper-start-10500-seed<S> and
  paper-start-nogain-10500-seed<S> (those that exist), without the demos; and the no-gain
  variant's `dips` minus every method of the paper's-setting run, paired on the same seeds.

The paired differences (DIPS minus each method, from results.json) are computed from the
committed files; the per-episode figures need the full runs (commit 717570b, or
target/kept-episodes/ where the trimmed episodes were moved).

Per run and method: the outcome (distance to the goal, cm; valid trials), the executed pushes'
length (cm of y per index/middle/both mode), where the card was after its third push, how many
pushes the trial made, and for every planning call of a searching method the model's expected
end of the plan's first mode against the executed one. From the demos: the push length by
start position (1 cm bins), which is what any plan of whole pushes is made of.
"""
import glob
import json
import os
import statistics as st
import struct
import sys

RUNS = ["docs/results/card/paper-tuning-500-code", "docs/results/card/paper-tuning-500-paper",
        "docs/results/card/paper-tuning-500-nogain-host"]
PUSHES = ("index", "middle", "both")


def mean(v):
    return round(st.mean(v), 3) if v else None


def card_y(state):
    return state[-2] * 100.0


def episode_figures(results):
    pushes, after_third, counts, first_mode_error, believed = [], [], [], [], []
    first_status, first_end = {}, []
    stopped, first_expanded, first_seconds = 0, [], []
    for r in results:
        plans = r.get("plans", [])
        if plans:
            # The first call's outcome: Found (a goal node), or the fallback to the node nearest
            # the goal (Approximate: budget, time or the open list's capacity).
            status = plans[0]["status"]
            first_status[status] = first_status.get(status, 0) + 1
            if plans[0]["expected_terminal_state"][9] is not None:
                first_end.append(plans[0]["expected_terminal_state"][9] * 100.0)
            first_expanded.append(plans[0]["nodes_expanded"])
            first_seconds.append(plans[0]["seconds"])
            # `--stop-rule no-gain`: the episode stopped instead of executing a plan.
            stopped += any(p.get("stopped_no_gain", False) for p in plans)
        ys = []
        n = 0
        for run in r["mode_runs"]:
            if run["mode"] in PUSHES:
                pushes.append(card_y(run["end_state"]) - card_y(run["start_state"]))
                n += 1
                if n == 3:
                    after_third.append(card_y(run["end_state"]))
            ys.append(card_y(run["end_state"]))
        counts.append(n)
        # The first call's plan from the start (y = 0): its expected end over its pushes is the
        # push length the models believe in.
        plans = r.get("plans", [])
        if plans and plans[0]["expected_terminal_state"][9] is not None:
            n_planned = sum(m in PUSHES for m in plans[0]["modes"])
            if n_planned:
                believed.append(plans[0]["expected_terminal_state"][9] * 100.0 / n_planned)
        # The plan's expected end (its whole plan) is all a call reports; its first mode's
        # expected end is not recorded, so compare the one-mode plans (the last calls).
        for call, plan in enumerate(r.get("plans", [])):
            exp = plan["expected_terminal_state"]
            if len(plan["modes"]) == 1 and call < len(r["mode_runs"]) and exp[9] is not None:
                executed = card_y(r["mode_runs"][call]["end_state"])
                first_mode_error.append(executed - exp[9] * 100.0)
    return {
        "push_length_cm": {"mean": mean(pushes), "n": len(pushes),
                           "min": round(min(pushes), 3) if pushes else None,
                           "max": round(max(pushes), 3) if pushes else None},
        "y_after_third_push_cm": {"mean": mean(after_third), "n": len(after_third)},
        "pushes_per_trial": {str(k): counts.count(k) for k in sorted(set(counts))},
        "one_mode_plans_executed_minus_expected_cm": {"mean": mean(first_mode_error),
                                                      "n": len(first_mode_error)},
        "first_plan_expected_push_length_cm": {"mean": mean(believed), "n": len(believed)},
        "first_call_status": first_status,
        "first_plan_expected_end_cm": {"mean": mean(first_end), "n": len(first_end)},
        "first_call_nodes_expanded": {"mean": mean(first_expanded), "n": len(first_expanded)},
        "first_call_seconds": {"mean": mean(first_seconds), "n": len(first_seconds),
                               "min": round(min(first_seconds), 1) if first_seconds else None,
                               "max": round(max(first_seconds), 1) if first_seconds else None},
        "trials_stopped_no_gain": stopped,
    }


def paired(run):
    """DIPS minus each other method, per seed, from the run's results.json: mean and SE (cm)."""
    path = f"{run}/results.json"
    if not os.path.isfile(path):
        return {}
    by = {}
    for t in json.load(open(path))["trials"]:
        by.setdefault(t["method"], {})[t["seed"]] = t["outcome"]
    dips = by.get("dips", {})
    out = {}
    for method, seeds in by.items():
        d = [dips[s] - seeds[s] for s in seeds if s in dips and method != "dips"]
        if len(d) > 1:
            out[method] = {"mean": round(st.mean(d), 3),
                           "se": round(st.stdev(d) / len(d) ** 0.5, 3), "n": len(d)}
    return out


def runs(names):
    out = {}
    for run in names:
        if not os.path.isdir(run):
            continue
        methods = {"paired_dips_minus": paired(run)}
        kept = f"target/kept-episodes/card/{os.path.basename(run)}"
        for mdir in sorted(glob.glob(f"{run}/episodes/*")):
            files = glob.glob(f"{mdir}/*/result.json")
            files += glob.glob(f"{kept}/episodes/{os.path.basename(mdir)}/*/result.json")
            res = [json.load(open(f)) for f in sorted(files)]
            if not res:
                continue
            d = [r["final_distance_m"] * 100.0 for r in res]
            dv = [r["final_distance_m"] * 100.0 for r in res if r["valid"]]
            methods[os.path.basename(mdir)] = {
                "trials": len(res),
                "valid": len(dv),
                "distance_cm_mean_all": mean(d),
                "distance_cm_mean_valid": mean(dv),
                "distance_cm_median": round(st.median(d), 3),
                **episode_figures(res),
            }
        out[os.path.basename(run)] = methods
    return out


def demos(data):
    bins = {}
    for f in sorted(glob.glob(f"{data}/demos/*.safetensors")):
        with open(f, "rb") as fh:
            n = struct.unpack("<Q", fh.read(8))[0]
            meta = json.loads(fh.read(n))["__metadata__"]
        for m in json.loads(meta["outcome"])["modes"]:
            if m["mode"] in PUSHES:
                y0 = card_y(m["start_state"])
                bins.setdefault(int(-y0), []).append(card_y(m["end_state"]) - y0)
    return {f"{b}-{b + 1} cm": {"n": len(v), "mean": mean(v)} for b, v in sorted(bins.items())}


REGISTERED = [f"docs/results/card/paper-{first}-seed{seed}"
              for first in (10300, 10310) for seed in (0, 1, 2)] + [
              "docs/results/card/paper-code-10300-seed0", "docs/results/card/capped-10300-seed0"]


START = ["docs/results/card/paper-start-tuning-500",
         "docs/results/card/paper-start-tuning-500-nogain"] + [
         f"docs/results/card/paper-start{variant}-10500-seed{seed}"
         for variant in ("", "-nogain") for seed in (0, 1, 2)]


def outcomes(run):
    """method -> seed -> outcome (cm) of a run's results.json; empty when it does not exist."""
    path = f"{run}/results.json"
    by = {}
    if os.path.isfile(path):
        for t in json.load(open(path))["trials"]:
            by.setdefault(t["method"], {})[t["seed"]] = t["outcome"]
    return by


def nogain_against_paper():
    """The no-gain variant's `dips` minus every method of the paper's-setting run on the same
    seeds and models (paired per seed), per model seed and pooled over the models."""
    out, pooled = {}, {}
    for seed in (0, 1, 2):
        nogain = outcomes(f"docs/results/card/paper-start-nogain-10500-seed{seed}").get("dips", {})
        paper = outcomes(f"docs/results/card/paper-start-10500-seed{seed}")
        if not nogain or not paper:
            continue
        per = {}
        for method, seeds in paper.items():
            d = [nogain[s] - seeds[s] for s in seeds if s in nogain]
            if len(d) > 1:
                pooled.setdefault(method, []).extend(d)
                per[method] = {"mean": round(st.mean(d), 3),
                               "se": round(st.stdev(d) / len(d) ** 0.5, 3), "n": len(d)}
        out[f"model_seed{seed}"] = per
    out["pooled"] = {m: {"mean": round(st.mean(d), 3),
                         "se": round(st.stdev(d) / len(d) ** 0.5, 3), "n": len(d)}
                     for m, d in pooled.items() if len(d) > 1}
    return out


def main():
    if sys.argv[1:] == ["--start"]:
        print(json.dumps({"command": "scripts/card-paper-diagnosis.py --start",
                          "runs": runs(START),
                          "nogain_dips_minus_paper_setting": nogain_against_paper()},
                         indent=1))
        return
    if sys.argv[1:] == ["--registered"]:
        print(json.dumps({"command": "scripts/card-paper-diagnosis.py --registered",
                          "runs": runs(REGISTERED)}, indent=1))
        return
    data = sys.argv[1] if len(sys.argv) > 1 else "target/models-work/data/card-paper"
    report = {
        "command": "scripts/card-paper-diagnosis.py " + data,
        "runs": runs(RUNS),
    }
    if os.path.isdir(data):
        report["demo_push_length_cm_by_start"] = demos(data)
    json.dump(report, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
