#!/usr/bin/env python3
"""Build a small contract-v1 denoiser that is NOT one of the fixtures' architectures, and its
onnxruntime reference outputs: card task (T=9, D=29, F=2), channels 12/24 (GroupNorm with 4
groups written as Reshape+InstanceNormalization+Reshape+Mul+Add), one level of stride-2
downsampling, ConvTranspose upsampling, explicit Pad (9 -> 10) and Slice crop, Mish written
both as the Mish op and as Softplus*Tanh, MatMul instead of Gemm in one place, a dilated conv,
ReduceMean, Sigmoid gating and Sin/Cos step embedding. Random weights, seed 11.

Run: .venv/bin/python onnx/tests/data/gen_custom.py   (writes custom_card.onnx and custom_card.io.json)
"""
import json
import os

import numpy as np
import onnx
import onnxruntime as ort
from onnx import TensorProto, helper, numpy_helper

rng = np.random.default_rng(11)
T, D, F = 9, 29, 2
nodes, inits = [], []
counter = [0]


def name(p):
    counter[0] += 1
    return f"{p}_{counter[0]}"


def init(arr, p="w"):
    n = name(p)
    inits.append(numpy_helper.from_array(np.asarray(arr, dtype=np.float32 if np.asarray(arr).dtype.kind == "f" else np.int64), n))
    return n


def node(op, ins, **attrs):
    out = name(op.lower())
    nodes.append(helper.make_node(op, ins, [out], **attrs))
    return out


def weight(*shape):
    fan_in = np.prod(shape[1:]) if len(shape) > 1 else shape[0]
    return init(rng.standard_normal(shape) / np.sqrt(fan_in))


def mish(x, fused):
    if fused:
        return node("Mish", [x])
    sp = node("Softplus", [x])
    return node("Mul", [x, node("Tanh", [sp])])


def group_norm(x, c, groups=4):
    r = node("Reshape", [x, init(np.array([0, groups, -1], dtype=np.int64), "shape")])
    n = node("InstanceNormalization", [r, init(np.ones(groups)), init(np.zeros(groups))], epsilon=1e-5)
    back = node("Reshape", [n, node("Shape", [x])])
    g = node("Mul", [back, init(1 + 0.1 * rng.standard_normal((c, 1)))])
    return node("Add", [g, init(0.1 * rng.standard_normal((c, 1)))])


def block(x, cin, cout, fused, dil=1):
    y = node("Conv", [x, weight(cout, cin, 3), init(0.1 * rng.standard_normal(cout))], kernel_shape=[3], pads=[dil, dil], dilations=[dil])
    return mish(group_norm(y, cout), fused)


def res_block(x, cin, cout, emb, fused):
    y = block(x, cin, cout, fused)
    e = node("Gemm", [emb, weight(cout, 32), init(np.zeros(cout))], transB=1)
    y = node("Add", [y, node("Unsqueeze", [e, init(np.array([2], dtype=np.int64), "axes")])])
    y = block(y, cout, cout, not fused, dil=2 if cout == 24 else 1)
    skip = x if cin == cout else node("Conv", [x, weight(cout, cin, 1), init(np.zeros(cout))], kernel_shape=[1])
    return node("Add", [y, skip])


# Step and context embedding (32 wide).
freqs = init(np.exp(-np.log(1000.0) * np.arange(8) / 8).reshape(1, 8))
tt = node("Mul", [node("Unsqueeze", ["t", init(np.array([1], dtype=np.int64), "axes")]), freqs])
temb = node("Concat", [node("Sin", [tt]), node("Cos", [tt])], axis=-1)
cemb = mish(node("MatMul", ["context", weight(F, 16)]), True)
cemb = node("Mul", [cemb, node("Unsqueeze", ["cond_mask", init(np.array([1], dtype=np.int64), "axes")])])
emb = mish(node("Gemm", [node("Concat", [temb, cemb], axis=1), weight(32, 32), init(np.zeros(32))], transB=1), False)

