//! [`DiffusionSegmentSampler`]: the search's sampler `M(c, s₀)` over a denoiser engine.

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
    /// The start states with an invariant angle zeroed, `max_segments · state_dim`
    /// ([`DiffusionSegmentSampler::set_invariant_angle`]).
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
    invariant_angle: Option<InvariantAngle>,
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
            invariant_angle: None,
            capacity,
        })
    }

    /// Declare an angle of the state a symmetry of the task (`None`, the default: none).
    ///
    /// The screwdriver's handle is a solid of revolution and its yaw is applied last
    /// (`Rx(roll)·Ry(pitch)·Rz(yaw)`), so a state and the same state with another yaw are the
    /// same physical situation: the same contacts, forces and costs (regrasp targets and goals
    /// are relative to the yaw). A segment whose start angle lies outside `[lo, hi]`, the
    /// angles the model was trained at, is sampled from its start with the angle clamped into
    /// them, and every row's angle is turned back by the difference. Without it a model
    /// trained on episodes that start at yaw 0 (no yaw augmentation) is asked about yaws it has
    /// not seen: measured, from yaws below −1 rad its turns barely turned, and the search
    /// stopped with three or four of seven modes left. Row 0's state stays exactly the given
    /// start; inside `[lo, hi]` nothing changes.
    pub fn set_invariant_angle(&mut self, angle: Option<InvariantAngle>) {
        self.invariant_angle = angle;
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
        let turned = match self.invariant_angle {
            Some(a) if a.cos_column + 1 < sd => {
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
                Some(a)
            }
            _ => None,
        };
        let request = SampleRequest {
            context,
            start_states: Some(match turned {
                Some(_) => &self.starts[..n * sd],
                None => starts,
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
        if let Some(a) = turned {
            a.turn_back(out, starts, &self.starts[..n * sd], dims);
        }
        Ok(())
    }
}

/// An angle the task's physics does not depend on, and the angles the model knows it at
/// ([`DiffusionSegmentSampler::set_invariant_angle`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvariantAngle {
    /// State column of the angle's `cos` (its `sin` follows).
    pub cos_column: usize,
    /// The smallest start angle the model is asked about (radians).
    pub lo: f32,
    /// The largest start angle the model is asked about (radians).
    pub hi: f32,
}

impl InvariantAngle {
    /// Move the angle of every start in `starts` (rows of `state_dim`) into `[lo, hi]`.
    pub fn clamp_starts(&self, starts: &mut [f32], state_dim: usize) {
        let c = self.cos_column;
        for s in starts.chunks_mut(state_dim) {
            let a = libm::atan2f(s[c + 1], s[c]);
            let k = a.clamp(self.lo, self.hi);
            if k != a {
                s[c] = libm::cosf(k);
                s[c + 1] = libm::sinf(k);
            }
        }
    }

    /// Turn every row's angle of each segment in `out`, sampled from `clamped` (the starts
    /// after [`Self::clamp_starts`]), by its start's angle in `starts` minus the clamped one,
    /// and put the start's exact `(cos, sin)` back into row 0.
    pub fn turn_back(&self, out: &mut [f32], starts: &[f32], clamped: &[f32], dims: &SegmentDims) {
        let c = self.cos_column;
        let d = dims.dim();
        let sd = dims.state_dim;
        for ((seg, start), k) in out
            .chunks_mut(dims.floats())
            .zip(starts.chunks(sd))
            .zip(clamped.chunks(sd))
        {
            let (cs, ss) = (start[c], start[c + 1]);
            let (ck, sk) = (k[c], k[c + 1]);
            if (cs, ss) == (ck, sk) {
                continue;
            }
            // The rotation from the clamped angle to the start's.
            let n = libm::sqrtf((cs * cs + ss * ss) * (ck * ck + sk * sk)).max(f32::MIN_POSITIVE);
            let c0 = (cs * ck + ss * sk) / n;
            let s0 = (ss * ck - cs * sk) / n;
            for row in seg.chunks_mut(d) {
                let (cr, sr) = (row[c], row[c + 1]);
                row[c] = cr * c0 - sr * s0;
                row[c + 1] = sr * c0 + cr * s0;
            }
            seg[c] = cs;
            seg[c + 1] = ss;
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn yaw(row: &[f32], c: usize) -> f32 {
        libm::atan2f(row[c + 1], row[c])
    }

    #[test]
    fn an_invariant_angle_is_clamped_for_the_model_and_turned_back() {
        let dims = SegmentDims {
            horizon: 2,
            state_dim: 4,
            action_dim: 1,
            fingers: 1,
        };
        let a = InvariantAngle {
            cos_column: 2,
            lo: -0.6,
            hi: 0.0,
        };
        let row = |q: f32, y: f32| [q, 0.5, libm::cosf(y), libm::sinf(y), 0.0];
        // Two starts: one inside [lo, hi], one below it.
        let starts: Vec<f32> = [row(0.1, -0.3), row(0.2, -1.4)]
            .iter()
            .flat_map(|r| r[..4].to_vec())
            .collect();
        let mut clamped = starts.clone();
        a.clamp_starts(&mut clamped, 4);
        assert_eq!(clamped[..4], starts[..4], "inside the range nothing moves");
        assert!((yaw(&clamped[4..], 2) - -0.6).abs() < 1e-6);
        assert_eq!(clamped[4..6], starts[4..6], "only the angle moves");
        // What the model would return from the clamped starts: row 1 turned by −0.3 more.
        let mut out: Vec<f32> = [(0.1, -0.3), (0.2, -0.6)]
            .iter()
            .flat_map(|&(q, y)| {
                let mut seg = row(q, y).to_vec();
                seg.extend(row(q, y - 0.3));
                seg
            })
            .collect();
        let before = out.clone();
        a.turn_back(&mut out, &starts, &clamped, &dims);
        assert_eq!(
            out[..10],
            before[..10],
            "an unclamped segment is left alone"
        );
        let seg = &out[10..];
        assert_eq!(seg[..4], starts[4..8], "row 0 is exactly the start");
        assert!((yaw(&seg[5..], 2) - (-1.4 - 0.3)).abs() < 1e-5);
    }
}
