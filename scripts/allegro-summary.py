#!/usr/bin/env python3
"""Summarise scripts/allegro-compare.sh's episodes into one JSON (docs/allegro.md, 'Measured').

usage: allegro-summary.py OUT_DIR SUMMARY_JSON
Per task and hand: each seed's outcome (card: final distance to the goal in cm; screwdriver:
final yaw in rad), validity, modes, and for the Allegro driver its loop period (p50, p99, max),
frames counted and tracking error at the end of each action; then per task the paired
difference allegro:emulated - its stand-in on the same seeds."""
import json
import math
import os
import sys


def outcome(r):
    if r.get("final_distance_m") is not None:
        return 100.0 * r["final_distance_m"]
    return r.get("final_yaw")


def mean_se(xs):
    if not xs:
        return None
    m = sum(xs) / len(xs)
    if len(xs) < 2:
        return {"mean": m, "se": None, "n": len(xs)}
    var = sum((x - m) ** 2 for x in xs) / (len(xs) - 1)
    return {"mean": m, "se": math.sqrt(var / len(xs)), "n": len(xs)}


def main(out, dest):
    summary = {"command": "scripts/allegro-compare.sh", "tasks": {}}
    for task in sorted(os.listdir(out)):
        tdir = os.path.join(out, task)
        hands = {}
        for tag in sorted(os.listdir(tdir)):
            hdir = os.path.join(tdir, tag)
            if not os.path.isdir(hdir):
                continue
            rows = {}
            for sd in sorted(os.listdir(hdir)):
                f = os.path.join(hdir, sd, "result.json")
                if not os.path.isfile(f):
                    continue
                r = json.load(open(f))
                row = {
                    "outcome": outcome(r),
                    "valid": r["valid"],
                    "modes": r["modes"],
                    "planning_s_mean": sum(r["planning_s"]) / max(1, len(r["planning_s"])),
                }
                rep = r.get("hand_report")
                if rep:
                    lp = rep["loop"]
                    row["loop"] = {k: lp["period"][k] for k in ("p50_ms", "p99_ms", "max_ms", "jitter_ms")}
                    row["frames"] = {k: lp[k] for k in ("frames_sent", "torque_frames", "frames_received", "pose_sets", "bad_frames", "saturated_ticks")}
                    row["tracking"] = rep["tracking"]
                rows[sd.removeprefix("seed-")] = row
            hands[tag] = {
                "unit": "cm to the goal" if task == "card" else "final yaw (rad)",
                "episodes": rows,
                "outcome": mean_se([r["outcome"] for r in rows.values()]),
                "valid": sum(r["valid"] for r in rows.values()),
            }
        pairs = {}
        for emu, base in (("allegro-emulated", "world"), ("allegro-emulated-plant-mujoco", "mujoco")):
            if emu in hands and base in hands:
                a, b = hands[emu]["episodes"], hands[base]["episodes"]
                d = [a[s]["outcome"] - b[s]["outcome"] for s in a if s in b]
                pairs[f"{emu} - {base}"] = mean_se(d)
        summary["tasks"][task] = {"hands": hands, "paired": pairs}
    os.makedirs(os.path.dirname(dest), exist_ok=True)
    with open(dest + ".tmp", "w") as f:
        json.dump(summary, f, indent=2)
    os.replace(dest + ".tmp", dest)
    print(json.dumps({t: {h: v["outcome"] for h, v in s["hands"].items()} for t, s in summary["tasks"].items()}, indent=1))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
