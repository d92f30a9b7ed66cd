//! Decoding, validation, weight installation and execution of a lowered model blob.
//!
//! Caller memory layout (`f32`): `[weights | op scratch | arena]`. The arena holds every
//! activation; a value of `len` floats per sample at per-sample offset `off` occupies
//! `[off·max_batch, (off+len)·max_batch)`, where `max_batch` is what the memory holds.

use super::format::{Body, Buf, CHECKSUM, Header, MAGIC, MAX_INPUTS, Op, OpRef, Operand, W};
use super::ops::{self, OpSizeError};
use super::{NnError, OpFault};
use crate::engine::ModelDims;

/// Decoded facts of a validated blob, free of borrows so a host can keep it next to the bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelInfo {
    /// 0 denoiser, 1 discriminator.
    pub role: u8,
    /// The contract dimensions.
    pub dims: ModelDims,
    /// Contract inputs in the arena.
    pub inputs: [Buf; MAX_INPUTS],
    /// How many inputs are used.
    pub n_inputs: usize,
    /// Contract output in the arena.
    pub output: Buf,
    /// Arena floats per sample.
    pub arena_per_sample: usize,
    /// Batch-independent op scratch floats.
    pub temp_len: usize,
    /// Weight floats.
    pub n_weights: usize,
    /// Ops in the stream.
    pub n_ops: usize,
    /// Normalization mean in the weights.
    pub norm_mean: W,
    /// Normalization std in the weights.
    pub norm_std: W,
    /// Where the model measures the object from (`dips.object_frame`).
    pub object_frame: crate::engine::ObjectFrame,
    ops_range: (usize, usize),
    weights_range: (usize, usize),
}

/// Check magic, version and checksum, then decode the body (borrowing from `blob`).
pub fn decode(blob: &[u8]) -> Result<Body<'_>, NnError> {
    if blob.len() < MAGIC.len() + 1 + 4 {
        return Err(NnError::Truncated);
    }
    let (header, _) = postcard::take_from_bytes::<Header>(blob).map_err(|_| NnError::Truncated)?;
    if header.magic != MAGIC {
        return Err(NnError::BadMagic);
    }
    if header.version != super::format::BLOB_VERSION {
        return Err(NnError::UnsupportedVersion {
            found: header.version,
            supported: super::format::BLOB_VERSION,
        });
    }
    let (payload, tail) = blob.split_at(blob.len() - 4);
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    let computed = CHECKSUM.checksum(payload);
    if stored != computed {
        return Err(NnError::ChecksumMismatch { stored, computed });
    }
    let (_, body_bytes) =
        postcard::take_from_bytes::<Header>(payload).map_err(|_| NnError::Decode)?;
    let (body, rest) =
        postcard::take_from_bytes::<Body<'_>>(body_bytes).map_err(|_| NnError::Decode)?;
    if !rest.is_empty() {
        return Err(NnError::Decode);
    }
    Ok(body)
}

fn offset_in(blob: &[u8], part: &[u8]) -> (usize, usize) {
    let start = (part.as_ptr() as usize).wrapping_sub(blob.as_ptr() as usize);
    (start, start + part.len())
}

fn buf_ok(b: &Buf, arena: usize) -> bool {
    (b.off as usize)
        .checked_add(b.len as usize)
        .is_some_and(|e| e <= arena)
}

fn w_ok(w: &W, n: usize) -> bool {
    (w.off as usize)
        .checked_add(w.len as usize)
        .is_some_and(|e| e <= n)
}

fn disjoint(a: &Buf, b: &Buf) -> bool {
    a.off as usize + a.len as usize <= b.off as usize
        || b.off as usize + b.len as usize <= a.off as usize
}

fn operand_ok(o: &Operand, arena: usize, n: usize, y: &Buf) -> bool {
    match o {
        Operand::Act(b) => buf_ok(b, arena) && disjoint(b, y),
        Operand::Weight(w) => w_ok(w, n),
    }
}

