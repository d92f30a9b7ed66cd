//! Evaluation of the ONNX graph at a probe batch: constants are folded, activations become
//! kernel ops over per-sample shapes (storage ids stand in for arena offsets until planning).

use std::collections::HashMap;

use dips_kernel::nn::format::{BinaryFn, Buf, ConvGeom, Op, Operand, RANK, UnaryFn, W};
use dips_kernel::nn::ops::conv::{self, padded_channels};
use tract_onnx::pb;

use super::copyplan::{CopyPlan, pad_plan, slice_plan, strides, transpose_plan};
use super::fold::{
    self, axes_of, pad_params, reshape_dims, slice_params, squeeze_dims, unsqueeze_dims,
};
use super::tensors::Const;
use crate::contract::Contract;
use crate::error::{ModelError, Result};

/// A node's attributes by name.
pub(super) struct Attrs<'a>(&'a [pb::AttributeProto]);

impl<'a> Attrs<'a> {
    fn get(&self, name: &str) -> Option<&'a pb::AttributeProto> {
        self.0.iter().find(|a| a.name == name)
    }
    /// Integer attribute.
    pub(super) fn int(&self, name: &str) -> Option<i64> {
        self.get(name).map(|a| a.i)
    }
    /// Integer list attribute.
    pub(super) fn ints(&self, name: &str) -> Option<Vec<i64>> {
        self.get(name).map(|a| a.ints.clone())
    }
    /// Float attribute.
    pub(super) fn float(&self, name: &str) -> Option<f32> {
        self.get(name).map(|a| a.f)
    }
    /// Float list attribute.
    pub(super) fn floats(&self, name: &str) -> Option<Vec<f32>> {
        self.get(name).map(|a| a.floats.clone())
    }
    /// String attribute.
    pub(super) fn string(&self, name: &str) -> Option<String> {
        self.get(name)
            .map(|a| String::from_utf8_lossy(&a.s).into_owned())
    }
    /// Tensor attribute.
    pub(super) fn tensor(&self, name: &str) -> Option<&'a pb::TensorProto> {
        self.get(name).and_then(|a| a.t.as_ref())
    }
}

/// Normalize a possibly negative axis for rank `r`.
pub(super) fn norm_axis(a: i64, r: usize) -> Option<usize> {
    let v = if a < 0 { a + r as i64 } else { a };
    (0..r as i64).contains(&v).then_some(v as usize)
}

/// Numpy broadcast of two shapes.
pub(super) fn broadcast_dims(a: &[usize], b: &[usize]) -> Option<Vec<usize>> {
    let r = a.len().max(b.len());
    (0..r)
        .map(|i| {
            let x = if i + a.len() >= r {
                a[i + a.len() - r]
            } else {
                1
            };
            let y = if i + b.len() >= r {
                b[i + b.len() - r]
            } else {
                1
            };
            match (x, y) {
                (x, y) if x == y => Some(x),
                (1, y) => Some(y),
                (x, 1) => Some(x),
                _ => None,
            }
        })
        .collect()
}

fn node_name(n: &pb::NodeProto) -> String {
    if !n.name.is_empty() {
        n.name.clone()
    } else {
        n.output.first().cloned().unwrap_or_default()
    }
}

/// Rewrite exporter idioms into single ops: `Mul(a, Tanh(Softplus(a)))` → `Mish(a)`.
pub(super) fn fuse_patterns(nodes: &[pb::NodeProto]) -> Vec<pb::NodeProto> {
    let mut producer: HashMap<&str, usize> = HashMap::new();
    let mut uses: HashMap<&str, usize> = HashMap::new();
    for (i, n) in nodes.iter().enumerate() {
        for o in &n.output {
            producer.insert(o, i);
        }
        for x in &n.input {
            *uses.entry(x).or_default() += 1;
        }
    }
    let mut drop = vec![false; nodes.len()];
    let mut out: Vec<pb::NodeProto> = nodes.to_vec();
    for (i, n) in nodes.iter().enumerate() {
        if n.op_type != "Mul" || n.input.len() != 2 {
            continue;
        }
        for (a, b) in [(0, 1), (1, 0)] {
            let (a, b) = (&n.input[a], &n.input[b]);
            let Some(&ti) = producer.get(b.as_str()) else {
                continue;
            };
            let tanh = &nodes[ti];
            if tanh.op_type != "Tanh" || uses.get(b.as_str()) != Some(&1) {
                continue;
            }
            let Some(tin) = tanh.input.first() else {
                continue;
            };
            let Some(&si) = producer.get(tin.as_str()) else {
                continue;
            };
            let sp = &nodes[si];
            if sp.op_type != "Softplus"
                || uses.get(tin.as_str()) != Some(&1)
                || sp.input.first() != Some(a)
            {
                continue;
            }
            drop[ti] = true;
            drop[si] = true;
            out[i] = pb::NodeProto {
                op_type: "Mish".into(),
                input: vec![a.clone()],
                output: n.output.clone(),
                name: n.name.clone(),
                ..Default::default()
            };
            break;
        }
    }
    out.into_iter()
        .zip(drop)
        .filter(|(_, d)| !d)
        .map(|(n, _)| n)
        .collect()
}

