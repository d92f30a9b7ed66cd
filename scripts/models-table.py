#!/usr/bin/env python3
"""The training-seed experiment's table (issue 38 items 3-4; registered in
docs/results/PROTOCOL.md): for each trained screwdriver model (seed 0 = the shipped one,
seeds 1 and 2), the `results.json` of docs/results/screwdriver/models-10200-seed<S>/ and, when
present, models-10210-seed<S>/ (dips, dips-k1, dips-max-likelihood on 20 more seeds). Prints
each method's mean ± SE (valid, over all trials and over valid ones) per model, and DIPS's
paired margins over every method per model and pooled over the models (each model's seeds
paired within the model), and writes docs/results/screwdriver/models-10200.json.

Usage: scripts/models-table.py [RESULTS_DIR]   (default docs/results/screwdriver)
"""
import json
import statistics as st
import sys
from pathlib import Path

from paired import se, trials as read_trials

root = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/results/screwdriver")
METHODS = ["dips", "dips-sampled", "csvto-sampled", "dips-no-replan", "dips-k1",
           "dips-max-likelihood", "diffusion-policy"]


def trials(seed):
    """(method, seed) → trial over the model's runs that exist, and their statuses."""
    paths = [p for first in (10200, 10210)
             if (p := root / f"models-{first}-seed{seed}" / "results.json").exists()]
    statuses = {p.parent.name.split("-")[1]:
                json.loads(p.read_text()).get("registration", {}).get("status", "unregistered")
                for p in paths}
    return read_trials(paths, "models-table.py"), statuses


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
        rows[m] = {"trials": len(xs), "valid": len(valid), "mean": st.mean(out), "se": se(out),
                   "mean_valid": st.mean(valid) if valid else None, "median": st.median(out)}
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
        print(f"  {m:20s} {r['mean']:+.3f} ± {r['se']:.3f} ({r['valid']}/{r['trials']}){tail}")
for m, d in pooled.items():
    if len(d) > 1:
        summary["pooled"][m] = {"pairs": len(d), "mean": st.mean(d), "se": se(d),
                                "se_multiples": st.mean(d) / se(d) if se(d) > 0 else None}
print("\npooled over the models, dips − method (paired within each model):")
for m, p in summary["pooled"].items():
    print(f"  {m:20s} {p['mean']:+.3f} ± {p['se']:.3f} over {p['pairs']} pairs")
dest = root / "models-10200.json"
tmp = dest.with_suffix(".json.partial")
tmp.write_text(json.dumps(summary, indent=1) + "\n")
tmp.replace(dest)
print(f"\nwrote {dest}")