/// Scratch an op needs besides the arena.
pub fn op_temp_len(op: &Op) -> Result<usize, OpSizeError> {
    match op {
        Op::Conv1d { g, .. } => ops::conv::conv1d_temp_len(g),
        Op::ConvTranspose1d { g, .. } => ops::conv::conv_transpose1d_temp_len(g),
        _ => Ok(0),
    }
}

fn op_refs_ok(op: &Op, arena: usize, n: usize) -> bool {
    let y = op.output();
    let mut ok = buf_ok(&y, arena);
    op.refs(|r| {
        ok &= match r {
            OpRef::Reads(x) => buf_ok(x, arena) && disjoint(x, &y),
            OpRef::ReadsOperand(o) => operand_ok(o, arena, n, &y),
            OpRef::Writes(_) => true,
            OpRef::Weight(w) => w_ok(w, n),
        };
    });
    ok
}

/// Decode and validate a blob: header, checksum, metadata, input/output layout and every op's
/// references and scratch needs.
pub fn parse(blob: &[u8]) -> Result<ModelInfo, NnError> {
    let body = decode(blob)?;
    let m = &body.meta;
    let n_inputs = body.n_inputs as usize;
    let want_inputs = match m.role {
        0 => 4,
        1 => 2,
        _ => return Err(NnError::BadLayout),
    };
    if n_inputs != want_inputs || m.contract != 1 {
        return Err(NnError::BadLayout);
    }
    let object_frame =
        crate::engine::ObjectFrame::from_code(m.object_frame).ok_or(NnError::BadLayout)?;
    let n_weights = body.n_weights as usize;
    if body.weights.len() != n_weights.checked_mul(4).ok_or(NnError::BadLayout)? {
        return Err(NnError::BadLayout);
    }
    let arena = body.arena_per_sample as usize;
    let d = (m.state_dim as usize)
        .checked_add(m.action_dim as usize)
        .ok_or(NnError::BadLayout)?;
    let td = (m.horizon as usize)
        .checked_mul(d)
        .ok_or(NnError::BadLayout)?;
    let in_lens: &[usize] = if m.role == 0 {
        &[td, 1, m.fingers as usize, 1]
    } else {
        &[td, m.fingers as usize]
    };
    for (b, want) in body.inputs.iter().zip(in_lens) {
        if !buf_ok(b, arena) || b.len as usize != *want {
            return Err(NnError::BadLayout);
        }
    }
    let out_len = if m.role == 0 { td } else { 1 };
    if !buf_ok(&body.output, arena) || body.output.len as usize != out_len || arena == 0 {
        return Err(NnError::BadLayout);
    }
    for w in [&m.norm_mean, &m.norm_std] {
        if !w_ok(w, n_weights) || w.len as usize != d {
            return Err(NnError::BadLayout);
        }
    }
    let temp_len = body.temp_len as usize;
    let mut rest = body.ops;
    let mut count = 0usize;
    while !rest.is_empty() {
        let (op, r) = postcard::take_from_bytes::<Op>(rest).map_err(|_| NnError::Decode)?;
        rest = r;
        let index = count as u32;
        if !op_temp_len(&op).is_ok_and(|t| t <= temp_len) {
            return Err(NnError::BadOp {
                index,
                cause: OpFault::Scratch,
            });
        }
        if !op_refs_ok(&op, arena, n_weights) {
            return Err(NnError::BadOp {
                index,
                cause: OpFault::References,
            });
        }
        count += 1;
    }
    if count != body.n_ops as usize {
        return Err(NnError::Decode);
    }
    Ok(ModelInfo {
        role: m.role,
        dims: ModelDims {
            horizon: m.horizon as usize,
            state_dim: m.state_dim as usize,
            action_dim: m.action_dim as usize,
            fingers: m.fingers as usize,
            diffusion_steps: m.diffusion_steps as usize,
        },
        inputs: body.inputs,
        n_inputs,
        output: body.output,
        arena_per_sample: arena,
        temp_len,
        n_weights,
        n_ops: count,
        norm_mean: m.norm_mean,
        norm_std: m.norm_std,
        object_frame,
        ops_range: offset_in(blob, body.ops),
        weights_range: offset_in(blob, body.weights),
    })
}

