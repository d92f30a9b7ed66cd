#!/usr/bin/env python3
"""Median seconds per onnxruntime call for a contract-v1 model at a batch size.

Usage: .venv/bin/python bench/ort_time.py MODEL.onnx --batch 96 [--iters 30] [--threads N]
Prints one JSON object. Inputs are random with the contract's shapes (same kinds as
`dips bench inference`). Needs `pip install onnxruntime numpy`; no test depends on it.
"""
import argparse
import json
import time

import numpy as np
import onnxruntime as ort


def main():
    p = argparse.ArgumentParser()
    p.add_argument("model")
    p.add_argument("--batch", type=int, default=96)
    p.add_argument("--iters", type=int, default=50)
    p.add_argument("--threads", type=int, default=0, help="intra-op threads (0 = onnxruntime default)")
    a = p.parse_args()
    so = ort.SessionOptions()
    if a.threads:
        so.intra_op_num_threads = a.threads
    sess = ort.InferenceSession(a.model, so, providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(7)
    feeds = {}
    for i in sess.get_inputs():
        shape = [a.batch] + [d for d in i.shape[1:]]
        if i.name == "t":
            feeds[i.name] = rng.integers(0, 256, size=shape).astype(np.float32)
        elif i.name == "context":
            feeds[i.name] = rng.choice([-1.0, 1.0], size=shape).astype(np.float32)
        elif i.name == "cond_mask":
            feeds[i.name] = rng.integers(0, 2, size=shape).astype(np.float32)
        else:
            feeds[i.name] = rng.standard_normal(shape).astype(np.float32)
    for _ in range(3):
        sess.run(None, feeds)
    times = []
    for _ in range(max(1, a.iters)):
        t0 = time.perf_counter()
        sess.run(None, feeds)
        times.append(time.perf_counter() - t0)
    times.sort()
    print(json.dumps({"bench": "ort", "file": a.model, "batch": a.batch, "iters": a.iters,
                      "threads": a.threads or "default", "ort_version": ort.__version__,
                      "ort_s": times[len(times) // 2], "ort_min_s": times[0]}))


if __name__ == "__main__":
    main()
