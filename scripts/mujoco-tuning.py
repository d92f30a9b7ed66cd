#!/usr/bin/env python3
"""Summarise scripts/mujoco-tuning.sh's evaluations (`dips eval --hand H` folders: each
episode's result.json and wall.json) into
one JSON (per episode and per task x hand x method) and print docs/mujoco.md's table.
Usage: scripts/mujoco-tuning.py OUT_DIR RESULTS_JSON"""
import json
import statistics
import sys
from pathlib import Path

out, dest = Path(sys.argv[1]), Path(sys.argv[2])
rows, episodes = [], []


def episodes_of(folder, method):
    """The episodes of `method` in a `dips eval` folder, one dict each, by seed."""
    eps = []
    seeds = sorted((folder / "episodes" / method).glob("seed-*"), key=lambda p: int(p.name[5:]))
    for d in seeds:
        wall = json.loads((d / "wall.json").read_text())
        r = json.loads((d / "result.json").read_text()) if (d / "result.json").exists() else {}
        eps.append({
            "method": method,
            "seed": int(d.name[5:]),
            "hand": r.get("hand", "world"),
            "modes": r.get("modes", []),
            "final_yaw": r.get("final_yaw"),
            "final_distance_m": r.get("final_distance_m"),
            "final_dy_m": r.get("final_dy_m"),
            "valid": r.get("valid", False),
            "success": r.get("success", False),
            "seconds": wall["seconds"],
            "error": wall.get("error"),
        })
    return eps


for task in ["screwdriver", "card"]:
    for method in ["dips", "dips-sampled"]:
        for hand in ["mujoco", "world"]:
            eps = episodes_of(out / f"{task}-{hand}", method)
            assert all(e["seed"] < 1000 for e in eps), "tuning seeds only"
            assert all(e["hand"] == hand for e in eps if e["error"] is None), "hand recorded"
            episodes += [{"task": task, **e} for e in eps]
            key = "final_yaw" if task == "screwdriver" else "final_distance_m"
            vals = [e[key] for e in eps if e[key] is not None]
            row = {
                "task": task,
                "method": method,
                "hand": hand,
                "seeds": [e["seed"] for e in eps],
                "episodes": len(eps),
                "errors": sum(e["error"] is not None for e in eps),
                "success": sum(e["success"] for e in eps),
                "valid": sum(e["valid"] for e in eps),
                key + "_median": statistics.median(vals) if vals else None,
                key + "_per_seed": [e[key] for e in eps],
                "mean_seconds": statistics.mean(e["seconds"] for e in eps) if eps else None,
            }
            if task == "card":
                row["final_dy_m_per_seed"] = [e["final_dy_m"] for e in eps]
            rows.append(row)


def diagnostics(hand):
    """Per-mode progress and fingertip-table contacts over every episode of `hand`."""
    import glob
    import math

    turns, first, later, steps, hits, eps_hit, eps, fmax = [], [], [], 0, 0, 0, 0, 0.0
    for f in glob.glob(str(out / f"screwdriver-{hand}" / "episodes" / "*" / "seed-*" / "result.json")):
        r = json.loads(Path(f).read_text())
        turns += [m["end_state"][-1] - m["start_state"][-1] for m in r["mode_runs"] if m["mode"] == "turn"]
    for f in glob.glob(str(out / f"card-{hand}" / "episodes" / "*" / "seed-*" / "result.json")):
        r = json.loads(Path(f).read_text())
        eps += 1
        hit = False
        for i, m in enumerate(r["mode_runs"]):
            if m["mode"] != "regrasp":
                (first if i == 0 else later).append(m["end_state"][-2] - m["start_state"][-2])
            for st in m["steps"]:
                steps += 1
                fs = [math.hypot(*c["force"]) for c in st["contacts"] or []
                      if c["finger"] != "card" and c["part"] == "table"]
                if fs and max(fs) > 1.0:
                    hits += 1
                    hit = True
                    fmax = max(fmax, max(fs))
        eps_hit += hit
    return {
        "screwdriver_turn_dyaw_mean_rad": statistics.mean(turns),
        "screwdriver_turn_modes": len(turns),
        "card_first_push_dy_mean_m": statistics.mean(first),
        "card_later_push_dy_mean_m": statistics.mean(later),
        "card_later_push_dy_max_m": max(later),
        "card_steps": steps,
        "card_steps_with_fingertip_table_force_over_1N": hits,
        "card_episodes_with_fingertip_table_force_over_1N": eps_hit,
        "card_episodes": eps,
        "card_fingertip_table_force_max_N": fmax,
    }


settings = {
    "command": "scripts/mujoco-tuning.sh (dips eval --hand mujoco|world through dips-mujoco)",
    "seeds": "500..505 (tuning seeds; none >= 1000)",
    "screwdriver": "--max-modes 4, the task's node budget (13), sampler ddpm:16, time budget 300 s",
    "card": "5 modes, --node-budget 8, sampler ddpm:16, time budget 300 s",
    "models": "the shipped models (onnx/models/<task>), kernel engine, 1 thread per model call",
}
dest.parent.mkdir(parents=True, exist_ok=True)
dest.write_text(json.dumps({"settings": settings, "rows": rows,
                            "diagnostics": {h: diagnostics(h) for h in ["mujoco", "world"]},
                            "episodes": episodes}, indent=1) + "\n")

print("| task | method | hand | success | valid | per seed | median | mean wall s |")
print("|---|---|---|---|---|---|---|---|")
for r in rows:
    key = "final_yaw" if r["task"] == "screwdriver" else "final_distance_m"
    scale, unit = (1.0, "rad") if key == "final_yaw" else (100.0, "cm")
    per = ", ".join("—" if v is None else f"{scale * v:.2f}" for v in r[key + "_per_seed"])
    med = r[key + "_median"]
    print(
        f"| {r['task']} | {r['method']} | {r['hand']} | {r['success']}/{r['episodes']} | "
        f"{r['valid']}/{r['episodes']} | {per} {unit} | "
        f"{'—' if med is None else f'{scale * med:.2f}'} | {r['mean_seconds']:.0f} |"
    )
