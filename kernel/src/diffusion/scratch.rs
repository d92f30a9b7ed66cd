//! Caller-provided working memory of the sampler.

use crate::diffusion::error::{SamplerError, ScratchBuffer};
use crate::engine::ModelDims;

/// Buffer lengths (in `f32`s) for a model's dimensions and a chunk of trajectories per
/// engine call (each call evaluates `2·chunk` samples: conditioned and unconditioned copies).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScratchLayout {
    /// Trajectories per engine call.
    pub chunk: usize,
    /// `alpha_bar`: `diffusion_steps`.
    pub alpha_bar: usize,
    /// `x`: `2·chunk·T·D`.
    pub x: usize,
    /// `eps`: `2·chunk·T·D`.
    pub eps: usize,
    /// `t`: `2·chunk`.
    pub t: usize,
    /// `context`: `2·chunk·F`.
    pub context: usize,
    /// `cond_mask`: `2·chunk`.
    pub cond_mask: usize,
}

impl ScratchLayout {
    /// The layout for `chunk` trajectories per engine call. Use
    /// `chunk = min(n, max_batch / 2)` to sample `n` trajectories with the fewest calls;
    /// any `chunk ≥ 1` works and gives the same samples.
    pub const fn new(dims: ModelDims, chunk: usize) -> Self {
        let pair = 2 * chunk;
        Self {
            chunk,
            alpha_bar: dims.diffusion_steps,
            x: pair * dims.floats_per_trajectory(),
            eps: pair * dims.floats_per_trajectory(),
            t: pair,
            context: pair * dims.fingers,
            cond_mask: pair,
        }
    }

    /// Total `f32`s of all buffers.
    pub const fn total(&self) -> usize {
        self.alpha_bar + self.x + self.eps + self.t + self.context + self.cond_mask
    }
}

/// The sampler's working memory. Every buffer may be longer than needed.
#[derive(Debug)]
pub struct SamplerScratch<'a> {
    /// Cumulative products ᾱ of the schedule.
    pub alpha_bar: &'a mut [f32],
    /// Model input `x`.
    pub x: &'a mut [f32],
    /// Model output `eps`.
    pub eps: &'a mut [f32],
    /// Model input `t`.
    pub t: &'a mut [f32],
    /// Model input `context`.
    pub context: &'a mut [f32],
    /// Model input `cond_mask`.
    pub cond_mask: &'a mut [f32],
}

impl<'a> SamplerScratch<'a> {
    /// Split one buffer of at least `layout.total()` floats into the sampler's buffers.
    pub fn split(buf: &'a mut [f32], layout: &ScratchLayout) -> Result<Self, SamplerError> {
        if buf.len() < layout.total() {
            return Err(SamplerError::ScratchTooSmall {
                buffer: ScratchBuffer::Whole,
                needed: layout.total(),
                got: buf.len(),
            });
        }
        let (alpha_bar, rest) = buf.split_at_mut(layout.alpha_bar);
        let (x, rest) = rest.split_at_mut(layout.x);
        let (eps, rest) = rest.split_at_mut(layout.eps);
        let (t, rest) = rest.split_at_mut(layout.t);
        let (context, rest) = rest.split_at_mut(layout.context);
        let (cond_mask, _) = rest.split_at_mut(layout.cond_mask);
        Ok(Self {
            alpha_bar,
            x,
            eps,
            t,
            context,
            cond_mask,
        })
    }

    /// Most trajectories per engine call these buffers hold for `dims`; an error names the
    /// first buffer too small for even one trajectory (or for the schedule).
    pub fn chunk_capacity(&self, dims: ModelDims) -> Result<usize, SamplerError> {
        let one = ScratchLayout::new(dims, 1);
        let checks = [
            (ScratchBuffer::X, self.x.len(), one.x),
            (ScratchBuffer::Eps, self.eps.len(), one.eps),
            (ScratchBuffer::T, self.t.len(), one.t),
            (ScratchBuffer::Context, self.context.len(), one.context),
            (ScratchBuffer::CondMask, self.cond_mask.len(), one.cond_mask),
        ];
        if self.alpha_bar.len() < one.alpha_bar {
            return Err(SamplerError::ScratchTooSmall {
                buffer: ScratchBuffer::AlphaBar,
                needed: one.alpha_bar,
                got: self.alpha_bar.len(),
            });
        }
        let mut capacity = usize::MAX;
        for (buffer, got, needed) in checks {
            if needed == 0 {
                continue;
            }
            if got < needed {
                return Err(SamplerError::ScratchTooSmall {
                    buffer,
                    needed,
                    got,
                });
            }
            capacity = capacity.min(got / needed);
        }
        Ok(capacity)
    }
}
