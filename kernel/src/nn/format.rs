//! The lowered model blob (`.dipsm`), format version 2 (version 1 had no
//! [`Meta::object_frame`]; lower the ONNX model again to get a version 2 blob).
//!
//! `blob = postcard(Header) ++ postcard(Body) ++ crc32_le(everything before)`.
//! The body borrows its strings, its op stream and its weight bytes from the blob, so decoding
//! copies nothing; the weights are copied into caller memory once, when the model is installed.
//! Every size is per sample: a value of `len` floats occupies `len * max_batch` floats of the
//! arena, so one blob runs at any batch the caller's memory can hold.

use serde::{Deserialize, Serialize};

/// The first four bytes of every blob.
pub const MAGIC: [u8; 4] = *b"DIPM";
/// The blob format version this interpreter reads.
pub const BLOB_VERSION: u16 = 2;
/// The checksum (CRC-32/ISO-HDLC) over header and body.
pub const CHECKSUM: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
/// Most contract inputs a model has (the denoiser's `x, t, context, cond_mask`).
pub const MAX_INPUTS: usize = 4;
/// Rank of the strided loops in [`Op::Binary`] and [`Op::Copy`] (per sample, without batch).
pub const RANK: usize = 4;

/// Fixed-size start of the blob, decoded before anything else.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// [`MAGIC`].
    pub magic: [u8; 4],
    /// [`BLOB_VERSION`] of the writer.
    pub version: u16,
}

/// A value in the activation arena: `len` floats per sample starting at `off` (per sample).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Buf {
    /// Offset in per-sample floats; the value starts at `off * max_batch`.
    pub off: u32,
    /// Floats per sample.
    pub len: u32,
}

/// A constant in the weight array.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct W {
    /// First float.
    pub off: u32,
    /// Floats.
    pub len: u32,
}

/// An operand that is either an activation (one block per sample) or a constant (shared).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Operand {
    /// Per-sample activation.
    Act(Buf),
    /// Constant shared by all samples.
    Weight(W),
}

/// Element-wise functions of one argument.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum UnaryFn {
    /// `x·tanh(softplus(x))`.
    Mish,
    /// `ln(1 + eˣ)`.
    Softplus,
    /// `tanh x`.
    Tanh,
    /// `1 / (1 + e⁻ˣ)`.
    Sigmoid,
    /// `sin x`.
    Sin,
    /// `cos x`.
    Cos,
    /// `eˣ`.
    Exp,
    /// `max(x, 0)`.
    Relu,
    /// `-x`.
    Neg,
    /// `√x`.
    Sqrt,
    /// `1/x`.
    Reciprocal,
    /// `|x|`.
    Abs,
    /// `ln x`.
    Log,
}

/// Element-wise functions of two broadcast arguments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BinaryFn {
    /// `a + b`.
    Add,
    /// `a − b`.
    Sub,
    /// `a · b`.
    Mul,
    /// `a / b`.
    Div,
    /// `max(a, b)`.
    Max,
    /// `min(a, b)`.
    Min,
    /// `aᵇ`.
    Pow,
}

/// Geometry of a 1-D (transposed) convolution, per sample; groups are 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ConvGeom {
    /// Input channels.
    pub cin: u32,
    /// Output channels.
    pub cout: u32,
    /// Output channels rounded up to the packing width ([`crate::nn::ops::conv::CO_BLOCK`]).
    pub cout_padded: u32,
    /// Input length.
    pub lin: u32,
    /// Output length.
    pub lout: u32,
    /// Kernel size.
    pub k: u32,
    /// Stride.
    pub stride: u32,
    /// Dilation.
    pub dilation: u32,
    /// Zero padding before the first input element (conv) or cropped from the front (transposed).
    pub pad_begin: u32,
}

