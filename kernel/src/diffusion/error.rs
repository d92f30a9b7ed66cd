//! Sampler errors.

use core::fmt;

/// A scratch buffer of [`crate::diffusion::SamplerScratch`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScratchBuffer {
    /// `alpha_bar`: one entry per diffusion step.
    AlphaBar,
    /// `x`: model input, `2·chunk·T·D`.
    X,
    /// `eps`: model output, `2·chunk·T·D`.
    Eps,
    /// `t`: `2·chunk`.
    T,
    /// `context`: `2·chunk·F`.
    Context,
    /// `cond_mask`: `2·chunk`.
    CondMask,
    /// The single buffer split by [`crate::diffusion::SamplerScratch::split`].
    Whole,
}

/// Why the sampler refused a call (misuse or a bad model); the engine's own errors come
/// wrapped in [`SampleError::Engine`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SamplerError {
    /// The output length is not a positive multiple of `T·D`.
    OutputLength {
        /// Floats per trajectory, `T·D`.
        floats_per_trajectory: usize,
        /// Length given.
        got: usize,
    },
    /// `context` is not `n·F` long.
    ContextLength {
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// `start_states` is not `n·state_dim` long.
    StartStateLength {
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A start state entry is not finite.
    NonFiniteStartState,
    /// A scratch buffer is too small for one trajectory pair (or for the schedule).
    ScratchTooSmall {
        /// Which buffer.
        buffer: ScratchBuffer,
        /// Length needed.
        needed: usize,
        /// Length given.
        got: usize,
    },
    /// The engine accepts fewer than 2 samples per call (guidance needs a pair).
    MaxBatchTooSmall {
        /// The engine's `max_batch()`.
        max_batch: usize,
    },
    /// The model has no diffusion steps, or a zero-sized trajectory.
    BadDims,
    /// The model's normalization does not have `D` finite entries with positive std.
    BadNormalization,
    /// Steps of a strided sampler (DDIM or strided DDPM) outside `1..=diffusion_steps`.
    StridedSteps {
        /// Steps asked for.
        steps: u16,
        /// The model's diffusion steps.
        diffusion_steps: usize,
    },
    /// A sampler setting is not finite, negative where it must not be, or a clip bound ≤ 0.
    BadConfig,
}

impl fmt::Display for SamplerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::OutputLength {
                floats_per_trajectory,
                got,
            } => write!(
                f,
                "output of {got} floats is not a positive multiple of {floats_per_trajectory} (T·D)"
            ),
            Self::ContextLength { expected, got } => {
                write!(f, "context has {got} floats, expected {expected} (n·F)")
            }
            Self::StartStateLength { expected, got } => write!(
                f,
                "start states have {got} floats, expected {expected} (n·state_dim)"
            ),
            Self::NonFiniteStartState => f.write_str("a start state entry is not finite"),
            Self::ScratchTooSmall {
                buffer,
                needed,
                got,
            } => write!(
                f,
                "scratch buffer {buffer:?} has {got} entries, needs at least {needed}"
            ),
            Self::MaxBatchTooSmall { max_batch } => write!(
                f,
                "engine max batch {max_batch} is below 2 (guidance needs a pair per call)"
            ),
            Self::BadDims => f.write_str("model has no diffusion steps or an empty trajectory"),
            Self::BadNormalization => {
                f.write_str("model normalization is not D finite means and positive stds")
            }
            Self::StridedSteps {
                steps,
                diffusion_steps,
            } => write!(
                f,
                "strided sampler steps {steps} outside 1..={diffusion_steps}"
            ),
            Self::BadConfig => f.write_str(
                "sampler settings out of range (allowed: finite guidance weight, noise factor and η ≥ 0, clip_denoised > 0)",
            ),
        }
    }
}

impl core::error::Error for SamplerError {}

/// A failed sampling call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleError<E> {
    /// The call was refused before or while running.
    Sampler(SamplerError),
    /// The engine failed.
    Engine(E),
}

impl<E> From<SamplerError> for SampleError<E> {
    fn from(e: SamplerError) -> Self {
        Self::Sampler(e)
    }
}

impl<E: fmt::Debug> fmt::Display for SampleError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Sampler(e) => write!(f, "diffusion sampler: {e}"),
            Self::Engine(e) => write!(f, "denoiser engine failed: {e:?}"),
        }
    }
}

impl<E: fmt::Debug> core::error::Error for SampleError<E> {}
