#!/usr/bin/env python3
"""The paper's hardware CSVTO settings on tuning seeds (docs/mujoco.md, "The paper's
hardware settings"): per run and method, the final yaw of every seed, the mean `turn` of a
`turn` mode, validity; then the paired differences asked for.

Usage: scripts/hardware-tuning.py OUT.json NAME=RUN_DIR... [--pair A:B ...]
  RUN_DIR: a `dips eval` directory (results.json, episodes/<method>/seed-<s>/result.json).
  --pair NAME_A/METHOD:NAME_B/METHOD  paired mean difference A − B over their common seeds.
"""
import json
import os
import sys

from paired import se


def turn_modes(result):
    out = []
    for m in result.get("mode_runs", []):
        if m["mode"] == "turn":
            out.append(m["end_state"][-1] - m["start_state"][-1])
    return out


def run(directory):
    res = json.load(open(os.path.join(directory, "results.json")))
    methods = {}
    for m in res["methods"]:
        name = m["method"]
        seeds = {}
        turns = []
        for t in res["trials"]:
            if t["method"] != name:
                continue
            f = os.path.join(directory, "episodes", name, f"seed-{t['seed']}", "result.json")
            if os.path.exists(f):
                turns += turn_modes(json.load(open(f)))
            seeds[str(t["seed"])] = {"final_yaw": t["outcome"], "valid": t["valid"],
                                     "modes": t["modes"]}
        ys = [s["final_yaw"] for s in seeds.values()]
        methods[name] = {
            "settings": res["eval"]["episode"],
            "trials": len(ys),
            "valid": sum(s["valid"] for s in seeds.values()),
            "mean_final_yaw": sum(ys) / len(ys),
            "se_final_yaw": se(ys) if len(ys) > 1 else None,
            "turn_mode_mean_yaw": sum(turns) / len(turns) if turns else None,
            "turn_modes": len(turns),
            "seeds": seeds,
        }
    return methods


def main():
    args = sys.argv[1:]
    if not args or "=" in args[0]:
        sys.exit(__doc__)
    out, rest = args[0], args[1:]
    runs, pairs = {}, []
    while rest:
        a = rest.pop(0)
        if a == "--pair":
            pairs.append(rest.pop(0))
        else:
            name, d = a.split("=", 1)
            runs[name] = run(d)
    summary = {"runs": runs, "paired": {}}
    for p in pairs:
        a, b = p.split(":")
        (ra, ma), (rb, mb) = a.split("/"), b.split("/")
        sa, sb = runs[ra][ma]["seeds"], runs[rb][mb]["seeds"]
        common = sorted(set(sa) & set(sb), key=int)
        d = [sa[s]["final_yaw"] - sb[s]["final_yaw"] for s in common]
        summary["paired"][p] = {
            "seeds": len(d),
            "mean": sum(d) / len(d),
            "se": se(d) if len(d) > 1 else None,
            "ratio_of_means": sum(sa[s]["final_yaw"] for s in common)
            / sum(sb[s]["final_yaw"] for s in common),
        }
    with open(out + ".tmp", "w") as f:
        json.dump(summary, f, indent=1)
        f.write("\n")
    os.replace(out + ".tmp", out)
    for name, methods in runs.items():
        for m, v in methods.items():
            t = v["turn_mode_mean_yaw"]
            print(f"{name:22} {m:14} {v['valid']}/{v['trials']} valid  mean {v['mean_final_yaw']:.3f}"
                  f"  turn mode {t if t is None else round(t, 3)} ({v['turn_modes']})")
    for p, v in summary["paired"].items():
        print(f"{p}: {v['mean']:+.3f} ± {v['se'] or 0:.3f} over {v['seeds']}; ratio {v['ratio_of_means']:.3f}")


main()
