#!/usr/bin/env python3
"""How far the card-paper models believe a push moves the card, by where it starts, beside the
demos' own pushes from the same states (the held-out demos of each model's training).

Runs the `mode_probe` example (host/cli/examples/mode_probe.rs: 64 segments per start state,
the planner's sampler) on every held-out push (index, middle, both) of the card-paper demos and
bins the mean diffused and executed change of the card's y by the push's start.

Usage: scripts/card-push-probe.py [DATA_DIR [MODELS...]] > docs/results/card/paper-push-probe.json
  DATA_DIR: the demos (default target/models-work/data/card-paper, `dips datagen --task card
  --card-goals paper --demos 128`). MODELS: model folders (default the three card-paper ones;
  the card-paper-start ones, trained in the segment-start frame, go to
  docs/results/card/paper-start-push-probe.json). Needs `cargo build --release -p dips-cli
  --example mode_probe`.
"""
import json
import re
import statistics as st
import subprocess
import sys

PROBE = "target/release/examples/mode_probe"
MODELS = ["onnx/models/card-paper", "onnx/models/card-paper-seed1", "onnx/models/card-paper-seed2"]
SAMPLER = "ddpm:16"
LINE = re.compile(r"start (\S+): executed (\S+), diffused (\S+);")
PROFILE = re.compile(r"profile, diffused:\s+(.*)$")


def probe(models, data, mode):
    out = subprocess.run(
        [PROBE, "--task", "card", "--models", models, "--sampler", SAMPLER, "--demos", data,
         "--held-out", "--mode", mode, "--limit", "1000", "--profile"],
        check=True, capture_output=True, text=True).stdout
    rows = []
    for line in out.splitlines():
        m = LINE.search(line)
        if m:
            rows.append([float(v.rstrip(",:")) * 100.0 for v in m.groups()])
        p = PROFILE.search(line)
        if p and rows:
            profile = [float(v) * 100.0 for v in p.group(1).split()]
            rows[-1] += [profile[1], profile[-1] - profile[1]]
    return rows


def main():
    data = sys.argv[1] if len(sys.argv) > 1 else "target/models-work/data/card-paper"
    models_list = sys.argv[2:] or MODELS
    report = {"command": " ".join(["scripts/card-push-probe.py", data] + sys.argv[2:]),
              "sampler": SAMPLER, "unit": "cm of card y", "models": {}}
    for models in models_list:
        rows = [r for mode in ("index", "middle", "both") for r in probe(models, data, mode)]
        bins = {}
        for start, executed, diffused, row1, after in rows:
            b = int(round(-start)) // 2 * 2
            bins.setdefault(b, []).append((diffused, executed, row1, after))
        report["models"][models] = {
            "pushes": len(rows),
            "diffused_mean": round(st.mean(r[2] for r in rows), 3),
            "executed_mean": round(st.mean(r[1] for r in rows), 3),
            "by_start": {
                f"{b}-{b + 2} cm": {
                    "n": len(v),
                    "diffused_mean": round(st.mean(r[0] for r in v), 3),
                    "executed_mean": round(st.mean(r[1] for r in v), 3),
                    "diffused_row1_mean": round(st.mean(r[2] for r in v), 3),
                    "diffused_after_row1_mean": round(st.mean(r[3] for r in v), 3),
                } for b, v in sorted(bins.items())},
        }
    json.dump(report, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
