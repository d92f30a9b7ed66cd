//! Planning request and reply.

use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::size::{MaxSize, vec_max_size};

/// Most raw state floats a request or reply carries (the screwdriver's 16 state columns).
pub const MAX_STATE_DIM: usize = 16;
/// Most contact modes in a planned sequence.
pub const MAX_PLAN_MODES: usize = 16;

/// The manipulation task (`docs/contracts.md` §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum Task {
    /// Turning a screwdriver with index, middle and thumb.
    Screwdriver,
    /// Sliding a card with index and middle.
    Card,
}

/// How the A* cost-to-come `g` is accumulated (`spec/algorithms.md` §3.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum CostToCome {
    /// Sum of the per-segment expected costs along the sequence (the paper's semantics).
    Cumulative,
    /// Expected cost of the last segment only (the authors' code).
    LastSegment,
}

/// The card's goals: where each push aims and when the goal test passes (the kernel's
/// `task::CardGoals`; no effect on the screwdriver).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, MaxSize)]
pub enum CardGoals {
    /// The paper's: every push aims 2 cm on, the goal test is `ȳ ≤ o_G`.
    Paper,
    /// Ours: pushes stop at `o_G`, the goal test passes within 1 mm of it.
    #[default]
    Capped,
}

/// Which search the kernel runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum SearchVariant {
    /// Particle A* with `k` particles per node (DIPS).
    Particles,
    /// One stored trajectory per node, keeping the best-scored sample (ablation 5).
    MaxLikelihood,
}

/// Search settings; the kernel's `SearchConfig` maps onto exactly these fields.
///
/// A copy of that type on purpose: this crate does not depend on the kernel, and the wire
/// layout is frozen by the wire rules while the kernel's types may change;
/// `dips_kernel::wire_convert` converts between the two.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, MaxSize)]
pub struct SearchSettings {
    /// Particles per node.
    pub k: u16,
    /// Most modes in a planned sequence (not counting the executed previous mode).
    pub max_depth: u8,
    /// Score discount γ per depth.
    pub gamma: f32,
    /// Weight α of the terminal-objective term of the heuristic.
    pub alpha: f32,
    /// Weight β of the prior negative log-likelihood term of the heuristic.
    pub beta: f32,
    /// Floor of the Markov prior's transition probabilities.
    pub p_min: f32,
    /// Most node expansions before the search returns its best approximate plan (0: limited
    /// only by the planner's capacity).
    pub node_budget: u32,
    /// Wall-clock budget in milliseconds (0: none).
    pub time_budget_ms: u32,
    /// Seed of the kernel's random stream for this call.
    pub seed: u64,
    /// Cost-to-come accumulation.
    pub cost_to_come: CostToCome,
    /// Search variant.
    pub variant: SearchVariant,
}

impl Default for SearchSettings {
    /// The paper's values (`spec/algorithms.md` §6): k 16, depth 7, γ 0.9, α 1e4, β 1e3,
    /// p_min 0.1, 300 s, no node budget: the kernel's `SearchConfig::default`, field by field
    /// (a kernel test holds them equal).
    fn default() -> Self {
        Self {
            k: 16,
            max_depth: 7,
            gamma: 0.9,
            alpha: 1.0e4,
            beta: 1.0e3,
            p_min: 0.1,
            node_budget: 0,
            time_budget_ms: 300_000,
            seed: 0,
            cost_to_come: CostToCome::Cumulative,
            variant: SearchVariant::Particles,
        }
    }
}

/// Ask the kernel for a contact-mode sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanRequest {
    /// The task, which fixes the state layout and the mode table.
    pub task: Task,
    /// The current raw (not normalized) state, in the task's state-column order.
    pub start_state: Vec<f32, MAX_STATE_DIM>,
    /// Goal of the search: screwdriver yaw in radians (clockwise negative) or card y in
    /// metres.
    pub goal: f32,
    /// Search settings.
    pub settings: SearchSettings,
    /// When replanning, the mode just executed (index into the task's mode table).
    pub previous_mode: Option<u8>,
    /// The card's goals (ignored for the screwdriver).
    pub card_goals: CardGoals,
    /// The modes the plan may begin with, one bit per index into the task's mode table
    /// (bit `i` = mode `i`; every mode: `(1 << modes) - 1`). At least one of the task's modes
    /// and no bit beyond its table, else [`crate::error::RequestField::FirstModes`].
    pub first_modes: u8,
}