/// A value during evaluation.
#[derive(Debug, Clone)]
enum Val {
    Const(Const),
    /// An activation: per-sample shape and storage id.
    Act {
        ps: Vec<usize>,
        st: usize,
    },
}

/// The program of one probe evaluation.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Program {
    /// Ops; every `Buf::off` is a storage id.
    pub ops: Vec<Op>,
    /// Per-sample length of each storage.
    pub storages: Vec<usize>,
    /// Packed weights.
    pub weights: Vec<f32>,
    /// Scratch the ops need.
    pub temp_len: usize,
    /// Storage of each contract input, in contract order.
    pub inputs: Vec<usize>,
    /// Storage of the output.
    pub output: usize,
}

pub(super) struct Builder {
    batch: usize,
    opset: i64,
    vals: HashMap<String, Val>,
    prog: Program,
    wcache: HashMap<String, W>,
}

type Ins = Vec<Option<Val>>;

impl Builder {
    /// Evaluate `nodes` (the graph's nodes after [`fuse_patterns`]) at `batch`.
    pub(super) fn build(
        graph: &pb::GraphProto,
        nodes: &[pb::NodeProto],
        contract: &Contract,
        opset: i64,
        batch: usize,
    ) -> Result<Program> {
        let mut b = Builder {
            batch,
            opset,
            vals: HashMap::new(),
            prog: Program {
                ops: vec![],
                storages: vec![],
                weights: vec![],
                temp_len: 0,
                inputs: vec![],
                output: 0,
            },
            wcache: HashMap::new(),
        };
        for init in &graph.initializer {
            let c = super::tensors::decode_tensor(init)?;
            b.vals.insert(init.name.clone(), Val::Const(c));
        }
        for name in contract.role.input_names() {
            let ps = contract.input_shape(name).unwrap_or_default();
            let st = b.new_storage(&ps)?;
            b.prog.inputs.push(st);
            b.vals.insert((*name).to_string(), Val::Act { ps, st });
        }
        for node in nodes {
            b.node(node)?;
        }
        let out_name = contract.role.output_name();
        match b.vals.get(out_name) {
            Some(Val::Act { ps, st }) => {
                if *ps != contract.output_shape() {
                    return Err(ModelError::Contract(format!(
                        "output {out_name} has per-sample shape {ps:?}, the contract says {:?}",
                        contract.output_shape()
                    )));
                }
                b.prog.output = *st;
            }
            Some(Val::Const(_)) => {
                return Err(ModelError::Contract(format!(
                    "output {out_name} does not depend on the inputs"
                )));
            }
            None => {
                return Err(ModelError::Contract(format!(
                    "no node computes the output {out_name}"
                )));
            }
        }
        Ok(b.prog)
    }

    fn new_storage(&mut self, ps: &[usize]) -> Result<usize> {
        let len: usize = ps.iter().product();
        if len == 0 || len > u32::MAX as usize / 4 {
            return Err(ModelError::Contract(format!(
                "activation of per-sample shape {ps:?} is empty or too large"
            )));
        }
        self.prog.storages.push(len);
        Ok(self.prog.storages.len() - 1)
    }

    fn buf(&self, st: usize) -> Buf {
        Buf {
            off: st as u32,
            len: self.prog.storages[st] as u32,
        }
    }

    fn weight(&mut self, key: Option<String>, data: &[f32]) -> W {
        if let Some(w) = key.as_ref().and_then(|k| self.wcache.get(k)) {
            return *w;
        }
        let w = W {
            off: self.prog.weights.len() as u32,
            len: data.len() as u32,
        };
        self.prog.weights.extend_from_slice(data);
        if let Some(k) = key {
            self.wcache.insert(k, w);
        }
        w
    }

