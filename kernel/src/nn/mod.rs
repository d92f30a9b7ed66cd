//! The no_std network interpreter: runs models lowered from ONNX (`dips-onnx`) as a versioned
//! postcard blob, with caller-provided memory and no allocation.
//!
//! - [`format`]: the blob layout (header, contract metadata, op stream, weights, checksum).
//! - [`ops`]: the op kernels, free functions over slices.
//! - [`model`]: decoding and validation of a blob, weight installation, the run loop.
//! - [`engine`]: [`engine::KernelEngine`], the denoiser/discriminator engine over a blob.

pub mod engine;
pub mod format;
pub mod model;
pub mod ops;

use core::fmt;

/// Everything the interpreter can reject. No input makes it panic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NnError {
    /// The blob is shorter than its header and checksum.
    Truncated,
    /// The blob does not start with [`format::MAGIC`].
    BadMagic,
    /// The blob was written for another format version.
    UnsupportedVersion {
        /// Version in the blob.
        found: u16,
        /// Version this interpreter reads.
        supported: u16,
    },
    /// The CRC over header and body does not match.
    ChecksumMismatch {
        /// Stored checksum.
        stored: u32,
        /// Computed checksum.
        computed: u32,
    },
    /// The body or an op could not be decoded.
    Decode,
    /// Op `index` cannot run: see its [`OpFault`].
    BadOp {
        /// Position in the op stream.
        index: u32,
        /// What is wrong with it.
        cause: OpFault,
    },
    /// The blob's inputs, output or metadata are inconsistent.
    BadLayout,
    /// A weight is NaN or infinite.
    NonFiniteWeight {
        /// Index into the weight array.
        index: u32,
    },
    /// The caller's memory is smaller than the model needs for one sample.
    MemoryTooSmall {
        /// Floats needed (batch 1).
        needed: usize,
        /// Floats given.
        given: usize,
    },
    /// The batch is zero or larger than the memory holds.
    BadBatch {
        /// Requested batch.
        batch: usize,
        /// Largest batch the memory holds.
        max: usize,
    },
    /// An input or output slice has the wrong length.
    BadLength {
        /// Contract input index, or [`format::MAX_INPUTS`] for the output.
        which: u8,
        /// Floats given.
        given: usize,
        /// Floats expected.
        expected: usize,
    },
    /// The call does not fit the model's role (e.g. `p_real` on a denoiser).
    WrongRole,
}

/// Why an op of a blob cannot run ([`NnError::BadOp`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OpFault {
    /// Its scratch need exceeds the blob's declared scratch (or overflows).
    Scratch,
    /// An operand lies outside the arena or the weights, or its output aliases an input
    /// (found when the blob is parsed).
    References,
    /// At run time, an operand's region is out of range or overlaps the output.
    Operand,
    /// The op kernel refused its slices: their sizes disagree with the op's geometry.
    Sizes,
}

impl fmt::Display for OpFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Scratch => "needs more scratch than the blob declares",
            Self::References => {
                "references memory outside the arena or weights, or aliases its output"
            }
            Self::Operand => "an operand region is out of range or overlaps the output",
            Self::Sizes => "its slice sizes disagree with its geometry",
        })
    }
}

impl fmt::Display for NnError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Truncated => f.write_str("model blob is shorter than its header and checksum"),
            Self::BadMagic => f.write_str("not a model blob (bad magic)"),
            Self::UnsupportedVersion { found, supported } => write!(
                f,
                "model blob format version {found}, this interpreter reads {supported}: lower the ONNX model again (`dips model lower`)"
            ),
            Self::ChecksumMismatch { stored, computed } => write!(
                f,
                "model blob checksum {stored:#010x} does not match its contents ({computed:#010x})"
            ),
            Self::Decode => f.write_str("model blob body or an op does not decode"),
            Self::BadOp { index, cause } => write!(f, "op {index}: {cause}"),
            Self::BadLayout => f.write_str("model inputs, output or metadata are inconsistent"),
            Self::NonFiniteWeight { index } => write!(f, "weight {index} is not finite"),
            Self::MemoryTooSmall { needed, given } => write!(
                f,
                "model memory has {given} floats, one sample needs {needed}"
            ),
            Self::BadBatch { batch, max } => {
                write!(
                    f,
                    "batch {batch} is zero or above the {max} the memory holds"
                )
            }
            Self::BadLength {
                which,
                given,
                expected,
            } => {
                if usize::from(which) == format::MAX_INPUTS {
                    write!(
                        f,
                        "output (or input count) has {given}, expected {expected}"
                    )
                } else {
                    write!(f, "input {which} has {given} floats, expected {expected}")
                }
            }
            Self::WrongRole => f.write_str("the call does not fit the model's role"),
        }
    }
}

impl core::error::Error for NnError {}
