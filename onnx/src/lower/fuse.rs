//! Fusions. On the ONNX graph: `Mul(a, Tanh(Softplus(a)))` → `Mish(a)`. On the emitted
//! program: the exporters' GroupNorm idiom
//! `InstanceNorm(groups) → Mul(γ per channel) → Add(β per channel) [→ Mish]` becomes one
//! [`Op::GroupNorm`], which reads and writes the activation once instead of three or four times.

use std::collections::HashMap;

use dips_kernel::nn::format::{BinaryFn, Op, OpRef, Operand, UnaryFn, W};
use tract_onnx::pb;

use super::emit::Program;
use super::plan::{reads, writes};

/// Consumers of every storage (op indices), the output counting as a consumer.
fn consumers(p: &Program) -> Vec<Vec<usize>> {
    let mut c = vec![Vec::new(); p.storages.len()];
    for (i, op) in p.ops.iter().enumerate() {
        for r in reads(op) {
            c[r.off as usize].push(i);
        }
    }
    c[p.output].push(usize::MAX);
    c
}

/// The single consumer of storage `st`, if it has exactly one.
fn only(c: &[Vec<usize>], st: usize) -> Option<usize> {
    match c[st].as_slice() {
        [i] if *i != usize::MAX => Some(*i),
        _ => None,
    }
}

/// A per-channel broadcast `act ⊙ w` over per-sample `[channels, channel_len]`: returns the
/// weight, the channel length and the output storage.
fn per_channel(op: &Op, f: BinaryFn, input: usize, total: usize) -> Option<(W, usize, usize)> {
    let Op::Binary {
        a,
        b,
        y,
        f: g,
        dims,
        sa,
        sb,
    } = op
    else {
        return None;
    };
    if *g != f {
        return None;
    }
    let (act, w, sw, sx) = match (a, b) {
        (Operand::Act(x), Operand::Weight(w)) => (x, w, sb, sa),
        (Operand::Weight(w), Operand::Act(x)) if matches!(f, BinaryFn::Add | BinaryFn::Mul) => {
            (x, w, sa, sb)
        }
        _ => return None,
    };
    let [d0, d1, c, l] = *dims;
    let ok = act.off as usize == input
        && d0 == 1
        && d1 == 1
        && (c * l) as usize == total
        && *sx == [0, 0, l, 1]
        && *sw == [0, 0, 1, 0]
        && w.len == c;
    ok.then_some((*w, l as usize, y.off as usize))
}

/// Apply the GroupNorm fusion everywhere it matches.
pub(super) fn fuse_group_norm(p: &mut Program) {
    let mut removed = vec![false; p.ops.len()];
    let c = consumers(p);
    for i in 0..p.ops.len() {
        let Op::InstanceNorm {
            x,
            y,
            channels,
            len,
            eps,
            scale,
            bias,
        } = p.ops[i]
        else {
            continue;
        };
        let total = (channels * len) as usize;
        let n = y.off as usize;
        let Some(j) = only(&c, n) else { continue };
        let Some((gamma, cl, m)) = per_channel(&p.ops[j], BinaryFn::Mul, n, total) else {
            continue;
        };
        let Some(k) = only(&c, m) else { continue };
        let Some((beta, cl2, a)) = per_channel(&p.ops[k], BinaryFn::Add, m, total) else {
            continue;
        };
        if cl != cl2 || !(len as usize).is_multiple_of(cl) {
            continue;
        }
        let (mut out, mut last) = (a, None);
        if let Some(l) = only(&c, a)
            && let Op::Unary {
                f: UnaryFn::Mish,
                y,
                ..
            } = p.ops[l]
        {
            out = y.off as usize;
            last = Some(l);
        }
        // Fold the instance norm's per-group affine map into the per-channel one.
        let wv = |w: W| p.weights[w.off as usize..(w.off + w.len) as usize].to_vec();
        let (s, b, g, be) = (wv(scale), wv(bias), wv(gamma), wv(beta));
        let per_group = len as usize / cl;
        let g2: Vec<f32> = (0..g.len()).map(|ch| s[ch / per_group] * g[ch]).collect();
        let b2: Vec<f32> = (0..g.len())
            .map(|ch| b[ch / per_group] * g[ch] + be[ch])
            .collect();
        let gw = W {
            off: p.weights.len() as u32,
            len: g2.len() as u32,
        };
        p.weights.extend(g2);
        let bw = W {
            off: p.weights.len() as u32,
            len: b2.len() as u32,
        };
        p.weights.extend(b2);
        let y = dips_kernel::nn::format::Buf {
            off: out as u32,
            len: total as u32,
        };
        p.ops[i] = Op::GroupNorm {
            x,
            y,
            groups: channels,
            group_len: len,
            channel_len: cl as u32,
            eps,
            gamma: gw,
            beta: bw,
            mish: last.is_some(),
        };
        removed[j] = true;
        removed[k] = true;
        if let Some(l) = last {
            removed[l] = true;
        }
    }
    let ops = std::mem::take(&mut p.ops);
    p.ops = ops
        .into_iter()
        .zip(removed)
        .filter(|(_, r)| !r)
        .map(|(o, _)| o)
        .collect();
    debug_assert!(
        p.ops
            .iter()
            .all(|o| (writes(o).off as usize) < p.storages.len())
    );
}

/// Every weight range an op references.
fn weight_refs(op: &mut Op) -> Vec<&mut W> {
    let mut out = Vec::new();
    op.refs_mut(|r| match r {
        OpRef::Weight(w) | OpRef::ReadsOperand(Operand::Weight(w)) => out.push(w),
        _ => {}
    });
    out
}

/// Drop weights no op references any more (the γ/β folded by the GroupNorm fusion), keeping
/// shared ranges shared.
pub(super) fn compact_weights(p: &mut Program) {
    let mut moved: std::collections::HashMap<(u32, u32), W> = std::collections::HashMap::new();
    let mut out: Vec<f32> = Vec::with_capacity(p.weights.len());
    for op in &mut p.ops {
        for w in weight_refs(op) {
            let key = (w.off, w.len);
            let new = *moved.entry(key).or_insert_with(|| {
                let n = W {
                    off: out.len() as u32,
                    len: w.len,
                };
                out.extend_from_slice(&p.weights[w.off as usize..(w.off + w.len) as usize]);
                n
            });
            *w = new;
        }
    }
    p.weights = out;
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
