#!/usr/bin/env python3
"""How CSVTO plans a card push and what the world gives, step by step, from the demos.

For every push (index, middle, both) of the card demos, the executed particle's recorded
trajectory at each online step k (rows 0..k executed, the rest CSVTO's plan from there) is read
as the card's y relative to the mode's start; the mean over pushes of each step's row profile
is printed beside the push's executed change (the mode's end state). It shows how far CSVTO
expects its next action to move the card and how far the world moves it.

Usage: scripts/card-push-profile.py [DATA_DIR] > docs/results/card/paper-push-profile.json
  DATA_DIR: the demos (default target/models-work/data/card-paper, `dips datagen --task card
  --card-goals paper --demos 128`). Needs numpy.
"""
import glob
import json
import struct
import sys

import numpy as np

PUSHES = ("index", "middle", "both")
Y = 9  # the card's y among the state columns (8 joints, then x, y, cos θ, sin θ)


def demo(path):
    raw = open(path, "rb").read()
    n = struct.unpack("<Q", raw[:8])[0]
    header = json.loads(raw[8:8 + n])
    base = 8 + n

    def tensor(key, dtype):
        lo, hi = header[key]["data_offsets"]
        return np.frombuffer(raw[base + lo:base + hi], dtype=dtype).reshape(header[key]["shape"])

    return (header["__metadata__"], tensor("mode_index", np.int64), tensor("particle", np.int64),
            tensor("step", np.int64), tensor("trajectories", np.float32))


def main():
    data = sys.argv[1] if len(sys.argv) > 1 else "target/models-work/data/card-paper"
    profiles, executed = [], []
    for path in sorted(glob.glob(f"{data}/demos/*.safetensors")):
        meta, mode_index, particle, step, traj = demo(path)
        modes = json.loads(meta["outcome"])["modes"]
        steps = int(step.max()) + 1
        for m, record in enumerate(modes):
            if record["mode"] not in PUSHES:
                continue
            y0 = record["start_state"][Y]
            rows = []
            for k in range(steps):
                at = np.flatnonzero((mode_index == m) & (particle == 0) & (step == k))
                if at.size == 0:
                    break
                rows.append(traj[at[0]][:, Y] - y0)
            if len(rows) == steps:
                profiles.append(rows)
                executed.append(record["end_state"][Y] - y0)
    p = np.array(profiles) * 100.0
    report = {
        "command": "scripts/card-push-profile.py " + data,
        "unit": "cm of card y from the push's start",
        "pushes": len(profiles),
        "executed_mean": round(float(np.mean(executed) * 100.0), 3),
        "by_step": [
            {"step": k,
             "rows_mean": [round(float(v), 3) for v in p[:, k, :].mean(axis=0)],
             "next_row_planned_mean": round(float(p[:, k, k + 1].mean()), 3)
             if k + 1 < p.shape[2] else None,
             "next_row_executed_mean": round(float(p[:, k + 1, k + 1].mean()), 3)
             if k + 1 < p.shape[1] else None}
            for k in range(p.shape[1])],
    }
    json.dump(report, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