    fn node(&mut self, node: &pb::NodeProto) -> Result<()> {
        let name = node_name(node);
        let err = |reason: String| ModelError::Lowering {
            op: node.op_type.clone(),
            node: name.clone(),
            reason,
        };
        if !node.domain.is_empty() && node.domain != "ai.onnx" {
            return Err(ModelError::UnsupportedOp {
                op: format!("{}:{}", node.domain, node.op_type),
                node: name,
            });
        }
        let ins: Ins =
            node.input
                .iter()
                .map(|i| {
                    if i.is_empty() {
                        Ok(None)
                    } else {
                        self.vals.get(i).cloned().map(Some).ok_or_else(|| {
                            err(format!("input {i:?} is not defined before this node"))
                        })
                    }
                })
                .collect::<Result<_>>()?;
        let attrs = Attrs(&node.attribute);
        let all_const = ins.iter().flatten().all(|v| matches!(v, Val::Const(_)));
        let outs: Vec<Val> = if node.op_type == "Shape" {
            let full = match ins.first().cloned().flatten() {
                Some(Val::Act { ps, .. }) => {
                    let mut d = vec![self.batch];
                    d.extend(ps);
                    d
                }
                Some(Val::Const(c)) => c.dims,
                None => return Err(err("Shape without input".into())),
            };
            let consts = vec![Some(Const {
                dims: full,
                data: vec![],
                float: true,
            })];
            fold::eval(node, &attrs, &consts)
                .map_err(err)?
                .into_iter()
                .map(Val::Const)
                .collect()
        } else if all_const {
            let consts: Vec<Option<Const>> = ins
                .iter()
                .map(|v| {
                    v.as_ref().and_then(|v| {
                        if let Val::Const(c) = v {
                            Some(c.clone())
                        } else {
                            None
                        }
                    })
                })
                .collect();
            match fold::eval(node, &attrs, &consts) {
                Ok(v) => v.into_iter().map(Val::Const).collect(),
                Err(reason) if reason.starts_with("no constant folding") => {
                    return Err(ModelError::UnsupportedOp {
                        op: node.op_type.clone(),
                        node: name,
                    });
                }
                Err(reason) => return Err(err(reason)),
            }
        } else {
            vec![self.act_op(node, &attrs, &ins).map_err(|e| match e {
                ActErr::Unsupported => ModelError::UnsupportedOp {
                    op: node.op_type.clone(),
                    node: name.clone(),
                },
                ActErr::Msg(m) => err(m),
                ActErr::Model(e) => e,
            })?]
        };
        for (o, v) in node.output.iter().zip(outs) {
            if !o.is_empty() {
                self.vals.insert(o.clone(), v);
            }
        }
        Ok(())
    }
}

enum ActErr {
    Unsupported,
    Msg(String),
    Model(ModelError),
}

impl From<String> for ActErr {
    fn from(s: String) -> Self {
        ActErr::Msg(s)
    }
}
impl From<&str> for ActErr {
    fn from(s: &str) -> Self {
        ActErr::Msg(s.into())
    }
}
impl From<ModelError> for ActErr {
    fn from(e: ModelError) -> Self {
        ActErr::Model(e)
    }
}

type ActResult<T> = std::result::Result<T, ActErr>;

fn pad4<T: Copy>(v: &[T], fill: T) -> ActResult<[T; RANK]> {
    if v.len() > RANK {
        return Err(format!("per-sample rank {} exceeds the kernel's {RANK}", v.len()).into());
    }
    let mut out = [fill; RANK];
    out[RANK - v.len()..].copy_from_slice(v);
    Ok(out)
}

fn u32s(v: &[usize]) -> ActResult<Vec<u32>> {
    v.iter()
        .map(|x| u32::try_from(*x).map_err(|_| ActErr::from("size exceeds u32")))
        .collect()
}

impl Builder {
    fn act(&self, v: &Option<Val>) -> ActResult<(Vec<usize>, usize)> {
        match v {
            Some(Val::Act { ps, st }) => Ok((ps.clone(), *st)),
            Some(Val::Const(_)) => Err("expected an activation, found a constant".into()),
            None => Err("missing input".into()),
        }
    }

