//! Evaluation of the ONNX graph at a probe batch: constants are folded, activations become
//! kernel ops over per-sample shapes (storage ids stand in for arena offsets until planning).

use std::collections::HashMap;

use dips_kernel::nn::format::{BinaryFn, Buf, Op, Operand, RANK, UnaryFn, W};
use tract_onnx::pb;

use super::attrs::{Attrs, node_name, norm_axis};
use super::copyplan::{CopyPlan, pad_plan, slice_plan, strides, transpose_plan};
use super::fold::{
    self, axes_of, pad_params, reshape_dims, slice_params, squeeze_dims, unsqueeze_dims,
};
use super::tensors::Const;
use crate::contract::Contract;
use crate::error::{ModelError, Result};

mod ops;

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
}
