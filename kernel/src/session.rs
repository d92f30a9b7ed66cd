//! One planning session: engines → adapters → planner, the single place that wiring is
//! written. `dips plan`, the benches, the firmware, the wire path, the tests and the DIPS
//! replanning loop all go through it.
//!
//! A call is described by a [`PlanSpec`] (task, search settings with seed and time budget,
//! sampler settings, prior, start state, goal, executed mode) and answered with the
//! planner's [`SearchReport`]:
//!
//! - [`plan_with_engines`]: two model engines (tract, the kernel interpreter, or anything
//!   implementing the engine traits) are wrapped in the diffusion sampler and discriminator
//!   adapters, whose buffers come from one caller-given work area ([`SessionLayout`]);
//! - [`plan_with_adapters`]: a ready sampler and scorer (the benchmark's synthetic ones, or
//!   adapters kept across calls).
//!
//! Nothing here allocates. A wire transport is the same [`PlanSpec`] sent as `SetPrior`,
//! `SetSampler` and a `PlanRequest` ([`PlanSpec::to_request`]) and answered by the firmware
//! through [`plan_with_engines`].

use core::fmt;

use crate::adapters::{
    AdapterError, DiffusionSegmentSampler, DiscriminatorScorer, SamplerAdapterLayout,
    ScorerAdapterLayout,
};
use crate::budget::Clock;
use crate::diffusion::SamplerConfig;
use crate::engine::{DenoiserEngine, DiscriminatorEngine, ModelDims};
use crate::mode::{MAX_STATE_DIM, ModeId, ModeSet, Task};
use crate::prior::MarkovPrior;
use crate::search::config::ConfigError;
use crate::search::{Planner, Problem, SearchConfig, SearchReport, SegmentSampler, SegmentScorer};
use crate::task::{CARD_GOAL_Y, CardGoals, Objective, ScrewdriverObjective};

/// Everything one planning call needs besides the models and the planner's memory.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSpec {
    /// The task: its modes, sizes and costs.
    pub task: Task,
    /// The search settings, the seed and the time budget included.
    pub search: SearchConfig,
    /// The diffusion sampler's settings (used when [`plan_with_engines`] builds the sampler).
    pub sampler: SamplerConfig,
    /// The contact-mode prior (the search floors it at `search.p_min`).
    pub prior: MarkovPrior,
    /// The raw start state (`docs/contracts.md` §2 state columns).
    pub start: heapless::Vec<f32, MAX_STATE_DIM>,
    /// The task objective for the search goal ([`Objective::for_goal`]).
    pub objective: Objective,
    /// The mode executed just before (replanning), `None` on a trial's first call.
    pub executed: Option<ModeId>,
    /// The modes the plan may begin with ([`Problem::first_modes`]); every mode of the task
    /// by default.
    pub first_modes: ModeSet,
}

/// The [`PlanSpec`] field that is not acceptable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpecError {
    /// The start state is not the task's state columns, or not finite.
    StartState,
    /// The goal is not finite.
    Goal,
    /// A search setting is out of range.
    Settings(ConfigError),
    /// The prior is not over the task's modes, or cannot be floored at `p_min`.
    Prior,
    /// The executed mode is not one of the task's.
    PreviousMode,
    /// The first modes name none of the task's modes, or a mode beyond its table.
    FirstModes,
}

impl fmt::Display for SpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::StartState => {
                f.write_str("start state: not the task's state columns, or not finite")
            }
            Self::Goal => f.write_str("goal: not finite"),
            Self::Settings(e) => write!(f, "{e}"),
            Self::Prior => f.write_str("prior: not over the task's modes, or p_min too large"),
            Self::PreviousMode => f.write_str("previous mode: not a mode of the task"),
            Self::FirstModes => {
                f.write_str("first modes: none of the task's modes, or one beyond its table")
            }
        }
    }
}

impl core::error::Error for SpecError {}

impl PlanSpec {
    /// A call for `task` from `start` to the search goal `goal` with the task's own settings
    /// ([`SearchConfig::for_task`]), the paper's prior ([`MarkovPrior::paper`] at the
    /// settings' `p_min`) and the default sampler. Every field is public: change what differs.
    pub fn new(task: Task, start: &[f32], goal: f32) -> Result<Self, SpecError> {
        let search = SearchConfig::for_task(task);
        let prior = MarkovPrior::paper(task, search.p_min).map_err(|_| SpecError::Prior)?;
        Self::with_settings(task, start, goal, search, prior)
    }