impl ModelInfo {
    /// Floats of caller memory needed to run batches of up to `max_batch`.
    pub fn memory_len(&self, max_batch: usize) -> Option<usize> {
        self.arena_per_sample
            .checked_mul(max_batch)?
            .checked_add(self.n_weights)?
            .checked_add(self.temp_len)
    }

    /// The largest batch `mem_len` floats hold (0 when not even one sample fits).
    pub fn max_batch(&self, mem_len: usize) -> usize {
        mem_len.saturating_sub(self.n_weights + self.temp_len) / self.arena_per_sample.max(1)
    }

    /// Per-sample length of contract input `i`.
    pub fn input_len(&self, i: usize) -> usize {
        self.inputs.get(i).map_or(0, |b| b.len as usize)
    }

    /// Per-sample length of the output.
    pub fn output_len(&self) -> usize {
        self.output.len as usize
    }
}

/// Copy the weights into the front of `mem`, refusing NaN or infinity. Returns the largest
/// batch the memory holds. `blob` must be the blob `info` was parsed from.
pub fn install(info: &ModelInfo, blob: &[u8], mem: &mut [f32]) -> Result<usize, NnError> {
    let needed = info.memory_len(1).ok_or(NnError::BadLayout)?;
    if mem.len() < needed {
        return Err(NnError::MemoryTooSmall {
            needed,
            given: mem.len(),
        });
    }
    let bytes = blob
        .get(info.weights_range.0..info.weights_range.1)
        .ok_or(NnError::BadLayout)?;
    let dst = mem.get_mut(..info.n_weights).ok_or(NnError::BadLayout)?;
    if bytes.len() != dst.len() * 4 {
        return Err(NnError::BadLayout);
    }
    for (i, (d, c)) in dst.iter_mut().zip(bytes.chunks_exact(4)).enumerate() {
        let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
        if !v.is_finite() {
            return Err(NnError::NonFiniteWeight { index: i as u32 });
        }
        *d = v;
    }
    Ok(info.max_batch(mem.len()))
}

/// The arena range of `batch` samples of a value (saturating: an out-of-range value from a
/// blob that was not the parsed one yields a range the checked slicing then refuses).
fn region(b: &Buf, mb: usize, batch: usize) -> (usize, usize) {
    let s = (b.off as usize).saturating_mul(mb);
    (s, s.saturating_add((b.len as usize).saturating_mul(batch)))
}

/// Split the arena into a read-only source and the destination region.
fn split(arena: &mut [f32], x: (usize, usize), y: (usize, usize)) -> Option<(&[f32], &mut [f32])> {
    let (left, rest) = arena.split_at_mut_checked(y.0)?;
    let (mid, right) = rest.split_at_mut_checked(y.1 - y.0)?;
    let src = if x.1 <= y.0 {
        left.get(x.0..x.1)?
    } else if x.0 >= y.1 {
        right.get(x.0 - y.1..x.1 - y.1)?
    } else {
        return None;
    };
    Some((src, mid))
}

/// Two read-only sources (activations or weights) and a destination.
fn split2<'a>(
    arena: &'a mut [f32],
    weights: &'a [f32],
    a: Operand,
    b: Operand,
    (mb, batch): (usize, usize),
    y: (usize, usize),
) -> Option<([&'a [f32]; 2], &'a mut [f32])> {
    let (left, rest) = arena.split_at_mut_checked(y.0)?;
    let (mid, right) = rest.split_at_mut_checked(y.1 - y.0)?;
    let (left, right) = (&*left, &*right);
    let pick = |o: Operand| -> Option<&'a [f32]> {
        match o {
            Operand::Weight(w) => weight_slice(weights, &w),
            Operand::Act(buf) => {
                let (s, e) = region(&buf, mb, batch);
                if e <= y.0 {
                    left.get(s..e)
                } else if s >= y.1 {
                    right.get(s - y.1..e - y.1)
                } else {
                    None
                }
            }
        }
    };
    Some(([pick(a)?, pick(b)?], mid))
}

