#!/usr/bin/env python3
"""The training-seed experiments' tables (issue 38 items 3-4; registered in
docs/results/PROTOCOL.md). For each trained model (seed 0 = the shipped one, seeds 1 and 2),
the `results.json` of the experiment's runs that exist:

  screwdriver  docs/results/screwdriver/models-10200-seed<S>/ (all seven methods, 10200-10209)
               and models-10210-seed<S>/ (dips, dips-k1, dips-max-likelihood, 10210-10229)
               -> docs/results/screwdriver/models-10200.json
  card-paper   docs/results/card/paper-10300-seed<S>/ (all seven methods, 10300-10309) and
               paper-10310-seed<S>/ (dips, dips-k1, dips-max-likelihood, 10310-10329), the
               card under the paper's setting -> docs/results/card/paper-10300.json
  card-paper-start   docs/results/card/paper-start-10500-seed<S>/ (all seven methods,
               10500-10509) and paper-start-10510-seed0 (dips, dips-k1, dips-max-likelihood,
               10510-10529, model seed 0 only), the same with the card-paper models trained in
               the segment-start object frame -> docs/results/card/paper-start-10500.json
  card-paper-start-nogain   docs/results/card/paper-start-nogain-10500-seed<S>/ (dips,
               dips-k1, dips-max-likelihood, 10500-10509, our `--stop-rule no-gain`)
               -> docs/results/card/paper-start-nogain-10500.json

Prints each method's mean ± SE (valid, over all trials and over valid ones), success count and
planning time (the paper's way: the mean over every call of every episode; ours: median and
p90) per model, and DIPS's paired margins over every method per model and pooled over the
models (each model's seeds paired within the model). Lower is better for both tasks (final yaw
in rad; distance to the goal in cm).

Usage: scripts/models-table.py [EXPERIMENT [RESULTS_DIR]]   (default: screwdriver, and the
experiment's task folder under docs/results)
"""
import json
import statistics as st
import sys
from pathlib import Path

from paired import se, trials as read_trials

EXPERIMENTS = {
    "screwdriver": ("screwdriver", "models", (10200, 10210), "models-10200.json"),
    "card-paper": ("card", "paper", (10300, 10310), "paper-10300.json"),
    "card-paper-start": ("card", "paper-start", (10500, 10510), "paper-start-10500.json"),
    "card-paper-start-nogain": ("card", "paper-start-nogain", (10500,),
                                "paper-start-nogain-10500.json"),
}
experiment = sys.argv[1] if len(sys.argv) > 1 else "screwdriver"
if experiment not in EXPERIMENTS:
    sys.exit(f"models-table.py: unknown experiment {experiment!r}; expected one of "
             f"{', '.join(EXPERIMENTS)}")
task, prefix, firsts, table = EXPERIMENTS[experiment]
root = Path(sys.argv[2] if len(sys.argv) > 2 else f"docs/results/{task}")
METHODS = ["dips", "dips-sampled", "csvto-sampled", "dips-no-replan", "dips-k1",
           "dips-max-likelihood", "diffusion-policy"]


def trials(seed):
    """(method, seed) → trial over the model's runs that exist, and their statuses."""
    paths = [p for first in firsts
             if (p := root / f"{prefix}-{first}-seed{seed}" / "results.json").exists()]
    statuses = {p.parent.name.removeprefix(prefix + "-").split("-")[0]:
                json.loads(p.read_text()).get("registration", {}).get("status", "unregistered")
                for p in paths}
    return read_trials(paths, "models-table.py"), statuses


def quantile(xs, q):
    """The q-quantile of xs, linear between order statistics (numpy's default)."""
    xs = sorted(xs)
    at = q * (len(xs) - 1)
    lo = int(at)
    hi = min(lo + 1, len(xs) - 1)
    return xs[lo] + (xs[hi] - xs[lo]) * (at - lo)


summary = {"models": {}, "pooled": {}}
pooled = {m: [] for m in METHODS[1:]}
for seed in (0, 1, 2):
    ts, statuses = trials(seed)
    if not ts:
        continue
    rows, paired = {}, {}
    for m in METHODS:
        xs = [t for (mm, _), t in ts.items() if mm == m]
        if not xs:
            continue
        out = [t["outcome"] for t in xs]
        valid = [t["outcome"] for t in xs if t["valid"]]
        calls = [c for t in xs for c in t.get("planning_s", [])]
        rows[m] = {"trials": len(xs), "valid": len(valid), "mean": st.mean(out), "se": se(out),
                   "mean_valid": st.mean(valid) if valid else None, "median": st.median(out),
                   "success": sum(bool(t.get("success")) for t in xs),
                   "planning_s": None if not calls else {
                       "calls": len(calls), "mean": st.mean(calls),
                       "median": st.median(calls), "p90": quantile(calls, 0.9)}}
    for m in METHODS[1:]:
        seeds = sorted(s for (mm, s) in ts if mm == m and ("dips", s) in ts)
        if len(seeds) < 2:
            continue
        d = [ts[("dips", s)]["outcome"] - ts[(m, s)]["outcome"] for s in seeds]
        pooled[m] += d
        paired[m] = {"seeds": len(d), "mean": st.mean(d), "se": se(d),
                     "dips_better": sum(x < 0 for x in d), "equal": sum(x == 0 for x in d)}
    summary["models"][str(seed)] = {"runs": statuses, "methods": rows, "dips_minus": paired}
    print(f"\nmodel seed {seed} ({statuses}): mean ± SE (valid); dips − method (paired)")
    for m, r in rows.items():
        p = paired.get(m)
        tail = "" if p is None else (f";  dips − it {p['mean']:+.3f} ± {p['se']:.3f} over "
                                     f"{p['seeds']} seeds ({p['dips_better']} better, "
                                     f"{p['equal']} equal)")
        plan = r["planning_s"]
        plan = "" if plan is None else (f"; planning mean {plan['mean']:.2f} s, median "
                                        f"{plan['median']:.2f}, p90 {plan['p90']:.2f} "
                                        f"({plan['calls']} calls)")
        valid_mean = "–" if r["mean_valid"] is None else f"{r['mean_valid']:+.3f}"
        print(f"  {m:20s} {r['mean']:+.3f} ± {r['se']:.3f} ({r['valid']}/{r['trials']} valid, "
              f"{valid_mean} over them; {r['success']} successes){plan}{tail}")
for m, d in pooled.items():
    if len(d) > 1:
        summary["pooled"][m] = {"pairs": len(d), "mean": st.mean(d), "se": se(d),
                                "se_multiples": st.mean(d) / se(d) if se(d) > 0 else None}
print("\npooled over the models, dips − method (paired within each model):")
for m, p in summary["pooled"].items():
    print(f"  {m:20s} {p['mean']:+.3f} ± {p['se']:.3f} over {p['pairs']} pairs")
dest = root / table
tmp = dest.with_suffix(".json.partial")
tmp.write_text(json.dumps(summary, indent=1) + "\n")
tmp.replace(dest)
print(f"\nwrote {dest}")