    /// A call with the given settings and prior (default sampler), checked ([`Self::check`]).
    pub fn with_settings(
        task: Task,
        start: &[f32],
        goal: f32,
        search: SearchConfig,
        prior: MarkovPrior,
    ) -> Result<Self, SpecError> {
        if start.len() != task.dims().state_dim || start.iter().any(|v| !v.is_finite()) {
            return Err(SpecError::StartState);
        }
        let objective =
            Objective::for_goal(task, start, goal, CardGoals::default()).ok_or(SpecError::Goal)?;
        let spec = Self {
            task,
            search,
            sampler: SamplerConfig::default(),
            prior,
            start: heapless::Vec::from_slice(start).map_err(|_| SpecError::StartState)?,
            objective,
            executed: None,
            first_modes: ModeSet::all(task),
        };
        spec.check()?;
        Ok(spec)
    }

    /// The paper's search goal from `start`: the screwdriver's yaw − π/3, the card's
    /// `y = −0.06` m. `None` when the start is too short.
    pub fn paper_goal(task: Task, start: &[f32]) -> Option<f32> {
        match task {
            Task::Screwdriver => ScrewdriverObjective::from_state(start).map(|o| o.goal_yaw),
            Task::Card => Some(CARD_GOAL_Y),
        }
    }

    /// The same call with the screwdriver's start yaw known unwrapped (`yaw`, radians, as a
    /// host tracks it over whole turns). The start's `atan2(sin, cos)` yaw is then taken on the
    /// branch nearest `yaw`, not within π of the goal ([`Objective::for_goal`]), so a goal more
    /// than π from the start (a full turn, −2π) is searched as given. No effect for the card.
    /// [`SpecError::Goal`] when `yaw` is not finite.
    pub fn with_start_yaw(mut self, yaw: f32) -> Result<Self, SpecError> {
        if let Objective::Screwdriver(o) = &mut self.objective {
            if !yaw.is_finite() {
                return Err(SpecError::Goal);
            }
            let raw = ScrewdriverObjective::raw_yaw(&self.start).ok_or(SpecError::StartState)?;
            o.reference_yaw = yaw + crate::task::wrap_angle(raw - yaw);
        }
        Ok(self)
    }

    /// The same call with the card's `goals` (where its pushes aim and its goal test; no
    /// effect for the screwdriver).
    pub fn with_card_goals(mut self, goals: CardGoals) -> Self {
        if let Objective::Card(o) = &mut self.objective {
            o.goals = goals;
        }
        self
    }

    /// The card's goals of this call ([`CardGoals::default`] for the screwdriver).
    pub fn card_goals(&self) -> CardGoals {
        match self.objective {
            Objective::Card(o) => o.goals,
            Objective::Screwdriver(_) => CardGoals::default(),
        }
    }

    /// The same call with another seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.search.seed = seed;
        self
    }

    /// The same call with another wall-clock budget (ms; 0 = none).
    pub fn with_time_budget_ms(mut self, ms: u32) -> Self {
        self.search.time_budget_ms = ms;
        self
    }

    /// The same call after executing `mode` (replanning).
    pub fn with_executed(mut self, mode: Option<ModeId>) -> Self {
        self.executed = mode;
        self
    }

    /// The search goal (screwdriver yaw in radians, card `y` in metres).
    pub fn goal(&self) -> f32 {
        self.objective.goal()
    }

    /// Check the fields the search would otherwise answer with a failure status; the first
    /// bad one is named.
    pub fn check(&self) -> Result<(), SpecError> {
        if self.start.len() != self.task.dims().state_dim
            || self.start.iter().any(|v| !v.is_finite())
        {
            return Err(SpecError::StartState);
        }
        if !self.goal().is_finite() {
            return Err(SpecError::Goal);
        }
        self.search.validate().map_err(SpecError::Settings)?;
        if self.prior.modes() != self.task.mode_count()
            || self.prior.with_floor(self.search.p_min).is_err()
        {
            return Err(SpecError::Prior);
        }
        if self
            .executed
            .is_some_and(|m| m.index() >= self.task.mode_count())
        {
            return Err(SpecError::PreviousMode);
        }
        if !self.first_modes.valid_for(self.task) {
            return Err(SpecError::FirstModes);
        }
        Ok(())
    }

    /// Segments per sampler call: every candidate mode times `k`.
    pub fn segments_per_call(&self) -> usize {
        self.task.mode_count() * usize::from(self.search.k)
    }

    /// The planner's problem.
    pub fn problem(&self) -> Problem<'_> {
        Problem {
            task: self.task,
            dims: self.task.dims(),
            start: &self.start,
            executed: self.executed,
            prior: &self.prior,
            first_modes: self.first_modes,
        }
    }
}

/// How [`plan_with_engines`] splits its work area between the two adapters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SessionLayout {
    /// The diffusion sampler adapter's buffer.
    pub sampler: SamplerAdapterLayout,
    /// The discriminator adapter's buffer.
    pub scorer: ScorerAdapterLayout,
}

