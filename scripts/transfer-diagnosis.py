#!/usr/bin/env python3
"""Where the transfer experiment's episodes differ between the hands (issue 37 item 6), from
the episodes' step logs: the card's per-mode displacement by mode kind, single-finger modes
that moved the card back, fingertips pressing on the table's side face; the screwdriver's yaw
per `turn` mode of `dips`. Writes docs/results/transfer-10100-diagnosis.json.

The committed result folders keep only the median episodes; the others are regenerated bit for
bit by running the same protocol into another folder (`dips eval --protocol … --out DIR`; it
is then labelled a rerun) or are found where scripts/transfer-10100.sh left them. Give the
folders that hold the episodes:

Usage: scripts/transfer-diagnosis.py [ROOT...]   (default: . and target/kept-episodes)
"""
import glob
import json
import statistics as st
import sys
from pathlib import Path

roots = sys.argv[1:] or [".", "target/kept-episodes"]
CARD_Y = 9  # state index of the card's y (8 task joints, then x, y, θ)


def episodes(task, arm, method=None):
    found = {}
    for root in roots:
        pattern = f"{root}/docs/results/{task}/transfer-10100-{arm}/episodes/{method or '*'}/seed-*/result.json"
        for f in glob.glob(pattern):
            key = Path(f).parts[-3:-1]
            found.setdefault(key, json.loads(Path(f).read_text()))
    return list(found.values())


out = {"roots": roots, "card": {}, "screwdriver": {}}
for arm in ["world", "mujoco", "mujoco-noisy"]:
    eps = episodes("card", arm)
    both, single, first, back, catch, steps, catch_eps = [], [], [], 0, 0, 0, 0
    for r in eps:
        caught = False
        for k, m in enumerate(r["mode_runs"]):
            dy = (m["end_state"][CARD_Y] - m["start_state"][CARD_Y]) * 100
            if m["mode"] == "both":
                both.append(dy)
                if k == 0:
                    first.append(dy)
            else:
                single.append(dy)
                back += dy > 0.2
            for s in m["steps"]:
                steps += 1
                side = [abs(c["force"][1]) for c in s["contacts"]
                        if c["part"] == "table" and c["finger"] != "card"]
                if side and max(side) > 1.0:
                    catch += 1
                    caught = True
        catch_eps += caught
    if eps:
        out["card"][arm] = {
            "episodes": len(eps),
            "both_modes": len(both), "both_mean_dy_cm": st.mean(both),
            "first_push_mean_dy_cm": st.mean(first),
            "single_finger_modes": len(single), "single_mean_dy_cm": st.mean(single),
            "single_moved_back_over_2mm": back,
            "steps": steps, "steps_tip_on_table_side_over_1N": catch,
            "episodes_with_tip_on_table_side": catch_eps,
        }
    turns = [m["end_state"][-1] - m["start_state"][-1]
             for r in episodes("screwdriver", arm, "dips") for m in r["mode_runs"]
             if m["mode"] == "turn"]
    if turns:
        out["screwdriver"][arm] = {"dips_turn_modes": len(turns),
                                   "dips_mean_dyaw_per_turn": st.mean(turns)}
dest = Path("docs/results/transfer-10100-diagnosis.json")
dest.write_text(json.dumps(out, indent=1) + "\n")
print(json.dumps(out, indent=1))
