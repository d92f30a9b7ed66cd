//! What the search needs from the models and the task, as traits: the diffusion sampler
//! `M`, the discriminator `Ψ`, and the task's costs (`J`, `φ`, goal). The real models plug in
//! through adapters over [`crate::engine`]; the real task costs are in [`crate::task`].
//!
//! All trajectory data is raw (de-normalized), in the `docs/contracts.md` §2 layout: a segment is
//! `[T × D]` row-major, row `t` = `[s_t, u_t]`, row 0 holds the start state.

use crate::mode::{ContactMode, SegmentDims};
use crate::rng::KernelRng;
use core::fmt;

/// The diffusion model `M(c, s_0)`, batch-shaped.
pub trait SegmentSampler {
    /// The sampler's error type.
    type Error: fmt::Debug;

    /// The largest batch one call accepts (`usize::MAX` when unbounded). The planner splits
    /// an expansion into several calls only when this is smaller than `modes × k`.
    fn max_batch(&self) -> usize;

    /// Whether the sampler can produce segments of these sizes (checked once per call; a
    /// mismatch is [`crate::search::SearchStatus::InvalidProblem`]). Model adapters compare
    /// them with the model's dimensions.
    fn accepts(&self, dims: &SegmentDims) -> bool {
        let _ = dims;
        true
    }

    /// Sample `n = modes.len()` segments: segment `i` has contact mode `modes[i]` and starts at
    /// the raw state `starts[i·state_dim .. (i+1)·state_dim]` (inpainted in row 0). Writes the
    /// raw segments to `out[i·T·D .. (i+1)·T·D]`. All noise comes from `rng`.
    fn sample(
        &mut self,
        dims: &SegmentDims,
        starts: &[f32],
        modes: &[ContactMode],
        rng: &mut KernelRng,
        out: &mut [f32],
    ) -> Result<(), Self::Error>;
}

/// The discriminator `Ψ(τ, c)`, batch-shaped.
pub trait SegmentScorer {
    /// The scorer's error type.
    type Error: fmt::Debug;

    /// The largest batch one call accepts (`usize::MAX` when unbounded).
    fn max_batch(&self) -> usize;

    /// Whether the scorer can score segments of these sizes (checked once per call; a
    /// mismatch is [`crate::search::SearchStatus::InvalidProblem`]).
    fn accepts(&self, dims: &SegmentDims) -> bool {
        let _ = dims;
        true
    }

    /// Score `n = modes.len()` raw segments `segments[i·T·D ..]` with their modes; writes the
    /// probability that each is realistic, in `[0, 1]`, to `out[i]`.
    fn score(
        &mut self,
        dims: &SegmentDims,
        segments: &[f32],
        modes: &[ContactMode],
        out: &mut [f32],
    ) -> Result<(), Self::Error>;
}

/// A task's costs and goal, as the search uses them.
///
/// The planner reduces each particle's end state to one *progress* number (screwdriver: the
/// yaw; card: `y`), takes its score-weighted mean over the node's particles, and evaluates the
/// terminal cost `φ` and the goal test on that mean.
pub trait TaskObjective {
    /// Whether the objective can evaluate segments of these sizes (checked once per call;
    /// a mismatch is [`crate::search::SearchStatus::InvalidProblem`]).
    fn accepts(&self, dims: &SegmentDims) -> bool {
        let _ = dims;
        true
    }

    /// The CSVTO cost `J` of one raw segment `[T × D]` executed in `mode` (lower is better).
    fn segment_cost(&self, mode: ContactMode, dims: &SegmentDims, segment: &[f32]) -> f32;

    /// The progress measure of one raw state (`state_dim` floats).
    fn progress(&self, state: &[f32]) -> f32;

    /// The terminal cost `φ` of an expected progress (weighted by `α` in the heuristic).
    fn terminal_cost(&self, expected_progress: f32) -> f32;

    /// Whether an expected progress satisfies the search goal `o_G`.
    fn goal_reached(&self, expected_progress: f32) -> bool;
}