impl SessionLayout {
    /// Buffers for sampler calls of up to `segments` segments ([`PlanSpec::segments_per_call`])
    /// with `chunk` segments per engine call (any `chunk ≥ 1` gives the same plan; a larger
    /// one fewer engine calls).
    pub const fn new(model: ModelDims, segments: usize, chunk: usize) -> Self {
        Self {
            sampler: SamplerAdapterLayout::new(model, segments, chunk),
            scorer: ScorerAdapterLayout::new(model, chunk),
        }
    }

    /// Total `f32`s of the work area.
    pub const fn total(&self) -> usize {
        self.sampler.total() + self.scorer.total()
    }
}

/// Why a session did not reach the planner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SessionError {
    /// The sampler adapter refused its denoiser or buffer.
    Sampler(AdapterError),
    /// The scorer adapter refused its discriminator or buffer.
    Scorer(AdapterError),
}

impl fmt::Display for SessionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Sampler(e) => write!(f, "denoiser adapter: {e}"),
            Self::Scorer(e) => write!(f, "discriminator adapter: {e}"),
        }
    }
}

impl core::error::Error for SessionError {}

/// Plan `spec` with a ready sampler and scorer (adapters → planner). Every outcome of the
/// search is the report's status; the same spec (seed included) and models give a
/// bit-identical report.
pub fn plan_with_adapters<
    const K: usize,
    const N: usize,
    const O: usize,
    const S: usize,
    Sa,
    Sc,
    Cl,
>(
    planner: &mut Planner<K, N, O, S>,
    spec: &PlanSpec,
    sampler: &mut Sa,
    scorer: &mut Sc,
    clock: &mut Cl,
) -> SearchReport
where
    Sa: SegmentSampler,
    Sc: SegmentScorer,
    Cl: Clock,
{
    planner.plan(
        &spec.search,
        &spec.problem(),
        sampler,
        scorer,
        &spec.objective,
        clock,
    )
}

/// How `task`'s sampled segments are made to continue from their starts
/// ([`DiffusionSegmentSampler::set_start_anchor`]), in the planner and in CSVTO's
/// initialisation alike.
///
/// The screwdriver: its yaw is a symmetry (an axisymmetric handle); the shipped models'
/// demos start their segments at −1.07 … 0 rad (turns) and −1.03 … −0.41 (regrasps), so
/// starts are sampled with the yaw kept within [[`SCREWDRIVER_MODEL_YAW_MIN`], 0] (with −1.0
/// the search stalled, `docs/online.md`); the yaw and the contact fingers' joints are anchored
/// at the start (measured: `docs/online.md`, "Anchored at the start"). The card: nothing (its
/// heading is no symmetry, a rectangle at a table edge; its models' first rows were not
/// measured to jump).
pub fn start_anchor(task: Task) -> crate::adapters::StartAnchor {
    match task {
        Task::Screwdriver => crate::adapters::StartAnchor {
            angle: Some(crate::adapters::InvariantAngle {
                cos_column: task.layout().angle_cos(),
                lo: SCREWDRIVER_MODEL_YAW_MIN,
                hi: 0.0,
            }),
            contact_joints: true,
        },
        Task::Card => crate::adapters::StartAnchor::NONE,
    }
}

/// The lowest screwdriver start yaw the planner asks the models about (rad); see
/// [`start_anchor`].
pub const SCREWDRIVER_MODEL_YAW_MIN: f32 = -0.6;

/// Plan `spec` with two model engines (engines → adapters → planner): the denoiser is wrapped
/// in the diffusion sampler with `spec.sampler` (and the task's [`start_anchor`]), the
/// discriminator in the scorer, both with buffers from `work` as `layout` splits it.
pub fn plan_with_engines<
    const K: usize,
    const N: usize,
    const O: usize,
    const S: usize,
    De,
    Di,
    Cl,
>(
    planner: &mut Planner<K, N, O, S>,
    spec: &PlanSpec,
    denoiser: De,
    discriminator: Di,
    layout: &SessionLayout,
    work: &mut [f32],
    clock: &mut Cl,
) -> Result<SearchReport, SessionError>
where
    De: DenoiserEngine,
    Di: DiscriminatorEngine,
    Cl: Clock,
{
    let split = layout.sampler.total().min(work.len());
    let (sampler_buf, scorer_buf) = work.split_at_mut(split);
    let mut sampler =
        DiffusionSegmentSampler::new(denoiser, spec.sampler, sampler_buf, &layout.sampler)
            .map_err(SessionError::Sampler)?;
    sampler.set_start_anchor(start_anchor(spec.task));
    let mut scorer = DiscriminatorScorer::new(discriminator, scorer_buf, &layout.scorer)
        .map_err(SessionError::Scorer)?;
    Ok(plan_with_adapters(
        planner,
        spec,
        &mut sampler,
        &mut scorer,
        clock,
    ))
}