    fn konst<'v>(&self, v: &'v Option<Val>, what: &str) -> ActResult<&'v Const> {
        match v {
            Some(Val::Const(c)) => Ok(c),
            Some(Val::Act { .. }) => Err(format!(
                "{what} must be a constant (weights computed from inputs are not supported)"
            )
            .into()),
            None => Err(format!("missing {what}").into()),
        }
    }

    fn konsts(ins: &Ins) -> Vec<Option<Const>> {
        ins.iter()
            .map(|v| match v {
                Some(Val::Const(c)) => Some(c.clone()),
                _ => None,
            })
            .collect()
    }

    fn out(&mut self, ps: Vec<usize>) -> ActResult<(Val, usize)> {
        let st = self.new_storage(&ps)?;
        Ok((Val::Act { ps, st }, st))
    }

    fn push(&mut self, op: Op) {
        let t = dips_kernel::nn::model::op_temp_len(&op).unwrap_or(usize::MAX);
        self.prog.temp_len = self.prog.temp_len.max(t);
        self.prog.ops.push(op);
    }

    /// Per-sample axis of a full-shape axis; the batch axis is refused.
    fn sample_axis(&self, a: i64, full_rank: usize) -> ActResult<usize> {
        match norm_axis(a, full_rank) {
            Some(0) => Err("the operation acts on the batch axis".into()),
            Some(v) => Ok(v - 1),
            None => Err(format!("axis {a} out of range for rank {full_rank}").into()),
        }
    }

    fn alias(&self, st: usize, ps: Vec<usize>, old: &[usize]) -> ActResult<Val> {
        if ps.iter().product::<usize>() != old.iter().product::<usize>() {
            return Err(
                format!("reshape from {old:?} to {ps:?} changes the per-sample size").into(),
            );
        }
        Ok(Val::Act { ps, st })
    }

    fn act_op(&mut self, node: &pb::NodeProto, attrs: &Attrs, ins: &Ins) -> ActResult<Val> {
        let op = node.op_type.as_str();
        match op {
            "Identity" | "Dropout" => {
                let (ps, st) = self.act(&ins[0])?;
                Ok(Val::Act { ps, st })
            }
            "Cast" => {
                let (ps, st) = self.act(&ins[0])?;
                match attrs.int("to") {
                    Some(1) => Ok(Val::Act { ps, st }),
                    to => {
                        Err(format!("cast of an activation to type {to:?} (only float32)").into())
                    }
                }
            }
            "Reshape" => {
                let (ps, st) = self.act(&ins[0])?;
                let target = self.konst(&ins[1], "the target shape")?.ints();
                let mut full = vec![self.batch];
                full.extend(&ps);
                let out = reshape_dims(&full, &target, attrs.int("allowzero") == Some(1))?;
                if out.first() != Some(&self.batch) {
                    return Err(format!("reshape to {out:?} moves the batch axis").into());
                }
                self.alias(st, out[1..].to_vec(), &ps)
            }
            "Flatten" => {
                let (ps, st) = self.act(&ins[0])?;
                if attrs.int("axis").unwrap_or(1) != 1 {
                    return Err("Flatten with axis other than 1 mixes the batch".into());
                }
                let n = ps.iter().product();
                self.alias(st, vec![n], &ps)
            }
            "Unsqueeze" => {
                let (ps, st) = self.act(&ins[0])?;
                let axes = axes_of(attrs, &Self::konsts(ins), 1).ok_or("Unsqueeze without axes")?;
                let mut full = vec![self.batch];
                full.extend(&ps);
                let out = unsqueeze_dims(&full, &axes)?;
                if out.first() != Some(&self.batch)
                    || axes.iter().any(|a| norm_axis(*a, out.len()) == Some(0))
                {
                    return Err("unsqueeze before the batch axis".into());
                }
                self.alias(st, out[1..].to_vec(), &ps)
            }
            "Squeeze" => {
                let (ps, st) = self.act(&ins[0])?;
                let axes = axes_of(attrs, &Self::konsts(ins), 1)
                    .ok_or("Squeeze needs explicit axes for an activation")?;
                let mut full = vec![self.batch];
                full.extend(&ps);
                if axes.iter().any(|a| norm_axis(*a, full.len()) == Some(0)) {
                    return Err("squeeze of the batch axis".into());
                }
                let out = squeeze_dims(&full, Some(&axes))?;
                self.alias(st, out[1..].to_vec(), &ps)
            }
            "Mish" | "Softplus" | "Tanh" | "Sigmoid" | "Sin" | "Cos" | "Exp" | "Relu" | "Neg"
            | "Sqrt" | "Reciprocal" | "Abs" | "Log" => {
                let f = match op {
                    "Mish" => UnaryFn::Mish,
                    "Softplus" => UnaryFn::Softplus,
                    "Tanh" => UnaryFn::Tanh,
                    "Sigmoid" => UnaryFn::Sigmoid,
                    "Sin" => UnaryFn::Sin,
                    "Cos" => UnaryFn::Cos,
                    "Exp" => UnaryFn::Exp,
                    "Relu" => UnaryFn::Relu,
                    "Neg" => UnaryFn::Neg,
                    "Sqrt" => UnaryFn::Sqrt,
                    "Reciprocal" => UnaryFn::Reciprocal,
                    "Abs" => UnaryFn::Abs,
                    _ => UnaryFn::Log,
                };
                let (ps, st) = self.act(&ins[0])?;
                let (v, y) = self.out(ps)?;
                let (x, y) = (self.buf(st), self.buf(y));
                self.push(Op::Unary { x, y, f });
                Ok(v)
            }
            "Add" | "Sub" | "Mul" | "Div" | "Max" | "Min" | "Pow" => {
                let f = match op {
                    "Add" => BinaryFn::Add,
                    "Sub" => BinaryFn::Sub,
                    "Mul" => BinaryFn::Mul,
                    "Div" => BinaryFn::Div,
                    "Max" => BinaryFn::Max,
                    "Min" => BinaryFn::Min,
                    _ => BinaryFn::Pow,
                };
                if ins.len() != 2 {
                    return Err("variadic form with other than two inputs".into());
                }
                self.binary(f, &ins[0], &ins[1])
            }
            "Conv" | "ConvTranspose" => self.conv(op == "ConvTranspose", attrs, ins),
            "InstanceNormalization" => {
                let (ps, st) = self.act(&ins[0])?;
                if ps.is_empty() {
                    return Err("InstanceNormalization needs [batch, channels, ...]".into());
                }
                let c = ps[0];
                let len: usize = ps[1..].iter().product();
                let scale = self.konst(&ins[1], "scale")?.floats();
                let bias = self.konst(&ins[2], "bias")?.floats();
                if scale.len() != c || bias.len() != c {
                    return Err(format!(
                        "scale/bias have {}/{} entries for {c} channels",
                        scale.len(),
                        bias.len()
                    )
                    .into());
                }
                let eps = attrs.float("epsilon").unwrap_or(1e-5);
                let scale = self.weight(Some(format!("in_scale:{}", node.input[1])), &scale);
                let bias = self.weight(Some(format!("in_bias:{}", node.input[2])), &bias);
                let (v, y) = self.out(ps)?;
                let (x, y) = (self.buf(st), self.buf(y));
                self.push(Op::InstanceNorm {
                    x,
                    y,
                    channels: c as u32,
                    len: len as u32,
                    eps,
                    scale,
                    bias,
                });
                Ok(v)
            }
            "GroupNormalization" => self.group_norm(node, attrs, ins),
            "Gemm" => {
                let (ps, st) = self.act(&ins[0])?;
                if ps.len() != 1 || attrs.int("transA").unwrap_or(0) != 0 {
                    return Err("Gemm needs A of shape [batch, K] without transA".into());
                }
                let b = self.konst(&ins[1], "B")?;
                if b.dims.len() != 2 {
                    return Err("Gemm B must be 2-D".into());
                }
                let trans_b = attrs.int("transB").unwrap_or(0) == 1;
                let (k, n) = if trans_b {
                    (b.dims[1], b.dims[0])
                } else {
                    (b.dims[0], b.dims[1])
                };
                if k != ps[0] {
                    return Err(format!("Gemm: A has {} columns, B has {k} rows", ps[0]).into());
                }
                let alpha = attrs.float("alpha").unwrap_or(1.0);
                let beta = attrs.float("beta").unwrap_or(1.0);
                let mut w = vec![0.0f32; k * n];
                for kk in 0..k {
                    for j in 0..n {
                        let v = if trans_b {
                            b.data[j * k + kk]
                        } else {
                            b.data[kk * n + j]
                        };
                        w[kk * n + j] = alpha * v as f32;
                    }
                }
                let bias = match ins.get(2).cloned().flatten() {
                    None => vec![0.0; n],
                    Some(Val::Const(c)) => {
                        let full =
                            fold::binary(&c, &Const::float(vec![n], vec![0.0; n]), true, |a, _| a)
                                .map_err(ActErr::Msg)?;
                        if full.dims != [n] {
                            return Err("Gemm C must broadcast to [N]".into());
                        }
                        full.data.iter().map(|v| beta * *v as f32).collect()
                    }
                    Some(Val::Act { .. }) => return Err("Gemm C must be a constant".into()),
                };
                self.gemm(
                    st,
                    &ps,
                    &w,
                    &bias,
                    k,
                    n,
                    vec![n],
                    format!("gemm:{}:{}", node.input[1], node.output[0]),
                )
            }
            "MatMul" => {
                let (ps, st) = self.act(&ins[0])?;
                let b = self.konst(&ins[1], "the right-hand matrix")?;
                if b.dims.len() != 2 || ps.is_empty() || ps[ps.len() - 1] != b.dims[0] {
                    return Err(format!(
                        "MatMul of {ps:?} by {:?} (only activation × 2-D constant)",
                        b.dims
                    )
                    .into());
                }
                let (k, n) = (b.dims[0], b.dims[1]);
                let w: Vec<f32> = b.floats();
                let mut out = ps[..ps.len() - 1].to_vec();
                out.push(n);
                self.gemm(
                    st,
                    &ps,
                    &w,
                    &vec![0.0; n],
                    k,
                    n,
                    out,
                    format!("matmul:{}", node.input[1]),
                )
            }
            "Transpose" => {
                let (ps, st) = self.act(&ins[0])?;
                let r = ps.len() + 1;
                let perm: Vec<usize> = attrs
                    .ints("perm")
                    .map(|p| p.iter().map(|v| *v as usize).collect())
                    .unwrap_or_else(|| (0..r).rev().collect());
                if perm.len() != r || perm[0] != 0 {
                    return Err(format!("permutation {perm:?} moves the batch axis").into());
                }
                let sp: Vec<usize> = perm[1..].iter().map(|p| p.wrapping_sub(1)).collect();
                let (out, plan) = transpose_plan(&ps, &sp).ok_or("bad perm")?;
                let (v, y) = self.out(out)?;
                self.copy(Operand::Act(self.buf(st)), y, &plan)?;
                Ok(v)
            }
            "Slice" => {
                let (ps, st) = self.act(&ins[0])?;
                let (axes, starts, ends, steps) =
                    slice_params(attrs, &Self::konsts(ins), ps.len() + 1)?;
                if axes.contains(&0) {
                    return Err("slicing the batch axis".into());
                }
                let axes: Vec<usize> = axes.iter().map(|a| a - 1).collect();
                let (out, plan) =
                    slice_plan(&ps, &axes, &starts, &ends, &steps).ok_or("bad Slice")?;
                let (v, y) = self.out(out)?;
                self.copy(Operand::Act(self.buf(st)), y, &plan)?;
                Ok(v)
            }
            "Pad" => {
                let (ps, st) = self.act(&ins[0])?;
                let (pads, value) = pad_params(attrs, &Self::konsts(ins), ps.len() + 1)?;
                let r = ps.len() + 1;
                if pads[0] != 0 || pads[r] != 0 {
                    return Err("padding the batch axis".into());
                }
                let sp: Vec<i64> = pads[1..r].iter().chain(&pads[r + 1..]).copied().collect();
                let (out, plan) = pad_plan(&ps, &sp).ok_or("bad pads")?;
                let (v, y) = self.out(out)?;
                let yb = self.buf(y);
                self.push(Op::Fill {
                    y: yb,
                    value: value as f32,
                });
                self.copy(Operand::Act(self.buf(st)), y, &plan)?;
                Ok(v)
            }
            "Concat" => {
                let first = ins
                    .iter()
                    .flatten()
                    .find_map(|v| {
                        if let Val::Act { ps, .. } = v {
                            Some(ps.clone())
                        } else {
                            None
                        }
                    })
                    .ok_or("no activation")?;
                let axis = self.sample_axis(
                    attrs.int("axis").ok_or("Concat without axis")?,
                    first.len() + 1,
                )?;
                let parts: Vec<(Vec<usize>, usize)> = ins
                    .iter()
                    .map(|v| self.act(v))
                    .collect::<ActResult<_>>()
                    .map_err(|_| {
                        ActErr::from("Concat of constants with activations is not supported")
                    })?;
                let mut out = first.clone();
                out[axis] = 0;
                for (p, _) in &parts {
                    if p.len() != first.len()
                        || p.iter()
                            .enumerate()
                            .any(|(i, d)| i != axis && *d != first[i])
                    {
                        return Err(format!("Concat of {p:?} with {first:?}").into());
                    }
                    out[axis] += p[axis];
                }
                let (v, y) = self.out(out.clone())?;
                let ys = strides(&out);
                let mut at = 0;
                for (p, st) in parts {
                    let plan = CopyPlan {
                        dims: p.clone(),
                        x_off: 0,
                        xs: strides(&p).iter().map(|s| *s as isize).collect(),
                        y_off: at * ys[axis],
                        ys: ys.clone(),
                    };
                    at += p[axis];
                    self.copy(Operand::Act(self.buf(st)), y, &plan)?;
                }
                Ok(v)
            }
            "ReduceMean" => {
                let (ps, st) = self.act(&ins[0])?;
                let r = ps.len() + 1;
                let axes = match axes_of(attrs, &Self::konsts(ins), 1) {
                    Some(a) if !a.is_empty() => a,
                    _ => return Err("ReduceMean over all axes mixes the batch".into()),
                };
                let mut ax: Vec<usize> = axes
                    .iter()
                    .map(|a| self.sample_axis(*a, r))
                    .collect::<ActResult<_>>()?;
                ax.sort_unstable();
                ax.dedup();
                if ax.windows(2).any(|w| w[1] != w[0] + 1) {
                    return Err("ReduceMean over non-adjacent axes".into());
                }
                let (a0, a1) = (ax[0], ax[ax.len() - 1] + 1);
                let outer: usize = ps[..a0].iter().product();
                let len: usize = ps[a0..a1].iter().product();
                let inner: usize = ps[a1..].iter().product();
                let keep = attrs.int("keepdims").unwrap_or(1) == 1;
                let out: Vec<usize> = ps
                    .iter()
                    .enumerate()
                    .filter_map(|(i, d)| {
                        if (a0..a1).contains(&i) {
                            keep.then_some(1)
                        } else {
                            Some(*d)
                        }
                    })
                    .collect();
                let (v, y) = self.out(out)?;
                let (x, y) = (self.buf(st), self.buf(y));
                let [outer, len, inner] = [outer, len, inner].map(|v| v as u32);
                self.push(Op::ReduceMean {
                    x,
                    y,
                    outer,
                    len,
                    inner,
                });
                Ok(v)
            }
            _ => Err(ActErr::Unsupported),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn gemm(
        &mut self,
        st: usize,
        ps: &[usize],
        w: &[f32],
        bias: &[f32],
        k: usize,
        n: usize,
        out: Vec<usize>,
        key: String,
    ) -> ActResult<Val> {
        let rows = ps.iter().product::<usize>() / k;
        let w = self.weight(Some(format!("{key}:w")), w);
        let b = self.weight(Some(format!("{key}:b")), bias);
        let (v, y) = self.out(out)?;
        let (a, y) = (self.buf(st), self.buf(y));
        let [rows, k, n] = [rows, k, n].map(|v| v as u32);
        self.push(Op::Gemm {
            a,
            y,
            w,
            b,
            rows,
            k,
            n,
        });
        Ok(v)
    }

    fn copy(&mut self, x: Operand, y: usize, plan: &CopyPlan) -> ActResult<()> {
        let dims = pad4(&u32s(&plan.dims)?, 1)?;
        let xs = pad4(
            &plan
                .xs
                .iter()
                .map(|s| i32::try_from(*s).map_err(|_| ActErr::from("stride exceeds i32")))
                .collect::<ActResult<Vec<_>>>()?,
            0,
        )?;
        let ys = pad4(&u32s(&plan.ys)?, 0)?;
        let x_off = u32::try_from(plan.x_off).map_err(|_| ActErr::from("negative copy offset"))?;
        let y_off = plan.y_off as u32;
        let yb = self.buf(y);
        self.push(Op::Copy {
            x,
            y: yb,
            dims,
            x_off,
            xs,
            y_off,
            ys,
        });
        Ok(())
    }

    /// Broadcast binary op with at least one activation.
    fn binary(&mut self, f: BinaryFn, a: &Option<Val>, b: &Option<Val>) -> ActResult<Val> {
        let full = |v: &Option<Val>| -> ActResult<Vec<usize>> {
            Ok(match v {
                Some(Val::Act { ps, .. }) => {
                    let mut d = vec![self.batch];
                    d.extend(ps);
                    d
                }
                Some(Val::Const(c)) => c.dims.clone(),
                None => return Err("missing operand".into()),
            })
        };
        let (fa, fb) = (full(a)?, full(b)?);
        let out = broadcast_dims(&fa, &fb)
            .ok_or_else(|| format!("shapes {fa:?} and {fb:?} do not broadcast"))?;
        let r = out.len();
        let ops_ = out[1..].to_vec();
        let mut operand = |v: &Option<Val>, fd: &[usize]| -> ActResult<(Operand, [u32; RANK])> {
            // Per-sample dims of the operand aligned to the output's per-sample rank.
            let aligned: Vec<usize> = (0..r)
                .map(|i| {
                    if i + fd.len() >= r {
                        fd[i + fd.len() - r]
                    } else {
                        1
                    }
                })
                .collect();
            let per = &aligned[1..];
            let st = strides(per);
            let strides_: Vec<u32> = per
                .iter()
                .zip(&st)
                .zip(&ops_)
                .map(|((d, s), o)| if *d == 1 && *o != 1 { 0 } else { *s as u32 })
                .collect();
            let s4 = pad4(&strides_, 0)?;
            match v {
                Some(Val::Act { st, .. }) => {
                    if fd.len() != r {
                        return Err("an activation broadcast along the batch axis".into());
                    }
                    Ok((Operand::Act(self.buf(*st)), s4))
                }
                Some(Val::Const(c)) => {
                    if aligned[0] != 1 {
                        return Err("a constant varies along the batch axis".into());
                    }
                    let w = self.weight(None, &c.floats());
                    Ok((Operand::Weight(w), s4))
                }
                None => Err("missing operand".into()),
            }
        };
        let (oa, sa) = operand(a, &fa)?;
        let (ob, sb) = operand(b, &fb)?;
        if out[0] != self.batch {
            return Err("result does not keep the batch axis".into());
        }
        let dims = pad4(&u32s(&ops_)?, 1)?;
        let (v, y) = self.out(ops_)?;
        let yb = self.buf(y);
        self.push(Op::Binary {
            a: oa,
            b: ob,
            y: yb,
            f,
            dims,
            sa,
            sb,
        });
        Ok(v)
    }

    fn conv(&mut self, transposed: bool, attrs: &Attrs, ins: &Ins) -> ActResult<Val> {
        let (ps, st) = self.act(&ins[0])?;
        if ps.len() != 2 {
            return Err(format!(
                "only 1-D convolutions ([batch, channels, length]) are supported, input is {ps:?}"
            )
            .into());
        }
        if attrs.int("group").unwrap_or(1) != 1 {
            return Err("grouped convolutions are not supported".into());
        }
        let auto_pad = attrs.string("auto_pad").unwrap_or_default();
        if !(auto_pad.is_empty() || auto_pad == "NOTSET" || auto_pad == "VALID") {
            return Err(format!("auto_pad {auto_pad} is not supported").into());
        }
        if attrs.get("output_shape").is_some() {
            return Err("ConvTranspose output_shape is not supported".into());
        }
        let w = self.konst(&ins[1], "the kernel")?.clone();
        if w.dims.len() != 3 {
            return Err("the kernel must be 3-D".into());
        }
        let (cin, lin) = (ps[0], ps[1]);
        let (cout, k) = if transposed {
            (w.dims[1], w.dims[2])
        } else {
            (w.dims[0], w.dims[2])
        };
        let wcin = if transposed { w.dims[0] } else { w.dims[1] };
        if wcin != cin {
            return Err(
                format!("the kernel expects {wcin} input channels, the input has {cin}").into(),
            );
        }
        let one = |name: &str, default: i64| -> ActResult<i64> {
            match attrs.ints(name) {
                Some(v) if v.len() == 1 => Ok(v[0]),
                Some(v) => Err(format!("{name} {v:?} is not 1-D").into()),
                None => Ok(default),
            }
        };
        let s = one("strides", 1)?;
        let d = one("dilations", 1)?;
        let pads = attrs.ints("pads").unwrap_or_else(|| vec![0, 0]);
        if pads.len() != 2 || pads.iter().any(|p| *p < 0) || s < 1 || d < 1 {
            return Err(format!("pads {pads:?}, stride {s}, dilation {d} not supported").into());
        }
        if let Some(kk) = attrs.ints("kernel_shape")
            && kk != [k as i64]
        {
            return Err("kernel_shape disagrees with the kernel".into());
        }
        let (s, d, pb, pe) = (s as usize, d as usize, pads[0] as usize, pads[1] as usize);
        let lout = if transposed {
            let op = one("output_padding", 0)? as usize;
            ((lin - 1) * s + op + (k - 1) * d + 1).checked_sub(pb + pe)
        } else {
            (lin + pb + pe)
                .checked_sub(d * (k - 1) + 1)
                .map(|v| v / s + 1)
        }
        .filter(|v| *v > 0)
        .ok_or("the convolution output is empty")?;
        let coutp = padded_channels(cout);
        let wf = w.floats();
        let mut packed = vec![0.0f32; cin * k * coutp];
        let res = if transposed {
            conv::pack_conv_transpose_kernel(&wf, cin, cout, k, coutp, &mut packed)
        } else {
            conv::pack_conv_kernel(&wf, cout, cin, k, coutp, &mut packed)
        };
        res.map_err(|_| ActErr::from("kernel packing failed"))?;
        let mut bias = match ins.get(2).cloned().flatten() {
            None => vec![0.0; cout],
            Some(Val::Const(c)) if c.len() == cout => c.floats(),
            Some(_) => return Err("the bias must be a constant of cout entries".into()),
        };
        bias.resize(coutp, 0.0);
        let wk = self.weight(None, &packed);
        let bk = self.weight(None, &bias);
        let g = ConvGeom {
            cin: cin as u32,
            cout: cout as u32,
            cout_padded: coutp as u32,
            lin: lin as u32,
            lout: lout as u32,
            k: k as u32,
            stride: s as u32,
            dilation: d as u32,
            pad_begin: pb as u32,
        };
        let (v, y) = self.out(vec![cout, lout])?;
        let (x, y) = (self.buf(st), self.buf(y));
        self.push(if transposed {
            Op::ConvTranspose1d {
                x,
                y,
                w: wk,
                b: bk,
                g,
            }
        } else {
            Op::Conv1d {
                x,
                y,
                w: wk,
                b: bk,
                g,
            }
        });
        Ok(v)
    }

    /// ONNX GroupNormalization: normalize `num_groups` groups, then scale/shift per channel
    /// (opset ≥ 21) or per group (opset 18, as tract and the older spec read it).
    fn group_norm(&mut self, node: &pb::NodeProto, attrs: &Attrs, ins: &Ins) -> ActResult<Val> {
        let (ps, st) = self.act(&ins[0])?;
        let groups = attrs
            .int("num_groups")
            .ok_or("GroupNormalization without num_groups")? as usize;
        if ps.is_empty() || groups == 0 || ps[0] % groups != 0 {
            return Err(format!("{groups} groups for shape {ps:?}").into());
        }
        let c = ps[0];
        let len: usize = ps.iter().product::<usize>() / groups;
        let eps = attrs.float("epsilon").unwrap_or(1e-5);
        let scale = self.konst(&ins[1], "scale")?.floats();
        let bias = self.konst(&ins[2], "bias")?.floats();
        let per_channel = self.opset >= 21;
        let want = if per_channel { c } else { groups };
        if scale.len() != want || bias.len() != want {
            return Err(format!("scale/bias need {want} entries").into());
        }
        let (ones, zeros) = (vec![1.0; groups], vec![0.0; groups]);
        let sc = self.weight(None, &ones);
        let bi = self.weight(None, &zeros);
        let (_, n) = self.out(ps.clone())?;
        let (xb, nb) = (self.buf(st), self.buf(n));
        self.push(Op::InstanceNorm {
            x: xb,
            y: nb,
            channels: groups as u32,
            len: len as u32,
            eps,
            scale: sc,
            bias: bi,
        });
        let expand = |v: &[f32]| -> Vec<f32> {
            (0..c)
                .map(|ch| {
                    if per_channel {
                        v[ch]
                    } else {
                        v[ch / (c / groups)]
                    }
                })
                .collect()
        };
        let mut cshape = vec![c];
        cshape.extend(std::iter::repeat_n(1, ps.len() - 1));
        let s_const = Some(Val::Const(Const::float(
            cshape.clone(),
            expand(&scale).iter().map(|v| *v as f64).collect(),
        )));
        let b_const = Some(Val::Const(Const::float(
            cshape,
            expand(&bias).iter().map(|v| *v as f64).collect(),
        )));
        let _ = node;
        let scaled = self.binary(
            BinaryFn::Mul,
            &Some(Val::Act {
                ps: ps.clone(),
                st: n,
            }),
            &s_const,
        )?;
        self.binary(BinaryFn::Add, &Some(scaled), &b_const)
    }
}
