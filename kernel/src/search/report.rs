//! What a planning call returns ([`SearchReport`]).

use super::config::{ConfigError, MAX_PLAN_LEN};
use crate::mode::{MAX_MODES, MAX_STATE_DIM, ModeId};

/// A capacity of the planner (or of the kernel) that a call needed more of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Capacity {
    /// `k` exceeds the planner's particle capacity `K`.
    Particles,
    /// The node arena (`N`) is full.
    Nodes,
    /// The open list (`O`) is full.
    OpenList,
    /// The task's state has more columns than [`MAX_STATE_DIM`].
    StateDim,
    /// A segment has more floats (`T·D`) than the planner's capacity `S`.
    SegmentFloats,
    /// The task has more modes than [`crate::mode::MAX_MODES`].
    Modes,
}

/// Why the search stopped before reaching the goal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ApproximateReason {
    /// The node budget was spent.
    NodeBudget,
    /// The time budget was spent.
    TimeBudget,
    /// Every sequence up to the maximum depth was examined (the open list ran empty).
    Exhausted,
    /// A run-time capacity (nodes, open list) ran out.
    Capacity(Capacity),
    /// The sampler returned an error.
    SamplerFailed,
    /// The scorer returned an error.
    ScorerFailed,
    /// The clock reported a cancellation ([`crate::budget::Clock::cancelled`]).
    Cancelled,
}

/// The outcome of a planning call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SearchStatus {
    /// A node whose expected terminal state meets the goal was popped; the plan leads to it.
    Found,
    /// The goal was not reached; the plan leads to the examined node closest to it (lowest
    /// terminal cost `φ`).
    Approximate(ApproximateReason),
    /// The configuration is invalid; nothing was searched.
    InvalidConfig(ConfigError),
    /// The problem needs more than the planner's capacity; nothing was searched.
    CapacityExceeded(Capacity),
    /// The problem is inconsistent (prior or dimensions do not match the task, the sampler,
    /// the scorer or the objective does not accept the segment sizes, unknown executed
    /// mode); nothing was searched.
    InvalidProblem,
    /// The start state has the wrong length or a non-finite entry.
    InvalidStart,
    /// The goal's terminal cost is not finite at the start state.
    InvalidGoal,
}

impl SearchStatus {
    /// Whether the report carries a plan (found or approximate).
    pub const fn has_plan(&self) -> bool {
        matches!(self, SearchStatus::Found | SearchStatus::Approximate(_))
    }
}

/// Counters of one planning call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SearchStats {
    /// Nodes expanded (one sampler batch each).
    pub nodes_expanded: u32,
    /// Nodes created, the root included.
    pub nodes_generated: u32,
    /// Nodes taken off the open list and goal-tested.
    pub nodes_popped: u32,
    /// Calls to the sampler.
    pub sampler_calls: u32,
    /// Calls to the scorer.
    pub scorer_calls: u32,
    /// Segments sampled.
    pub segments_sampled: u32,
    /// Children not created because every score of their mode was zero or invalid.
    pub dead_children: u32,
    /// Largest open-list length seen.
    pub max_open: u32,
    /// Wall time by the injected clock, in milliseconds.
    pub elapsed_ms: u32,
}

/// Bins of [`ParticleDiagnostics::psi_histogram`] over `[0, 1]`.
pub const PSI_BINS: usize = 10;