impl MaxSize for PlanRequest {
    const POSTCARD_MAX_SIZE: usize = Task::POSTCARD_MAX_SIZE
        + vec_max_size::<f32, MAX_STATE_DIM>()
        + f32::POSTCARD_MAX_SIZE
        + SearchSettings::POSTCARD_MAX_SIZE
        + Option::<u8>::POSTCARD_MAX_SIZE
        + CardGoals::POSTCARD_MAX_SIZE
        + u8::POSTCARD_MAX_SIZE;
}

/// Why a plan is only approximate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum ApproximateReason {
    /// The node budget ran out.
    NodeBudget,
    /// The time budget ran out.
    TimeBudget,
    /// Every node was expanded without reaching the goal.
    Exhausted,
    /// A capacity of the kernel's planner (nodes, open list) ran out during the search.
    Capacity {
        /// Which one.
        capacity: PlanCapacity,
    },
    /// The diffusion sampler (or its model engine) failed.
    SamplerFailed,
    /// The discriminator (or its model engine) failed.
    ScorerFailed,
    /// A `Cancel` request stopped the search (appended).
    Cancelled,
}

/// A capacity of the kernel's planner that a request needed more of (the wire copy of the
/// kernel's `search::Capacity`, see [`SearchSettings`] for why it is a copy).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum PlanCapacity {
    /// `k` exceeds the planner's particles per node.
    Particles,
    /// The node arena is full.
    Nodes,
    /// The open list is full.
    OpenList,
    /// The task's state has more columns than the planner holds.
    StateDim,
    /// A segment has more floats (`T·D`) than the planner holds.
    SegmentFloats,
    /// The task has more modes than the planner expands.
    Modes,
}

/// A [`SearchSettings`] field that is out of range.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum SettingsField {
    /// `k` is zero.
    K,
    /// `max_depth` is zero or above [`MAX_PLAN_MODES`].
    MaxDepth,
    /// `gamma` is not in `(0, 1]`.
    Gamma,
    /// `alpha` is negative or not finite.
    Alpha,
    /// `beta` is negative or not finite.
    Beta,
    /// `p_min` is not in `[0, 1)` or too large for the task's mode count.
    PMin,
}

/// Outcome of a search (mirror of the kernel's search status).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum PlanStatus {
    /// A sequence whose expected terminal state meets the goal.
    Found,
    /// The best sequence found, which does not meet the goal.
    Approximate {
        /// Why the search stopped.
        reason: ApproximateReason,
    },
    /// No sequence at all (nothing beyond the root could be expanded).
    NoPlan,
    /// The start state is invalid for the task.
    InvalidStart,
    /// The goal is invalid for the task.
    InvalidGoal,
    /// The search was cancelled.
    Cancelled,
    /// A search setting is out of range; nothing was searched.
    InvalidSettings {
        /// The first bad field.
        field: SettingsField,
    },
    /// The kernel's models or prior do not fit the task (dimensions, mode count); nothing
    /// was searched.
    InvalidProblem,
    /// The request needs more than the kernel's planner holds; nothing was searched.
    CapacityExceeded {
        /// Which capacity.
        capacity: PlanCapacity,
    },
}

/// Search statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, MaxSize)]
pub struct PlanStats {
    /// Nodes popped and expanded.
    pub nodes_expanded: u32,
    /// Child nodes created.
    pub nodes_generated: u32,
    /// Diffusion sampler calls.
    pub sampler_calls: u32,
    /// Discriminator calls.
    pub discriminator_calls: u32,
    /// Wall-clock time of the search in milliseconds.
    pub elapsed_ms: u32,
}

/// The kernel's answer to a [`PlanRequest`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanReply {
    /// Planned contact modes, first to execute first (indices into the task's mode table).
    pub modes: Vec<u8, MAX_PLAN_MODES>,
    /// Expected (score-weighted) raw terminal state of the plan.
    pub terminal_state: Vec<f32, MAX_STATE_DIM>,
    /// Outcome.
    pub status: PlanStatus,
    /// Statistics.
    pub stats: PlanStats,
}

impl MaxSize for PlanReply {
    const POSTCARD_MAX_SIZE: usize = vec_max_size::<u8, MAX_PLAN_MODES>()
        + vec_max_size::<f32, MAX_STATE_DIM>()
        + PlanStatus::POSTCARD_MAX_SIZE
        + PlanStats::POSTCARD_MAX_SIZE;
}
