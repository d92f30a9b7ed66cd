//! The DIPS contact-sequence search: an A* over contact-mode sequences whose nodes carry
//! particles of diffused trajectories (paper Algorithm 1, `spec/algorithms.md` §3).
//!
//! - [`config`]: [`SearchConfig`] (paper defaults) and its validation.
//! - [`traits`]: the sampler `M`, the discriminator `Ψ` and the task costs, as traits.
//! - [`particles`]: the arithmetic of `propagate_variability` over slices.
//! - [`planner`]: the fixed-capacity [`Planner`] and its [`Problem`].
//! - [`report`]: [`SearchReport`], [`SearchStatus`] and the counters.
//!
//! `docs/search.md` explains the design and the decisions taken where paper and code differ.

pub mod config;
pub mod particles;
pub mod planner;
pub mod report;
pub mod traits;

pub use config::{
    CostToCome, MAX_PLAN_LEN, SCREWDRIVER_NODE_BUDGET, SearchConfig, SearchOverrides, SearchVariant,
};
pub use planner::{PaperPlanner, Planner, Problem};
pub use report::{
    ApproximateReason, Capacity, PSI_BINS, ParticleDiagnostics, SearchReport, SearchStats,
    SearchStatus,
};
pub use traits::{SegmentSampler, SegmentScorer, TaskObjective};
