#!/usr/bin/env python3
"""A small card denoiser using the GroupNormalization op (opset 21: per-channel scale and
bias), Relu, Sub/Div by constants and a step input broadcast over channels and time;
reference outputs by onnxruntime. Random weights, seed 5.

Run: .venv/bin/python onnx/tests/data/gen_groupnorm.py  (writes groupnorm21_card.onnx/.io.json)
"""
import json
import os

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

rng = np.random.default_rng(5)
T, D, F, C = 9, 29, 2, 10
inits = []


def init(name, arr):
    inits.append(numpy_helper.from_array(np.asarray(arr, dtype=np.float32), name))
    return name


def i64(name, arr):
    inits.append(numpy_helper.from_array(np.asarray(arr, dtype=np.int64), name))
    return name


nodes = [
    helper.make_node("Transpose", ["x"], ["xt"], perm=[0, 2, 1]),
    helper.make_node("Sub", ["xt", init("mu", 0.1 * rng.standard_normal((D, 1)))], ["xc"]),
    helper.make_node("Div", ["xc", init("sd", 1 + rng.random((D, 1)))], ["xn"]),
    helper.make_node("Conv", ["xn", init("w1", rng.standard_normal((C, D, 3)) / np.sqrt(3 * D)), init("b1", 0.1 * rng.standard_normal(C))], ["c1"], kernel_shape=[3], pads=[1, 1]),
    helper.make_node("GroupNormalization", ["c1", init("gs", 1 + 0.2 * rng.standard_normal(C)), init("gb", 0.2 * rng.standard_normal(C))], ["g1"], num_groups=2, epsilon=1e-5),
    helper.make_node("Relu", ["g1"], ["r1"]),
    helper.make_node("Gemm", ["context", init("wc", rng.standard_normal((C, F))), init("bc", np.zeros(C))], ["ce"], transB=1),
    helper.make_node("Mul", ["ce", "cm2"], ["cem"]),
    helper.make_node("Unsqueeze", ["cond_mask", i64("ax1", [1])], ["cm2"]),
    helper.make_node("Unsqueeze", ["cem", i64("ax2", [2])], ["ce3"]),
    helper.make_node("Unsqueeze", ["t", i64("ax1b", [1])], ["t2"]),
    helper.make_node("Unsqueeze", ["t2", i64("ax2b", [2])], ["t3"]),
    helper.make_node("Mul", ["t3", init("tscale", [[[0.01]]])], ["ts"]),
    helper.make_node("Add", ["r1", "ce3"], ["a1"]),
    helper.make_node("Add", ["a1", "ts"], ["a2"]),
    helper.make_node("Conv", ["a2", init("w2", rng.standard_normal((D, C, 1)) / np.sqrt(C)), init("b2", np.zeros(D))], ["c2"], kernel_shape=[1]),
    helper.make_node("Transpose", ["c2"], ["eps"], perm=[0, 2, 1]),
]
# Mul must come after its inputs are defined: move the cond_mask Unsqueeze first.
nodes.insert(6, nodes.pop(8))
cols = [f"q_{f}_{j}" for f in ["index", "middle"] for j in range(4)] + ["x", "y", "cos_theta", "sin_theta"]
cols += [f"dq_{f}_{j}" for f in ["index", "middle"] for j in range(4)] + [f"f_{f}_{a}" for f in ["index", "middle", "env"] for a in "xyz"]
graph = helper.make_graph(
    nodes, "groupnorm21_card",
    [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["B", T, D]),
     helper.make_tensor_value_info("t", TensorProto.FLOAT, ["B"]),
     helper.make_tensor_value_info("context", TensorProto.FLOAT, ["B", F]),
     helper.make_tensor_value_info("cond_mask", TensorProto.FLOAT, ["B"])],
    [helper.make_tensor_value_info("eps", TensorProto.FLOAT, ["B", T, D])], inits)
model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 21)])
model.ir_version = 10
meta = {"dips.contract": "1", "dips.role": "denoiser", "dips.task": "card", "dips.horizon": str(T),
        "dips.state_dim": "12", "dips.action_dim": "17", "dips.fingers": str(F), "dips.diffusion_steps": "100",
        "dips.beta_schedule": "cosine", "dips.prediction": "epsilon",
        "dips.norm_mean": json.dumps([0.0] * D), "dips.norm_std": json.dumps([1.0] * D), "dips.columns": json.dumps(cols)}
for k, v in meta.items():
    model.metadata_props.append(onnx.StringStringEntryProto(key=k, value=v))
onnx.checker.check_model(model, full_check=True)
here = os.path.dirname(os.path.abspath(__file__))
onnx.save(model, os.path.join(here, "groupnorm21_card.onnx"))
B = 3
feeds = {"x": rng.standard_normal((B, T, D)).astype(np.float32), "t": np.array([3, 50, 99], dtype=np.float32),
         "context": rng.choice([-1.0, 1.0], (B, F)).astype(np.float32), "cond_mask": np.array([1, 0, 1], dtype=np.float32)}
(eps,) = ort.InferenceSession(os.path.join(here, "groupnorm21_card.onnx"), providers=["CPUExecutionProvider"]).run(None, feeds)
with open(os.path.join(here, "groupnorm21_card.io.json"), "w") as f:
    json.dump({"inputs": {k: {"shape": list(v.shape), "data": v.flatten().tolist()} for k, v in feeds.items()},
               "outputs": {"eps": {"shape": list(eps.shape), "data": eps.flatten().tolist()}}}, f)
print("eps std", float(eps.std()))