/// What the particles and the discriminator did over one planning call: how many particles
/// the weights keep, how far apart a mode's samples end, what Ψ said about them, and how far
/// the weights moved a child's expected progress from its samples' plain mean. Sums, so a
/// caller divides by [`ParticleDiagnostics::children`] (or the per-mode counts); fixed size,
/// no heap. Filled for the particle variant and max-likelihood alike; with `k = 1` every
/// spread is 0 and every effective number 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleDiagnostics {
    /// Children created (one per mode per expansion that kept a particle).
    pub children: u32,
    /// Σ over children of the effective number `1 / Σ w²` of the accumulated scores
    /// `S' = γ^d·Ψ + S_parent`, normalised, before resampling (`k` when they are equal).
    pub ess_scores_sum: f32,
    /// The smallest of those.
    pub ess_scores_min: f32,
    /// Σ over children of the effective number of this expansion's Ψ alone, normalised: how
    /// many of the `k` fresh samples Ψ's own weights keep (`k` for a flat Ψ).
    pub ess_psi_sum: f32,
    /// The smallest of those.
    pub ess_psi_min: f32,
    /// Σ over children of the distinct samples the resampling drew (`k` draws with
    /// replacement; about `0.63·k` when the scores are equal).
    pub distinct_sum: u32,
    /// Histogram of Ψ over every finite sampled segment, [`PSI_BINS`] bins over `[0, 1]`
    /// (Ψ is clamped to it before use).
    pub psi_histogram: [u32; PSI_BINS],
    /// Σ Ψ and Σ Ψ² over the same segments (mean and spread).
    pub psi_sum: f32,
    /// Σ Ψ².
    pub psi_sq_sum: f32,
    /// Per candidate mode (the task's order): Σ over its children of the standard deviation of
    /// the `k` samples' end progress (screwdriver yaw in rad, card `y` in m).
    pub progress_spread_sum: [f32; MAX_MODES],
    /// Per candidate mode: children counted in [`Self::progress_spread_sum`].
    pub mode_children: [u32; MAX_MODES],
    /// Σ over children of |weighted − plain mean| of the `k` samples' end progress, the
    /// weights being this expansion's accumulated scores: how far Ψ moves the estimate.
    pub weight_shift_sum: f32,
}

impl ParticleDiagnostics {
    /// Nothing counted yet.
    pub const EMPTY: Self = Self {
        children: 0,
        ess_scores_sum: 0.0,
        ess_scores_min: f32::INFINITY,
        ess_psi_sum: 0.0,
        ess_psi_min: f32::INFINITY,
        distinct_sum: 0,
        psi_histogram: [0; PSI_BINS],
        psi_sum: 0.0,
        psi_sq_sum: 0.0,
        progress_spread_sum: [0.0; MAX_MODES],
        mode_children: [0; MAX_MODES],
        weight_shift_sum: 0.0,
    };

    /// Count one Ψ value (clamped to `[0, 1]`; a non-finite one is not counted).
    pub(crate) fn count_psi(&mut self, psi: f32) {
        if !psi.is_finite() {
            return;
        }
        let p = psi.clamp(0.0, 1.0);
        let bin = ((p * PSI_BINS as f32) as usize).min(PSI_BINS - 1);
        self.psi_histogram[bin] += 1;
        self.psi_sum += p;
        self.psi_sq_sum += p * p;
    }
}

impl Default for ParticleDiagnostics {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// The result of a planning call.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchReport {
    /// How the search ended.
    pub status: SearchStatus,
    /// The planned modes after the root (the executed mode of a replanning call excluded);
    /// empty when the root itself is the answer or there is no plan.
    pub modes: heapless::Vec<ModeId, MAX_PLAN_LEN>,
    /// The executed mode the root continued from (replanning), as given.
    pub executed: Option<ModeId>,
    /// Score-weighted mean of the result node's particle end states (raw layout; `cos`/`sin`
    /// columns are averaged as they are). Empty when there is no plan.
    pub terminal_state: heapless::Vec<f32, MAX_STATE_DIM>,
    /// Score-weighted mean progress (screwdriver yaw, card `y`) of the result node; NaN when
    /// there is no plan.
    pub expected_progress: f32,
    /// Terminal cost `φ(expected_progress)` of the result node.
    pub terminal_cost: f32,
    /// Cost-to-come `g` of the result node.
    pub cost_to_come: f32,
    /// Heuristic `h` of the result node.
    pub heuristic: f32,
    /// Particles the result node carries: `k`, or 1 for `k = 1` and the max-likelihood
    /// variant; 0 when there is no plan.
    pub particles: u8,
    /// Effective particles of the result node's normalised scores, `1 / Σ w²` (how many of
    /// them its weights keep); NaN when there is no plan.
    pub effective_particles: f32,
    /// Counters.
    pub stats: SearchStats,
    /// What the particles and Ψ did over the call.
    pub particle_diagnostics: ParticleDiagnostics,
}

impl SearchReport {
    /// A report without a plan.
    pub(crate) fn empty(status: SearchStatus, executed: Option<ModeId>) -> Self {
        Self {
            status,
            modes: heapless::Vec::new(),
            executed,
            terminal_state: heapless::Vec::new(),
            expected_progress: f32::NAN,
            terminal_cost: f32::NAN,
            cost_to_come: f32::NAN,
            heuristic: f32::NAN,
            particles: 0,
            effective_particles: f32::NAN,
            stats: SearchStats::default(),
            particle_diagnostics: ParticleDiagnostics::EMPTY,
        }
    }
}