/// One step of the program. Every shape is per sample; the interpreter loops over the batch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Op {
    /// `y[co,t] = b[co] + Σ w[ci,k,co]·x[ci, t·s + k·d − pad]` (`w` packed `[cin][k][cout_padded]`).
    Conv1d {
        /// Input `[cin, lin]`.
        x: Buf,
        /// Output `[cout, lout]`.
        y: Buf,
        /// Packed kernel.
        w: W,
        /// Bias, `cout_padded` floats.
        b: W,
        /// Geometry.
        g: ConvGeom,
    },
    /// Transposed convolution (`w` packed `[cin][k][cout_padded]`).
    ConvTranspose1d {
        /// Input `[cin, lin]`.
        x: Buf,
        /// Output `[cout, lout]`.
        y: Buf,
        /// Packed kernel.
        w: W,
        /// Bias, `cout_padded` floats.
        b: W,
        /// Geometry.
        g: ConvGeom,
    },
    /// Instance normalization over `[channels, len]` with a per-channel affine map, optionally
    /// followed by a per-row affine map (GroupNorm's γ, β) and Mish.
    InstanceNorm {
        /// Input `[channels, len]`.
        x: Buf,
        /// Output, same shape.
        y: Buf,
        /// Normalized rows.
        channels: u32,
        /// Elements per row.
        len: u32,
        /// Variance epsilon.
        eps: f32,
        /// Scale, `channels` floats.
        scale: W,
        /// Bias, `channels` floats.
        bias: W,
    },
    /// Group normalization with a per-channel affine map and optional Mish: each of the
    /// `groups` blocks of `group_len` elements is normalized, then element `i` of the sample
    /// is mapped by `γ[i / channel_len]`, `β[i / channel_len]` (exporters' GroupNorm:
    /// Reshape, InstanceNormalization, Reshape, Mul, Add, Mish fused into one pass).
    GroupNorm {
        /// Input, `groups × group_len` floats.
        x: Buf,
        /// Output, same shape.
        y: Buf,
        /// Groups.
        groups: u32,
        /// Elements per group.
        group_len: u32,
        /// Elements per channel (divides `group_len`).
        channel_len: u32,
        /// Variance epsilon.
        eps: f32,
        /// Per-channel scale.
        gamma: W,
        /// Per-channel shift.
        beta: W,
        /// Apply Mish after the affine map.
        mish: bool,
    },
    /// `y = f(x)` element-wise.
    Unary {
        /// Input.
        x: Buf,
        /// Output, same length.
        y: Buf,
        /// Function.
        f: UnaryFn,
    },
    /// `y = f(a, b)` with broadcasting: the output is `dims` (row-major) and each operand is
    /// read at `Σ iᵢ·strideᵢ` (stride 0 on a broadcast axis).
    Binary {
        /// First operand.
        a: Operand,
        /// Second operand.
        b: Operand,
        /// Output.
        y: Buf,
        /// Function.
        f: BinaryFn,
        /// Output dims, padded at the front with 1.
        dims: [u32; RANK],
        /// Strides of `a`.
        sa: [u32; RANK],
        /// Strides of `b`.
        sb: [u32; RANK],
    },
    /// `y[r, :] = b + a[r, :]·w` for each of `rows` rows per sample (`w` packed `[k][n]`).
    Gemm {
        /// Input `[rows, k]`.
        a: Buf,
        /// Output `[rows, n]`.
        y: Buf,
        /// Weight `[k, n]`.
        w: W,
        /// Bias, `n` floats.
        b: W,
        /// Rows per sample.
        rows: u32,
        /// Inner size.
        k: u32,
        /// Output columns.
        n: u32,
    },
    /// Strided copy: for every index `i` of `dims`, `y[y_off + i·ys] = x[x_off + i·xs]`
    /// (layout ops: Transpose, Slice, Concat parts, Pad interiors, Expand).
    Copy {
        /// Source.
        x: Operand,
        /// Destination.
        y: Buf,
        /// Index space.
        dims: [u32; RANK],
        /// Source start.
        x_off: u32,
        /// Source strides (may be negative for reversed slices).
        xs: [i32; RANK],
        /// Destination start.
        y_off: u32,
        /// Destination strides.
        ys: [u32; RANK],
    },
    /// `y = value` everywhere.
    Fill {
        /// Destination.
        y: Buf,
        /// The value.
        value: f32,
    },
    /// `y[o, i] = mean_l x[o, l, i]`.
    ReduceMean {
        /// Input `[outer, len, inner]`.
        x: Buf,
        /// Output `[outer, inner]`.
        y: Buf,
        /// Outer size.
        outer: u32,
        /// Reduced size.
        len: u32,
        /// Inner size.
        inner: u32,
    },
}

