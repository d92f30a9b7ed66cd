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
    /// Op `index` references memory outside the arena or the weights, or its sizes disagree.
    BadOp {
        /// Position in the op stream.
        index: u32,
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
