//! [`DiffusionSegmentSampler`]: the search's sampler `M(c, s₀)` over a denoiser engine.

use super::anchor::StartAnchor;
use super::check_dims;
use super::error::{AdapterBuffer, AdapterError, DimsMismatch, SegmentModelError};
use crate::diffusion::{
    SampleRequest, SamplerConfig, SamplerError, SamplerScratch, ScratchLayout, sample,
};
use crate::engine::{DenoiserEngine, ModelDims};
use crate::mode::{ContactMode, SegmentDims};
use crate::rng::KernelRng;
use crate::search::SegmentSampler;

/// Buffer lengths (in `f32`s) of one caller buffer split by [`DiffusionSegmentSampler::new`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SamplerAdapterLayout {
    /// Most segments per sampler call (the planner's batch: candidate modes × `k`).
    pub max_segments: usize,
    /// The contact-mode rows, `max_segments · F`.
    pub context: usize,
    /// The start states with a symmetry angle clamped, `max_segments · state_dim`
    /// ([`DiffusionSegmentSampler::set_start_anchor`]).
    pub starts: usize,
    /// The diffusion sampler's scratch.
    pub sampler: ScratchLayout,
}

impl SamplerAdapterLayout {
    /// The layout for up to `max_segments` segments per call, denoised `chunk` at a time per
    /// engine call (each engine call evaluates `2·chunk` samples; any `chunk ≥ 1` gives the
    /// same segments, a larger one fewer engine calls).
    pub const fn new(model: ModelDims, max_segments: usize, chunk: usize) -> Self {
        Self {
            max_segments,
            context: max_segments * model.fingers,
            starts: max_segments * model.state_dim,
            sampler: ScratchLayout::new(model, chunk),
        }
    }

    /// Total `f32`s.
    pub const fn total(&self) -> usize {
        self.context + self.starts + self.sampler.total()
    }
}

/// The search's [`SegmentSampler`] over any [`DenoiserEngine`]: each call runs the diffusion
/// sampler once over the whole batch (DDPM by default, DDIM selectable through
/// [`SamplerConfig`]) with classifier-free guidance, the contact modes as context (±1), and
/// the raw start states inpainted into row 0.
///
/// Raw segments are the `docs/contracts.md` §2 layout, which is the model's (yaw as `cos`, `sin`);
/// the model's normalization is applied to the start states and undone on the output, and
/// row 0's state columns come back exactly equal to the start state. The noise comes from the
/// planner's stream, so a seed fixes the plan.
#[derive(Debug)]
pub struct DiffusionSegmentSampler<'s, E> {
    engine: E,
    config: SamplerConfig,
    scratch: SamplerScratch<'s>,
    context: &'s mut [f32],
    starts: &'s mut [f32],
    anchor: StartAnchor,
    capacity: usize,
}

impl<'s, E: DenoiserEngine> DiffusionSegmentSampler<'s, E> {
    /// An adapter whose buffers are carved out of `buf` (at least `layout.total()` floats).
    pub fn new(
        engine: E,
        config: SamplerConfig,
        buf: &'s mut [f32],
        layout: &SamplerAdapterLayout,
    ) -> Result<Self, AdapterError> {
        if buf.len() < layout.total() {
            return Err(AdapterError::ScratchTooSmall {
                buffer: AdapterBuffer::Sampler,
                needed: layout.total(),
                got: buf.len(),
            });
        }
        let (context, rest) = buf.split_at_mut(layout.context);
        let (starts, rest) = rest.split_at_mut(layout.starts);
        let scratch = SamplerScratch::split(rest, &layout.sampler).map_err(scratch_error)?;
        let mut sampler = Self::from_parts(engine, config, scratch, context)?;
        sampler.starts = starts;
        Ok(sampler)
    }

    /// An adapter over separately provided buffers: the diffusion scratch and `context`
    /// (`F` floats per segment of the largest call).
    pub fn from_parts(
        engine: E,
        config: SamplerConfig,
        scratch: SamplerScratch<'s>,
        context: &'s mut [f32],
    ) -> Result<Self, AdapterError> {
        let dims = engine.dims();
        let fingers = dims.fingers.max(1);
        if context.len() < fingers {
            return Err(AdapterError::ScratchTooSmall {
                buffer: AdapterBuffer::Context,
                needed: fingers,
                got: context.len(),
            });
        }
        scratch.chunk_capacity(dims).map_err(scratch_error)?;
        let capacity = context.len() / fingers;
        Ok(Self {
            engine,
            config,
            scratch,
            context,
            starts: &mut [],
            anchor: StartAnchor::NONE,
            capacity,
        })
    }

