//! Errors of the model adapters.

use core::fmt;

use crate::diffusion::{SampleError, SamplerError};

/// A segment size that a model and a problem disagree on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DimField {
    /// Rows per segment, `T` (`dips.horizon`).
    Horizon,
    /// State columns (`dips.state_dim`).
    StateDim,
    /// Action columns (`dips.action_dim`).
    ActionDim,
    /// Fingers in a contact mode (`dips.fingers`).
    Fingers,
}

impl fmt::Display for DimField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Horizon => "horizon",
            Self::StateDim => "state_dim",
            Self::ActionDim => "action_dim",
            Self::Fingers => "fingers",
        })
    }
}

/// A model exported for other segment sizes than the problem's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DimsMismatch {
    /// The first size that differs.
    pub field: DimField,
    /// The model's value.
    pub model: usize,
    /// The problem's value.
    pub problem: usize,
}

impl fmt::Display for DimsMismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "model {} is {} but the problem's is {}",
            self.field, self.model, self.problem
        )
    }
}

/// A working buffer of an adapter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AdapterBuffer {
    /// The contact-mode rows (`context`, `n·F`).
    Context,
    /// The normalized segments handed to the discriminator (`chunk·T·D`).
    Segments,
    /// The diffusion sampler's scratch.
    Sampler,
    /// The start states with a symmetry angle clamped (`n·state_dim`).
    Starts,
}

/// Why an adapter refused a call (before its model ran).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum AdapterError {
    /// The model's segment sizes are not the problem's.
    Dims(DimsMismatch),
    /// More segments in one call than the adapter's buffers hold.
    TooManySegments {
        /// Segments asked for.
        got: usize,
        /// Most segments per call ([`crate::search::SegmentSampler::max_batch`]).
        capacity: usize,
    },
    /// `starts` is not `n·state_dim` floats.
    StartsLength {
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// The segment buffer is not `n·T·D` floats.
    SegmentsLength {
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// The score output is shorter than `n`.
    ScoresLength {
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A contact mode describes another number of fingers than the model's `F`.
    ModeFingers {
        /// The model's `F`.
        expected: usize,
        /// The mode's finger count.
        got: usize,
    },
    /// A working buffer cannot hold even one segment.
    ScratchTooSmall {
        /// Which buffer.
        buffer: AdapterBuffer,
        /// Floats needed.
        needed: usize,
        /// Floats given.
        got: usize,
    },
    /// The model's normalization is not `D` finite means and positive stds.
    BadNormalization,
    /// The engine accepts no batch at all (`max_batch() == 0`).
    EngineBatch,
    /// The diffusion sampler refused its scratch (a buffer too small for one trajectory
    /// pair or for the schedule).
    Sampler(SamplerError),
}

impl fmt::Display for AdapterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Dims(d) => write!(f, "{d}"),
            Self::TooManySegments { got, capacity } => {
                write!(
                    f,
                    "{got} segments in one call, the adapter holds {capacity}"
                )
            }
            Self::StartsLength { expected, got } => {
                write!(f, "start states have {got} floats, expected {expected}")
            }
            Self::SegmentsLength { expected, got } => {
                write!(f, "segment buffer has {got} floats, expected {expected}")
            }
            Self::ScoresLength { expected, got } => {
                write!(f, "score output has {got} entries, expected {expected}")
            }
            Self::ModeFingers { expected, got } => {
                write!(f, "contact mode has {got} fingers, the model {expected}")
            }
            Self::ScratchTooSmall {
                buffer,
                needed,
                got,
            } => write!(
                f,
                "adapter buffer {buffer:?} has {got} floats, needs at least {needed}"
            ),
            Self::BadNormalization => {
                f.write_str("model normalization is not D finite means and positive stds")
            }
            Self::EngineBatch => f.write_str("engine accepts no batch (max_batch 0)"),
            Self::Sampler(e) => write!(f, "diffusion sampler scratch: {e}"),
        }
    }
}

impl core::error::Error for AdapterError {}

impl From<DimsMismatch> for AdapterError {
    fn from(d: DimsMismatch) -> Self {
        Self::Dims(d)
    }
}

/// A failed adapter call: refused by the adapter, by the diffusion sampler, or failed in the
/// engine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SegmentModelError<E> {
    /// The adapter refused the call.
    Adapter(AdapterError),
    /// The diffusion sampler refused the call or its engine failed.
    Sample(SampleError<E>),
    /// The discriminator engine failed.
    Engine(E),
}

impl<E> From<AdapterError> for SegmentModelError<E> {
    fn from(e: AdapterError) -> Self {
        Self::Adapter(e)
    }
}

impl<E: fmt::Debug> fmt::Display for SegmentModelError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Adapter(e) => write!(f, "model adapter: {e}"),
            Self::Sample(e) => write!(f, "{e}"),
            Self::Engine(e) => write!(f, "discriminator engine failed: {e:?}"),
        }
    }
}

impl<E: fmt::Debug> core::error::Error for SegmentModelError<E> {}