/// The floats of weight range `w`, or `None` when it lies outside `weights`.
pub fn weight_slice<'a>(weights: &'a [f32], w: &W) -> Option<&'a [f32]> {
    weights.get(w.off as usize..(w.off as usize).checked_add(w.len as usize)?)
}

/// Per-sample chunk `i` of a region (the whole slice for a weight).
fn sample<'a>(s: &'a [f32], o: &Operand, i: usize) -> Option<&'a [f32]> {
    match o {
        Operand::Weight(_) => Some(s),
        Operand::Act(b) => s.get(i * b.len as usize..(i + 1) * b.len as usize),
    }
}

/// Call `f` on each sample's input (`xl` floats of `src`) and output (`yl` floats of `dst`),
/// in sample order; an error as soon as a slice is out of range or `f` fails.
fn per_sample(
    src: &[f32],
    dst: &mut [f32],
    batch: usize,
    (xl, yl): (usize, usize),
    mut f: impl FnMut(&[f32], &mut [f32]) -> Result<(), OpSizeError>,
) -> Result<(), OpFault> {
    for i in 0..batch {
        let xs = src.get(i * xl..(i + 1) * xl).ok_or(OpFault::Operand)?;
        let ys = dst.get_mut(i * yl..(i + 1) * yl).ok_or(OpFault::Operand)?;
        f(xs, ys).map_err(|_| OpFault::Sizes)?;
    }
    Ok(())
}

