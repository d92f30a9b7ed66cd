//! [`DiscriminatorScorer`]: the search's `Ψ(τ, c)` over a discriminator engine.

use super::check_dims;
use super::error::{AdapterBuffer, AdapterError, DimsMismatch, SegmentModelError};
use super::sampler::write_context;
use crate::diffusion::normalize::{is_valid, normalize_in_place};
use crate::engine::{DiscriminatorEngine, ModelDims};
use crate::mode::{ContactMode, SegmentDims};
use crate::search::SegmentScorer;

/// Buffer lengths (in `f32`s) of one caller buffer split by [`DiscriminatorScorer::new`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScorerAdapterLayout {
    /// Segments per engine call.
    pub chunk: usize,
    /// The normalized segments, `chunk · T · D`.
    pub segments: usize,
    /// The contact-mode rows, `chunk · F`.
    pub context: usize,
}

impl ScorerAdapterLayout {
    /// The layout for `chunk` segments per engine call (any `chunk ≥ 1` gives the same
    /// scores; a larger one fewer engine calls).
    pub const fn new(model: ModelDims, chunk: usize) -> Self {
        Self {
            chunk,
            segments: chunk * model.floats_per_trajectory(),
            context: chunk * model.fingers,
        }
    }

    /// Total `f32`s.
    pub const fn total(&self) -> usize {
        self.segments + self.context
    }
}

/// The search's [`SegmentScorer`] over any [`DiscriminatorEngine`]: raw segments are
/// normalized with the model's normalization, the contact mode is passed as context (±1),
/// and the model's `p_real` is the score. Any batch is accepted; it is scored in chunks of
/// what the buffers and the engine hold.
#[derive(Debug)]
pub struct DiscriminatorScorer<'s, E> {
    engine: E,
    segments: &'s mut [f32],
    context: &'s mut [f32],
    chunk: usize,
}

impl<'s, E: DiscriminatorEngine> DiscriminatorScorer<'s, E> {
    /// A scorer whose buffers are carved out of `buf` (at least `layout.total()` floats).
    pub fn new(
        engine: E,
        buf: &'s mut [f32],
        layout: &ScorerAdapterLayout,
    ) -> Result<Self, AdapterError> {
        if buf.len() < layout.total() {
            return Err(AdapterError::ScratchTooSmall {
                buffer: AdapterBuffer::Segments,
                needed: layout.total(),
                got: buf.len(),
            });
        }
        let (segments, rest) = buf.split_at_mut(layout.segments);
        let (context, _) = rest.split_at_mut(layout.context);
        Self::from_parts(engine, segments, context)
    }

    /// A scorer over separately provided buffers: `segments` (`T·D` floats per segment of an
    /// engine call) and `context` (`F` floats per segment).
    pub fn from_parts(
        engine: E,
        segments: &'s mut [f32],
        context: &'s mut [f32],
    ) -> Result<Self, AdapterError> {
        let dims = engine.dims();
        let floats = dims.floats_per_trajectory().max(1);
        let fingers = dims.fingers.max(1);
        if segments.len() < floats {
            return Err(AdapterError::ScratchTooSmall {
                buffer: AdapterBuffer::Segments,
                needed: floats,
                got: segments.len(),
            });
        }
        if context.len() < fingers {
            return Err(AdapterError::ScratchTooSmall {
                buffer: AdapterBuffer::Context,
                needed: fingers,
                got: context.len(),
            });
        }
        if !is_valid(&engine.normalization(), dims.dim()) {
            return Err(AdapterError::BadNormalization);
        }
        let chunk = (segments.len() / floats).min(context.len() / fingers);
        Ok(Self {
            engine,
            segments,
            context,
            chunk,
        })
    }

    /// The engine.
    pub fn engine(&self) -> &E {
        &self.engine
    }

    /// The engine, mutably.
    pub fn engine_mut(&mut self) -> &mut E {
        &mut self.engine
    }

    /// Give the engine back.
    pub fn into_engine(self) -> E {
        self.engine
    }

    /// Whether the model scores segments of `dims`' sizes; the first size that differs is
    /// named.
    pub fn check_dims(&self, dims: &SegmentDims) -> Result<(), DimsMismatch> {
        check_dims(self.engine.dims(), dims)
    }
}

impl<E: DiscriminatorEngine> SegmentScorer for DiscriminatorScorer<'_, E> {
    type Error = SegmentModelError<E::Error>;

    fn max_batch(&self) -> usize {
        usize::MAX
    }

    fn accepts(&self, dims: &SegmentDims) -> bool {
        self.check_dims(dims).is_ok()
    }

    fn score(
        &mut self,
        dims: &SegmentDims,
        segments: &[f32],
        modes: &[ContactMode],
        out: &mut [f32],
    ) -> Result<(), Self::Error> {
        self.check_dims(dims).map_err(AdapterError::Dims)?;
        let n = modes.len();
        let floats = dims.floats();
        if segments.len() != n * floats {
            return Err(AdapterError::SegmentsLength {
                expected: n * floats,
                got: segments.len(),
            }
            .into());
        }
        if out.len() < n {
            return Err(AdapterError::ScoresLength {
                expected: n,
                got: out.len(),
            }
            .into());
        }
        if !is_valid(&self.engine.normalization(), dims.dim()) {
            return Err(AdapterError::BadNormalization.into());
        }
        let per_call = self.chunk.min(self.engine.max_batch());
        if per_call == 0 {
            return Err(AdapterError::EngineBatch.into());
        }
        let fingers = dims.fingers;
        let mut c0 = 0;
        while c0 < n {
            let m = per_call.min(n - c0);
            let (Some(x), Some(ctx), Some(src), Some(p)) = (
                self.segments.get_mut(..m * floats),
                self.context.get_mut(..m * fingers),
                segments.get(c0 * floats..(c0 + m) * floats),
                out.get_mut(c0..c0 + m),
            ) else {
                // `per_call` is within the buffers and the lengths were checked above.
                return Err(AdapterError::EngineBatch.into());
            };
            x.copy_from_slice(src);
            normalize_in_place(&self.engine.normalization(), x);
            write_context(modes.get(c0..c0 + m).unwrap_or(&[]), fingers, ctx)?;
            self.engine
                .p_real(m, x, ctx, p)
                .map_err(SegmentModelError::Engine)?;
            c0 += m;
        }
        Ok(())
    }
}