    /// How each sampled segment is made to continue from its start ([`StartAnchor`]; the
    /// default, [`StartAnchor::NONE`], returns segments as the model draws them).
    ///
    /// The screwdriver's (`crate::session::start_anchor`): its handle is a solid of
    /// revolution and its yaw is applied last (`Rx(roll)·Ry(pitch)·Rz(yaw)`), so a state and
    /// the same state with another yaw are the same physical situation (regrasp targets and
    /// goals are relative to the yaw). A segment whose start yaw lies outside the yaws the
    /// model was trained at is sampled with the yaw clamped into them: without it, from yaws
    /// below −1 rad the turns barely turned and the search stalled. Then every segment's yaw
    /// and its contact fingers' joints are anchored at the start: row 1 repeats the start's,
    /// so the model's first-row jump (up to 0.36 rad of yaw, measured) is not read as progress.
    pub fn set_start_anchor(&mut self, anchor: StartAnchor) {
        self.anchor = anchor;
    }

    /// The start anchor in use.
    pub fn start_anchor(&self) -> StartAnchor {
        self.anchor
    }

    /// The sampler settings.
    pub fn config(&self) -> &SamplerConfig {
        &self.config
    }

    /// Change the sampler settings (method, guidance weight, noise).
    pub fn set_config(&mut self, config: SamplerConfig) {
        self.config = config;
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

    /// Whether the model produces segments of `dims`' sizes; the first size that differs is
    /// named.
    pub fn check_dims(&self, dims: &SegmentDims) -> Result<(), DimsMismatch> {
        check_dims(self.engine.dims(), dims)
    }
}

/// The diffusion scratch's own checks, as the adapter's error.
fn scratch_error(e: SamplerError) -> AdapterError {
    AdapterError::Sampler(e)
}

/// Write each mode's signs (±1) as a row of `F` floats into `context`.
pub(super) fn write_context(
    modes: &[ContactMode],
    fingers: usize,
    context: &mut [f32],
) -> Result<(), AdapterError> {
    for (row, m) in context.chunks_mut(fingers.max(1)).zip(modes) {
        if m.fingers() != fingers {
            return Err(AdapterError::ModeFingers {
                expected: fingers,
                got: m.fingers(),
            });
        }
        m.write_signs(row);
    }
    Ok(())
}

impl<E: DenoiserEngine> SegmentSampler for DiffusionSegmentSampler<'_, E> {
    type Error = SegmentModelError<E::Error>;

    fn max_batch(&self) -> usize {
        self.capacity
    }

    fn accepts(&self, dims: &SegmentDims) -> bool {
        self.check_dims(dims).is_ok()
    }

    fn sample(
        &mut self,
        dims: &SegmentDims,
        starts: &[f32],
        modes: &[ContactMode],
        rng: &mut KernelRng,
        out: &mut [f32],
    ) -> Result<(), Self::Error> {
        self.check_dims(dims).map_err(AdapterError::Dims)?;
        let n = modes.len();
        if n > self.capacity {
            return Err(AdapterError::TooManySegments {
                got: n,
                capacity: self.capacity,
            }
            .into());
        }
        if starts.len() != n * dims.state_dim {
            return Err(AdapterError::StartsLength {
                expected: n * dims.state_dim,
                got: starts.len(),
            }
            .into());
        }
        if out.len() != n * dims.floats() {
            return Err(AdapterError::SegmentsLength {
                expected: n * dims.floats(),
                got: out.len(),
            }
            .into());
        }
        if n == 0 {
            return Ok(());
        }
        let fingers = dims.fingers;
        let context = self
            .context
            .get_mut(..n * fingers)
            .ok_or(AdapterError::TooManySegments {
                got: n,
                capacity: self.capacity,
            })?;
        write_context(modes, fingers, context)?;
        let sd = dims.state_dim;
        let clamped = match self.anchor.clamp_angle(sd) {
            Some(a) => {
                let got = self.starts.len();
                let clamped =
                    self.starts
                        .get_mut(..n * sd)
                        .ok_or(AdapterError::ScratchTooSmall {
                            buffer: AdapterBuffer::Starts,
                            needed: n * sd,
                            got,
                        })?;
                clamped.copy_from_slice(starts);
                a.clamp_starts(clamped, sd);
                true
            }
            None => false,
        };
        let request = SampleRequest {
            context,
            start_states: Some(if clamped {
                &self.starts[..n * sd]
            } else {
                starts
            }),
        };
        sample(
            &mut self.engine,
            &self.config,
            &request,
            rng,
            &mut self.scratch,
            out,
        )
        .map_err(SegmentModelError::Sample)?;
        self.anchor
            .apply(out, starts, &self.context[..n * fingers], dims);
        Ok(())
    }
}