fn exec(
    op: &Op,
    weights: &[f32],
    temp: &mut [f32],
    arena: &mut [f32],
    mb: usize,
    batch: usize,
) -> Result<(), OpFault> {
    let r = |b: &Buf| region(b, mb, batch);
    match op {
        Op::Conv1d { x, y, w, b, g } | Op::ConvTranspose1d { x, y, w, b, g } => {
            let (src, dst) = split(arena, r(x), r(y)).ok_or(OpFault::Operand)?;
            let (w, b) = (
                weight_slice(weights, w).ok_or(OpFault::Operand)?,
                weight_slice(weights, b).ok_or(OpFault::Operand)?,
            );
            let transposed = matches!(op, Op::ConvTranspose1d { .. });
            per_sample(
                src,
                dst,
                batch,
                (x.len as usize, y.len as usize),
                |xs, ys| {
                    if transposed {
                        ops::conv::conv_transpose1d(g, xs, ys, w, b, temp)
                    } else {
                        ops::conv::conv1d(g, xs, ys, w, b, temp)
                    }
                },
            )?;
        }
        Op::InstanceNorm {
            x,
            y,
            len,
            eps,
            scale,
            bias,
            ..
        } => {
            let (src, dst) = split(arena, r(x), r(y)).ok_or(OpFault::Operand)?;
            let (sc, bi) = (
                weight_slice(weights, scale).ok_or(OpFault::Operand)?,
                weight_slice(weights, bias).ok_or(OpFault::Operand)?,
            );
            let l = x.len as usize;
            per_sample(src, dst, batch, (l, l), |xs, ys| {
                ops::norm::instance_norm(xs, ys, *len as usize, *eps, sc, bi)
            })?;
        }
        Op::GroupNorm {
            x,
            y,
            group_len,
            channel_len,
            eps,
            gamma,
            beta,
            mish,
            ..
        } => {
            let (src, dst) = split(arena, r(x), r(y)).ok_or(OpFault::Operand)?;
            let (ga, be) = (
                weight_slice(weights, gamma).ok_or(OpFault::Operand)?,
                weight_slice(weights, beta).ok_or(OpFault::Operand)?,
            );
            let l = x.len as usize;
            per_sample(src, dst, batch, (l, l), |xs, ys| {
                ops::norm::group_norm(
                    xs,
                    ys,
                    *group_len as usize,
                    *channel_len as usize,
                    *eps,
                    ga,
                    be,
                    *mish,
                )
            })?;
        }
        Op::Unary { x, y, f } => {
            let (src, dst) = split(arena, r(x), r(y)).ok_or(OpFault::Operand)?;
            ops::elementwise::unary(*f, src, dst).map_err(|_| OpFault::Sizes)?;
        }
        Op::Binary {
            a,
            b,
            y,
            f,
            dims,
            sa,
            sb,
        } => {
            let ([sa_, sb_], dst) =
                split2(arena, weights, *a, *b, (mb, batch), r(y)).ok_or(OpFault::Operand)?;
            let yl = y.len as usize;
            for i in 0..batch {
                let ys = dst.get_mut(i * yl..(i + 1) * yl).ok_or(OpFault::Operand)?;
                ops::elementwise::binary(
                    *f,
                    sample(sa_, a, i).ok_or(OpFault::Operand)?,
                    sample(sb_, b, i).ok_or(OpFault::Operand)?,
                    ys,
                    dims,
                    sa,
                    sb,
                )
                .map_err(|_| OpFault::Sizes)?;
            }
        }
        Op::Gemm {
            a, y, w, b, k, n, ..
        } => {
            let (src, dst) = split(arena, r(a), r(y)).ok_or(OpFault::Operand)?;
            ops::gemm::gemm(
                src,
                weight_slice(weights, w).ok_or(OpFault::Operand)?,
                weight_slice(weights, b).ok_or(OpFault::Operand)?,
                dst,
                *k as usize,
                *n as usize,
            )
            .map_err(|_| OpFault::Sizes)?;
        }
        Op::Copy {
            x,
            y,
            dims,
            x_off,
            xs,
            y_off,
            ys,
        } => {
            let dummy = Operand::Weight(W { off: 0, len: 0 });
            let ([src, _], dst) =
                split2(arena, weights, *x, dummy, (mb, batch), r(y)).ok_or(OpFault::Operand)?;
            let yl = y.len as usize;
            for i in 0..batch {
                let yd = dst.get_mut(i * yl..(i + 1) * yl).ok_or(OpFault::Operand)?;
                ops::layout::strided_copy(
                    sample(src, x, i).ok_or(OpFault::Operand)?,
                    yd,
                    dims,
                    *x_off as usize,
                    xs,
                    *y_off as usize,
                    ys,
                )
                .map_err(|_| OpFault::Sizes)?;
            }
        }
        Op::Fill { y, value } => {
            let (s, e) = r(y);
            arena.get_mut(s..e).ok_or(OpFault::Operand)?.fill(*value);
        }
        Op::ReduceMean {
            x,
            y,
            outer,
            len,
            inner,
        } => {
            let (src, dst) = split(arena, r(x), r(y)).ok_or(OpFault::Operand)?;
            per_sample(
                src,
                dst,
                batch,
                (x.len as usize, y.len as usize),
                |xs, ys| {
                    ops::norm::reduce_mean(xs, ys, *outer as usize, *len as usize, *inner as usize)
                },
            )?;
        }
    }
    Ok(())
}