/// One reference an [`Op`] holds: what it reads, writes, or takes as a constant.
#[derive(Debug)]
pub enum OpRef<'a> {
    /// A per-sample activation it reads.
    Reads(&'a mut Buf),
    /// An operand it reads that may be an activation or a weight.
    ReadsOperand(&'a mut Operand),
    /// The activation it writes.
    Writes(&'a mut Buf),
    /// A constant weight range it reads.
    Weight(&'a mut W),
}

impl Op {
    /// Visit every buffer, operand and weight the op refers to, in field order, mutably. The
    /// op's structure lives here once: the interpreter's checks, the lowering's arena
    /// planning, remapping and weight compaction all go through it, so a new op adds its
    /// fields here and its computation in the interpreter.
    pub fn refs_mut<'a>(&'a mut self, mut f: impl FnMut(OpRef<'a>)) {
        match self {
            Op::Conv1d { x, y, w, b, .. } | Op::ConvTranspose1d { x, y, w, b, .. } => {
                f(OpRef::Reads(x));
                f(OpRef::Writes(y));
                f(OpRef::Weight(w));
                f(OpRef::Weight(b));
            }
            Op::Gemm { a, y, w, b, .. } => {
                f(OpRef::Reads(a));
                f(OpRef::Writes(y));
                f(OpRef::Weight(w));
                f(OpRef::Weight(b));
            }
            Op::InstanceNorm {
                x, y, scale, bias, ..
            } => {
                f(OpRef::Reads(x));
                f(OpRef::Writes(y));
                f(OpRef::Weight(scale));
                f(OpRef::Weight(bias));
            }
            Op::GroupNorm {
                x, y, gamma, beta, ..
            } => {
                f(OpRef::Reads(x));
                f(OpRef::Writes(y));
                f(OpRef::Weight(gamma));
                f(OpRef::Weight(beta));
            }
            Op::Unary { x, y, .. } | Op::ReduceMean { x, y, .. } => {
                f(OpRef::Reads(x));
                f(OpRef::Writes(y));
            }
            Op::Binary { a, b, y, .. } => {
                f(OpRef::ReadsOperand(a));
                f(OpRef::ReadsOperand(b));
                f(OpRef::Writes(y));
            }
            Op::Copy { x, y, .. } => {
                f(OpRef::ReadsOperand(x));
                f(OpRef::Writes(y));
            }
            Op::Fill { y, .. } => f(OpRef::Writes(y)),
        }
    }

    /// [`Self::refs_mut`] on a copy: visit without changing the op.
    pub fn refs(&self, f: impl for<'r> FnMut(OpRef<'r>)) {
        let mut copy = *self;
        copy.refs_mut(f);
    }

    /// The activation the op writes.
    pub fn output(&self) -> Buf {
        let mut out = Buf { off: 0, len: 0 };
        self.refs(|r| {
            if let OpRef::Writes(b) = r {
                out = *b;
            }
        });
        out
    }
}

/// Contract metadata carried by the blob (`docs/contracts.md` §3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Meta<'a> {
    /// `dips.contract`.
    pub contract: u32,
    /// 0 denoiser, 1 discriminator.
    pub role: u8,
    /// `dips.task`.
    pub task: &'a str,
    /// `dips.horizon`.
    pub horizon: u32,
    /// `dips.state_dim`.
    pub state_dim: u32,
    /// `dips.action_dim`.
    pub action_dim: u32,
    /// `dips.fingers`.
    pub fingers: u32,
    /// `dips.diffusion_steps`.
    pub diffusion_steps: u32,
    /// `dips.beta_schedule`.
    pub beta_schedule: &'a str,
    /// `dips.prediction`.
    pub prediction: &'a str,
    /// `dips.columns` as the JSON array string of the ONNX file.
    pub columns_json: &'a str,
    /// `dips.norm_mean` in the weight array.
    pub norm_mean: W,
    /// `dips.norm_std` in the weight array.
    pub norm_std: W,
    /// `dips.object_frame` as [`crate::engine::ObjectFrame::code`] (0 for a discriminator).
    pub object_frame: u8,
}

/// Everything after the header.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Body<'a> {
    /// Contract metadata.
    #[serde(borrow)]
    pub meta: Meta<'a>,
    /// Contract inputs in contract order (`x, t, context, cond_mask` or `x, context`).
    pub inputs: [Buf; MAX_INPUTS],
    /// How many of `inputs` are used.
    pub n_inputs: u8,
    /// The contract output.
    pub output: Buf,
    /// Arena floats per sample.
    pub arena_per_sample: u32,
    /// Scratch floats the ops need besides the arena (independent of the batch).
    pub temp_len: u32,
    /// Number of ops in `ops`.
    pub n_ops: u32,
    /// The ops, each postcard-encoded, back to back.
    pub ops: &'a [u8],
    /// Number of weights.
    pub n_weights: u32,
    /// Weights as little-endian `f32` bytes.
    pub weights: &'a [u8],
}