x = node("Transpose", ["x"], perm=[0, 2, 1])
x = node("Pad", [x, init(np.array([0, 0, 0, 0, 0, 1], dtype=np.int64), "pads")], mode="constant")
h1 = res_block(x, D, 12, emb, False)
down = node("Conv", [h1, weight(12, 12, 3), init(np.zeros(12))], kernel_shape=[3], pads=[1, 1], strides=[2])
h2 = res_block(down, 12, 24, emb, True)
gate = node("Sigmoid", [node("ReduceMean", [h2, init(np.array([2], dtype=np.int64), "axes")], keepdims=1)])
h2 = node("Mul", [h2, gate])
up = node("ConvTranspose", [h2, weight(24, 12, 4), init(np.zeros(12))], kernel_shape=[4], strides=[2], pads=[1, 1])
h3 = res_block(node("Concat", [up, h1], axis=1), 24, 12, emb, False)
out = node("Conv", [h3, weight(D, 12, 1), init(np.zeros(D))], kernel_shape=[1])
out = node("Slice", [out, init(np.array([0], dtype=np.int64), "s"), init(np.array([T], dtype=np.int64), "e"), init(np.array([2], dtype=np.int64), "a")])
nodes.append(helper.make_node("Transpose", [out], ["eps"], perm=[0, 2, 1]))

cols = [f"q_{f}_{j}" for f in ["index", "middle"] for j in range(4)] + ["x", "y", "cos_theta", "sin_theta"]
cols += [f"dq_{f}_{j}" for f in ["index", "middle"] for j in range(4)] + [f"f_{f}_{a}" for f in ["index", "middle", "env"] for a in "xyz"]
inputs = [
    helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", T, D]),
    helper.make_tensor_value_info("t", TensorProto.FLOAT, ["batch"]),
    helper.make_tensor_value_info("context", TensorProto.FLOAT, ["batch", F]),
    helper.make_tensor_value_info("cond_mask", TensorProto.FLOAT, ["batch"]),
]
outputs = [helper.make_tensor_value_info("eps", TensorProto.FLOAT, ["batch", T, D])]
graph = helper.make_graph(nodes, "custom_card_denoiser", inputs, outputs, inits)
model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
model.ir_version = 9
meta = {
    "dips.contract": "1", "dips.role": "denoiser", "dips.task": "card", "dips.horizon": str(T),
    "dips.state_dim": "12", "dips.action_dim": "17", "dips.fingers": str(F), "dips.diffusion_steps": "256",
    "dips.beta_schedule": "cosine", "dips.prediction": "epsilon",
    "dips.norm_mean": json.dumps([round(float(v), 4) for v in rng.standard_normal(D)]),
    "dips.norm_std": json.dumps([round(float(v), 4) for v in 0.5 + rng.random(D)]),
    "dips.columns": json.dumps(cols),
}
for k, v in meta.items():
    model.metadata_props.append(onnx.StringStringEntryProto(key=k, value=v))
onnx.checker.check_model(model, full_check=True)
here = os.path.dirname(os.path.abspath(__file__))
onnx.save(model, os.path.join(here, "custom_card.onnx"))

B = 4
feeds = {
    "x": rng.standard_normal((B, T, D)).astype(np.float32),
    "t": rng.integers(0, 256, B).astype(np.float32),
    "context": rng.choice([-1.0, 1.0], (B, F)).astype(np.float32),
    "cond_mask": np.array([1, 0, 1, 1], dtype=np.float32),
}
sess = ort.InferenceSession(os.path.join(here, "custom_card.onnx"), providers=["CPUExecutionProvider"])
(eps,) = sess.run(None, feeds)
io = {"inputs": {k: {"shape": list(v.shape), "data": v.flatten().tolist()} for k, v in feeds.items()},
      "outputs": {"eps": {"shape": list(eps.shape), "data": eps.flatten().tolist()}}}
with open(os.path.join(here, "custom_card.io.json"), "w") as f:
    json.dump(io, f)
print("wrote custom_card.onnx", len(nodes), "nodes; eps std", float(eps.std()))