/// Run the model on `batch` samples. `mem` is memory that [`install`] filled; `inputs` are the
/// contract inputs in contract order (`batch × input_len(i)` floats each); `output` receives
/// `batch × output_len()` floats.
pub fn run(
    info: &ModelInfo,
    blob: &[u8],
    mem: &mut [f32],
    batch: usize,
    inputs: &[&[f32]],
    output: &mut [f32],
) -> Result<(), NnError> {
    let mb = info.max_batch(mem.len());
    if batch == 0 || batch > mb {
        return Err(NnError::BadBatch { batch, max: mb });
    }
    if inputs.len() != info.n_inputs {
        return Err(NnError::BadLength {
            which: MAX_INPUTS as u8,
            given: inputs.len(),
            expected: info.n_inputs,
        });
    }
    let (weights, rest) = mem.split_at_mut(info.n_weights);
    let (temp, arena) = rest.split_at_mut(info.temp_len);
    let weights = &*weights;
    for (i, (data, buf)) in inputs.iter().zip(&info.inputs).enumerate() {
        let (s, e) = region(buf, mb, batch);
        if data.len() != e - s {
            return Err(NnError::BadLength {
                which: i as u8,
                given: data.len(),
                expected: e - s,
            });
        }
        arena
            .get_mut(s..e)
            .ok_or(NnError::BadLayout)?
            .copy_from_slice(data);
    }
    let (os, oe) = region(&info.output, mb, batch);
    if output.len() != oe - os {
        return Err(NnError::BadLength {
            which: MAX_INPUTS as u8,
            given: output.len(),
            expected: oe - os,
        });
    }
    let mut ops_bytes = blob
        .get(info.ops_range.0..info.ops_range.1)
        .ok_or(NnError::BadLayout)?;
    let mut index = 0u32;
    while !ops_bytes.is_empty() {
        let (op, r) = postcard::take_from_bytes::<Op>(ops_bytes).map_err(|_| NnError::Decode)?;
        ops_bytes = r;
        exec(&op, weights, temp, arena, mb, batch)
            .map_err(|cause| NnError::BadOp { index, cause })?;
        index += 1;
    }
    output.copy_from_slice(arena.get(os..oe).ok_or(NnError::BadLayout)?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::format::{BLOB_VERSION, BinaryFn, Meta, UnaryFn};
    use std::vec;
    use std::vec::Vec;

    fn enc<T: serde::Serialize>(v: &T) -> Vec<u8> {
        let mut out = vec![0u8; 4096];
        let n = postcard::to_slice(v, &mut out).unwrap().len();
        out.truncate(n);
        out
    }

    const fn buf(off: u32, len: u32) -> Buf {
        Buf { off, len }
    }

    /// A hand-written discriminator: `p = σ(x·w + b + context)` with T = 2, D = 2, F = 1.
    fn blob(ops: &[Op]) -> Vec<u8> {
        let mut op_bytes = Vec::new();
        for op in ops {
            op_bytes.extend(enc(op));
        }
        let weights: Vec<f32> = vec![0.5, -1.0, 0.25, 2.0, 0.1, 0.0, 0.0, 1.0, 1.0];
        let wbytes: Vec<u8> = weights.iter().flat_map(|w| w.to_le_bytes()).collect();
        let body = Body {
            meta: Meta {
                contract: 1,
                role: 1,
                task: "test",
                horizon: 2,
                state_dim: 1,
                action_dim: 1,
                fingers: 1,
                diffusion_steps: 0,
                beta_schedule: "cosine",
                prediction: "epsilon",
                columns_json: "[\"a\",\"b\"]",
                norm_mean: W { off: 5, len: 2 },
                norm_std: W { off: 7, len: 2 },
                object_frame: 0,
            },
            inputs: [buf(0, 4), buf(4, 1), buf(0, 0), buf(0, 0)],
            n_inputs: 2,
            output: buf(7, 1),
            arena_per_sample: 8,
            temp_len: 0,
            n_ops: ops.len() as u32,
            ops: &op_bytes,
            n_weights: weights.len() as u32,
            weights: &wbytes,
        };
        let mut b = enc(&Header {
            magic: MAGIC,
            version: BLOB_VERSION,
        });
        b.extend(enc(&body));
        let crc = CHECKSUM.checksum(&b);
        b.extend(crc.to_le_bytes());
        b
    }

    fn program() -> [Op; 3] {
        [
            Op::Gemm {
                a: buf(0, 4),
                y: buf(5, 1),
                w: W { off: 0, len: 4 },
                b: W { off: 4, len: 1 },
                rows: 1,
                k: 4,
                n: 1,
            },
            Op::Binary {
                a: Operand::Act(buf(5, 1)),
                b: Operand::Act(buf(4, 1)),
                y: buf(6, 1),
                f: BinaryFn::Add,
                dims: [1, 1, 1, 1],
                sa: [0, 0, 0, 1],
                sb: [0, 0, 0, 1],
            },
            Op::Unary {
                x: buf(6, 1),
                y: buf(7, 1),
                f: UnaryFn::Sigmoid,
            },
        ]
    }

    #[test]
    fn runs_a_hand_written_program_at_several_batches() {
        let b = blob(&program());
        let info = parse(&b).unwrap();
        assert_eq!(
            (info.n_ops, info.arena_per_sample, info.n_weights),
            (3, 8, 9)
        );
        let mut mem = vec![0.0; info.memory_len(3).unwrap()];
        assert_eq!(install(&info, &b, &mut mem).unwrap(), 3);
        let x = [1.0, 2.0, 3.0, 4.0, -1.0, 0.0, 0.5, 0.25, 0.0, 0.0, 0.0, 0.0];
        let ctx = [0.5, -0.5, 3.0];
        let w = [0.5f32, -1.0, 0.25, 2.0];
        let want: Vec<f32> = (0..3)
            .map(|i| {
                let z: f32 = (0..4).map(|j| x[i * 4 + j] * w[j]).sum::<f32>() + 0.1 + ctx[i];
                1.0 / (1.0 + (-z).exp())
            })
            .collect();
        let mut out = [0.0; 3];
        run(&info, &b, &mut mem, 3, &[&x, &ctx], &mut out).unwrap();
        for (g, w) in out.iter().zip(&want) {
            assert!((g - w).abs() < 1e-6, "{g} vs {w}");
        }
        let mut one = [0.0; 1];
        run(&info, &b, &mut mem, 1, &[&x[4..8], &ctx[1..2]], &mut one).unwrap();
        assert!((one[0] - want[1]).abs() < 1e-6);
        assert_eq!(
            run(&info, &b, &mut mem, 4, &[&x, &ctx], &mut out),
            Err(NnError::BadBatch { batch: 4, max: 3 })
        );
    }

    #[test]
    fn out_of_range_or_aliased_ops_are_refused_at_parse() {
        // The test program with op `index` replaced.
        let with = |index: usize, op: Op| {
            let mut p = program();
            p[index] = op;
            blob(&p)
        };
        let tanh = |x, y| Op::Unary {
            x,
            y,
            f: UnaryFn::Tanh,
        };
        let gemm = |w_off, k| Op::Gemm {
            a: buf(0, 4),
            y: buf(5, 1),
            w: W { off: w_off, len: 4 },
            b: W { off: 4, len: 1 },
            rows: 1,
            k,
            n: 1,
        };
        let out_of_range = with(2, tanh(buf(6, 1), buf(8, 1)));
        assert_eq!(
            parse(&out_of_range),
            Err(NnError::BadOp {
                index: 2,
                cause: OpFault::References
            })
        );
        let weights_out_of_range = with(0, gemm(6, 4));
        assert_eq!(
            parse(&weights_out_of_range),
            Err(NnError::BadOp {
                index: 0,
                cause: OpFault::References
            })
        );
        let aliased = with(2, tanh(buf(6, 1), buf(6, 1)));
        assert_eq!(
            parse(&aliased),
            Err(NnError::BadOp {
                index: 2,
                cause: OpFault::References
            })
        );
        // Inconsistent sizes inside an op pass the reference checks but fail when run.
        let b = with(0, gemm(0, 3));
        let info = parse(&b).unwrap();
        let mut mem = vec![0.0; info.memory_len(1).unwrap()];
        install(&info, &b, &mut mem).unwrap();
        let mut out = [0.0];
        assert_eq!(
            run(&info, &b, &mut mem, 1, &[&[0.0; 4], &[0.0]], &mut out),
            Err(NnError::BadOp {
                index: 0,
                cause: OpFault::Sizes
            })
        );
    }
}
