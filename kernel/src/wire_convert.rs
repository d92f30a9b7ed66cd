//! The kernel's side of the wire: conversions between the search's types and the
//! `dips-wire` messages, and [`plan_request`], which answers a [`PlanRequest`] with a
//! [`PlanReply`] through a real planning call.
//!
//! The mapping is one to one where both sides have the value: [`SearchConfig`] ↔
//! [`SearchSettings`] (same fields, budgets `0` = unlimited on both sides), tasks, cost-to-come,
//! variants, mode ids (the index into the task's mode table), and every [`SearchStatus`] ↔
//! [`PlanStatus`] (the wire has two statuses the kernel never produces: `NoPlan` and
//! `Cancelled`). The reply keeps the counters the wire carries; the report's expected
//! progress, `g` and `h` stay on the kernel side.

use core::fmt;

use dips_wire::{
    ApproximateReason as WireApproximate, CardGoals as WireCardGoals, CostToCome as WireCostToCome,
    MAX_PLAN_MODES, PlanCapacity, PlanReply, PlanRequest, PlanStats, PlanStatus, PriorTable,
    RequestField, SamplerMethod, SamplerSettings, SearchSettings, SearchVariant as WireVariant,
    SettingsField, Task as WireTask, WireError,
};

use crate::budget::Clock;
use crate::diffusion::{SamplerConfig, SamplingMethod};
use crate::mode::{MAX_STATE_DIM, ModeId, ModeSet, SegmentDims, Task};
use crate::prior::MarkovPrior;
use crate::search::config::ConfigError;
use crate::search::{
    ApproximateReason, Capacity, CostToCome, MAX_PLAN_LEN, Planner, Problem, SearchConfig,
    SearchReport, SearchStats, SearchStatus, SearchVariant, SegmentSampler, SegmentScorer,
};
use crate::session::{PlanSpec, SpecError, plan_with_adapters};
use crate::task::{CardGoals, Objective};

const _: () = assert!(MAX_PLAN_LEN == MAX_PLAN_MODES, "plan lengths must agree");
const _: () = assert!(
    MAX_STATE_DIM == dips_wire::MAX_STATE_DIM,
    "state sizes must agree"
);

impl From<WireTask> for Task {
    fn from(t: WireTask) -> Self {
        match t {
            WireTask::Screwdriver => Task::Screwdriver,
            WireTask::Card => Task::Card,
        }
    }
}

impl From<Task> for WireTask {
    fn from(t: Task) -> Self {
        match t {
            Task::Screwdriver => WireTask::Screwdriver,
            Task::Card => WireTask::Card,
        }
    }
}

impl From<WireCardGoals> for CardGoals {
    fn from(c: WireCardGoals) -> Self {
        match c {
            WireCardGoals::Paper => CardGoals::Paper,
            WireCardGoals::Capped => CardGoals::Capped,
        }
    }
}

impl From<CardGoals> for WireCardGoals {
    fn from(c: CardGoals) -> Self {
        match c {
            CardGoals::Paper => WireCardGoals::Paper,
            CardGoals::Capped => WireCardGoals::Capped,
        }
    }
}

impl From<WireCostToCome> for CostToCome {
    fn from(c: WireCostToCome) -> Self {
        match c {
            WireCostToCome::Cumulative => CostToCome::Cumulative,
            WireCostToCome::LastSegment => CostToCome::LastSegment,
        }
    }
}

impl From<CostToCome> for WireCostToCome {
    fn from(c: CostToCome) -> Self {
        match c {
            CostToCome::Cumulative => WireCostToCome::Cumulative,
            CostToCome::LastSegment => WireCostToCome::LastSegment,
        }
    }
}

impl From<WireVariant> for SearchVariant {
    fn from(v: WireVariant) -> Self {
        match v {
            WireVariant::Particles => SearchVariant::Particles,
            WireVariant::MaxLikelihood => SearchVariant::MaxLikelihood,
        }
    }
}

impl From<SearchVariant> for WireVariant {
    fn from(v: SearchVariant) -> Self {
        match v {
            SearchVariant::Particles => WireVariant::Particles,
            SearchVariant::MaxLikelihood => WireVariant::MaxLikelihood,
        }
    }
}

impl From<SearchSettings> for SearchConfig {
    /// Field by field; `node_budget` and `time_budget_ms` of `0` mean unlimited on both
    /// sides. Not validated here ([`SearchConfig::validate`]).
    fn from(s: SearchSettings) -> Self {
        Self {
            k: s.k,
            max_depth: s.max_depth,
            gamma: s.gamma,
            alpha: s.alpha,
            beta: s.beta,
            p_min: s.p_min,
            node_budget: s.node_budget,
            time_budget_ms: s.time_budget_ms,
            seed: s.seed,
            cost_to_come: s.cost_to_come.into(),
            variant: s.variant.into(),
        }
    }
}

impl From<SearchConfig> for SearchSettings {
    fn from(c: SearchConfig) -> Self {
        Self {
            k: c.k,
            max_depth: c.max_depth,
            gamma: c.gamma,
            alpha: c.alpha,
            beta: c.beta,
            p_min: c.p_min,
            node_budget: c.node_budget,
            time_budget_ms: c.time_budget_ms,
            seed: c.seed,
            cost_to_come: c.cost_to_come.into(),
            variant: c.variant.into(),
        }
    }
}

impl From<Capacity> for PlanCapacity {
    fn from(c: Capacity) -> Self {
        match c {
            Capacity::Particles => PlanCapacity::Particles,
            Capacity::Nodes => PlanCapacity::Nodes,
            Capacity::OpenList => PlanCapacity::OpenList,
            Capacity::StateDim => PlanCapacity::StateDim,
            Capacity::SegmentFloats => PlanCapacity::SegmentFloats,
            Capacity::Modes => PlanCapacity::Modes,
        }
    }
}

impl From<PlanCapacity> for Capacity {
    fn from(c: PlanCapacity) -> Self {
        match c {
            PlanCapacity::Particles => Capacity::Particles,
            PlanCapacity::Nodes => Capacity::Nodes,
            PlanCapacity::OpenList => Capacity::OpenList,
            PlanCapacity::StateDim => Capacity::StateDim,
            PlanCapacity::SegmentFloats => Capacity::SegmentFloats,
            PlanCapacity::Modes => Capacity::Modes,
        }
    }
}

impl From<ConfigError> for SettingsField {
    fn from(e: ConfigError) -> Self {
        match e {
            ConfigError::K => SettingsField::K,
            ConfigError::MaxDepth => SettingsField::MaxDepth,
            ConfigError::Gamma => SettingsField::Gamma,
            ConfigError::Alpha => SettingsField::Alpha,
            ConfigError::Beta => SettingsField::Beta,
            ConfigError::PMin => SettingsField::PMin,
        }
    }
}

impl From<SettingsField> for ConfigError {
    fn from(f: SettingsField) -> Self {
        match f {
            SettingsField::K => ConfigError::K,
            SettingsField::MaxDepth => ConfigError::MaxDepth,
            SettingsField::Gamma => ConfigError::Gamma,
            SettingsField::Alpha => ConfigError::Alpha,
            SettingsField::Beta => ConfigError::Beta,
            SettingsField::PMin => ConfigError::PMin,
        }
    }
}

impl From<ApproximateReason> for WireApproximate {
    fn from(r: ApproximateReason) -> Self {
        match r {
            ApproximateReason::NodeBudget => WireApproximate::NodeBudget,
            ApproximateReason::TimeBudget => WireApproximate::TimeBudget,
            ApproximateReason::Exhausted => WireApproximate::Exhausted,
            ApproximateReason::Capacity(c) => WireApproximate::Capacity { capacity: c.into() },
            ApproximateReason::SamplerFailed => WireApproximate::SamplerFailed,
            ApproximateReason::ScorerFailed => WireApproximate::ScorerFailed,
            ApproximateReason::Cancelled => WireApproximate::Cancelled,
        }
    }
}

impl From<WireApproximate> for ApproximateReason {
    fn from(r: WireApproximate) -> Self {
        match r {
            WireApproximate::NodeBudget => ApproximateReason::NodeBudget,
            WireApproximate::TimeBudget => ApproximateReason::TimeBudget,
            WireApproximate::Exhausted => ApproximateReason::Exhausted,
            WireApproximate::Capacity { capacity } => ApproximateReason::Capacity(capacity.into()),
            WireApproximate::SamplerFailed => ApproximateReason::SamplerFailed,
            WireApproximate::ScorerFailed => ApproximateReason::ScorerFailed,
            WireApproximate::Cancelled => ApproximateReason::Cancelled,
        }
    }
}

impl From<SearchStatus> for PlanStatus {
    fn from(s: SearchStatus) -> Self {
        match s {
            SearchStatus::Found => PlanStatus::Found,
            SearchStatus::Approximate(r) => PlanStatus::Approximate { reason: r.into() },
            SearchStatus::InvalidConfig(e) => PlanStatus::InvalidSettings { field: e.into() },
            SearchStatus::CapacityExceeded(c) => {
                PlanStatus::CapacityExceeded { capacity: c.into() }
            }
            SearchStatus::InvalidProblem => PlanStatus::InvalidProblem,
            SearchStatus::InvalidStart => PlanStatus::InvalidStart,
            SearchStatus::InvalidGoal => PlanStatus::InvalidGoal,
        }
    }
}

/// A wire status the kernel's search never produces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NoSearchStatus(pub PlanStatus);

impl fmt::Display for NoSearchStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "wire status {:?} has no kernel search status", self.0)
    }
}

impl core::error::Error for NoSearchStatus {}

impl TryFrom<PlanStatus> for SearchStatus {
    type Error = NoSearchStatus;

    fn try_from(s: PlanStatus) -> Result<Self, NoSearchStatus> {
        Ok(match s {
            PlanStatus::Found => SearchStatus::Found,
            PlanStatus::Approximate { reason } => SearchStatus::Approximate(reason.into()),
            PlanStatus::InvalidSettings { field } => SearchStatus::InvalidConfig(field.into()),
            PlanStatus::CapacityExceeded { capacity } => {
                SearchStatus::CapacityExceeded(capacity.into())
            }
            PlanStatus::InvalidProblem => SearchStatus::InvalidProblem,
            PlanStatus::InvalidStart => SearchStatus::InvalidStart,
            PlanStatus::InvalidGoal => SearchStatus::InvalidGoal,
            PlanStatus::NoPlan | PlanStatus::Cancelled => return Err(NoSearchStatus(s)),
        })
    }
}

impl From<&SearchStats> for PlanStats {
    /// The counters the wire carries (`discriminator_calls` = the scorer's calls).
    fn from(s: &SearchStats) -> Self {
        Self {
            nodes_expanded: s.nodes_expanded,
            nodes_generated: s.nodes_generated,
            sampler_calls: s.sampler_calls,
            discriminator_calls: s.scorer_calls,
            elapsed_ms: s.elapsed_ms,
        }
    }
}

/// A mode id as the wire carries it (its index in the task's mode table).
pub const fn mode_to_wire(mode: ModeId) -> u8 {
    mode.0
}

/// A wire mode index as a mode of `task`; `None` when the task has no such mode.
pub fn mode_from_wire(task: Task, index: u8) -> Option<ModeId> {
    let id = ModeId(index);
    (id.index() < task.mode_count()).then_some(id)
}

impl From<&SearchReport> for PlanReply {
    /// The planned modes, the expected terminal state, the status and the counters.
    fn from(r: &SearchReport) -> Self {
        let mut modes = heapless::Vec::new();
        for &m in &r.modes {
            // Both sides hold MAX_PLAN_LEN == MAX_PLAN_MODES modes: cannot fail.
            let _ = modes.push(mode_to_wire(m));
        }
        let mut terminal_state = heapless::Vec::new();
        // Both sides hold MAX_STATE_DIM floats: cannot fail.
        let _ = terminal_state.extend_from_slice(&r.terminal_state);
        PlanReply {
            modes,
            terminal_state,
            status: r.status.into(),
            stats: (&r.stats).into(),
        }
    }
}

/// A [`PlanRequest`], checked and converted: everything a planning call needs except the
/// prior and the models.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanInputs {
    /// The task.
    pub task: Task,
    /// Its segment sizes (`docs/contracts.md` §2).
    pub dims: SegmentDims,
    /// The search settings.
    pub config: SearchConfig,
    /// The raw start state.
    pub start: heapless::Vec<f32, MAX_STATE_DIM>,
    /// The mode executed before (replanning).
    pub executed: Option<ModeId>,
    /// The task's objective for the request's goal ([`Objective::for_goal`]).
    pub objective: Objective,
    /// The modes the plan may begin with.
    pub first_modes: ModeSet,
}

impl PlanInputs {
    /// Check a request: the start state has the task's state columns and is finite, the goal
    /// is finite, the settings are valid, the previous mode is one of the task's, the first
    /// modes name at least one of the task's modes and none beyond. The first bad field is
    /// named.
    pub fn from_request(request: &PlanRequest) -> Result<Self, RequestField> {
        let task = Task::from(request.task);
        let dims = task.dims();
        let start = request.start_state.clone();
        if start.len() != dims.state_dim || start.iter().any(|v| !v.is_finite()) {
            return Err(RequestField::StartState);
        }
        let objective = Objective::for_goal(task, &start, request.goal, request.card_goals.into())
            .ok_or(RequestField::Goal)?;
        let config = SearchConfig::from(request.settings);
        config.validate().map_err(|_| RequestField::Settings)?;
        let executed = match request.previous_mode {
            None => None,
            Some(i) => Some(mode_from_wire(task, i).ok_or(RequestField::PreviousMode)?),
        };
        let first_modes = ModeSet(request.first_modes);
        if !first_modes.valid_for(task) {
            return Err(RequestField::FirstModes);
        }
        Ok(Self {
            task,
            dims,
            config,
            start,
            executed,
            objective,
            first_modes,
        })
    }

    /// The search problem over `prior`.
    pub fn problem<'a>(&'a self, prior: &'a MarkovPrior) -> Problem<'a> {
        Problem {
            task: self.task,
            dims: self.dims,
            start: &self.start,
            executed: self.executed,
            prior,
            first_modes: self.first_modes,
        }
    }
}

impl PlanInputs {
    /// The session call of these inputs with the `prior` and `sampler` the kernel holds
    /// (`SetPrior`, `SetSampler`).
    pub fn into_spec(self, prior: MarkovPrior, sampler: SamplerConfig) -> PlanSpec {
        PlanSpec {
            task: self.task,
            search: self.config,
            sampler,
            prior,
            start: self.start,
            objective: self.objective,
            executed: self.executed,
            first_modes: self.first_modes,
        }
    }
}

impl From<SpecError> for RequestField {
    fn from(e: SpecError) -> Self {
        match e {
            SpecError::StartState => RequestField::StartState,
            SpecError::Goal => RequestField::Goal,
            SpecError::Settings(_) => RequestField::Settings,
            SpecError::Prior => RequestField::Prior,
            SpecError::PreviousMode => RequestField::PreviousMode,
            SpecError::FirstModes => RequestField::FirstModes,
        }
    }
}

impl PlanSpec {
    /// The `PlanRequest` of this call, as a wire transport sends it (the prior and sampler
    /// go as `SetPrior` and `SetSampler` before it). Answered on the other side through
    /// [`PlanInputs::from_request`] and [`PlanInputs::into_spec`], it is the same spec.
    pub fn to_request(&self) -> PlanRequest {
        PlanRequest {
            task: self.task.into(),
            start_state: self.start.clone(),
            goal: self.goal(),
            settings: self.search.into(),
            previous_mode: self.executed.map(mode_to_wire),
            card_goals: self.card_goals().into(),
            first_modes: self.first_modes.0,
        }
    }
}

/// The task and prior of a `SetPrior` table: `modes + modes²` non-negative finite values
/// for the task's mode count, no row summing to zero (each row is renormalised). A bad table
/// is [`RequestField::Prior`].
pub fn prior_from_table(table: &PriorTable) -> Result<(Task, MarkovPrior), RequestField> {
    let task = Task::from(table.task);
    let m = task.mode_count();
    let values = &table.probabilities;
    if values.len() != m + m * m {
        return Err(RequestField::Prior);
    }
    let (start, rest) = values.split_at(m);
    let mut rows: [&[f32]; crate::mode::MAX_MODES] = [&[]; crate::mode::MAX_MODES];
    for (row, chunk) in rows.iter_mut().zip(rest.chunks_exact(m)) {
        *row = chunk;
    }
    let prior = MarkovPrior::from_rows(start, &rows[..m]).map_err(|_| RequestField::Prior)?;
    Ok((task, prior))
}

/// The sampler settings of a `SetSampler` request: a DDPM noise factor in `[0, 1]`, at least
/// one strided step (DDIM, DDIM with η in `[0, 1]`, strided DDPM), a finite guidance weight.
/// Bad settings are [`RequestField::Sampler`]. Whether the steps fit the model is checked
/// when sampling.
pub fn sampler_from_settings(settings: &SamplerSettings) -> Result<SamplerConfig, RequestField> {
    let method = match settings.method {
        SamplerMethod::Ddpm { noise_factor } if (0.0..=1.0).contains(&noise_factor) => {
            SamplingMethod::Ddpm { noise_factor }
        }
        SamplerMethod::Ddim { steps } if steps > 0 => SamplingMethod::Ddim { steps, eta: 0.0 },
        SamplerMethod::DdimEta { steps, eta } if steps > 0 && (0.0..=1.0).contains(&eta) => {
            SamplingMethod::Ddim { steps, eta }
        }
        SamplerMethod::DdpmStrided {
            steps,
            noise_factor,
        } if steps > 0 && (0.0..=1.0).contains(&noise_factor) => SamplingMethod::DdpmStrided {
            steps,
            noise_factor,
        },
        _ => return Err(RequestField::Sampler),
    };
    if !settings.guidance_weight.is_finite() {
        return Err(RequestField::Sampler);
    }
    Ok(SamplerConfig {
        method,
        guidance_weight: settings.guidance_weight,
        ..SamplerConfig::default()
    })
}

/// The `SetPrior` table of `prior` for `task` (`p(c₀)`, then one transition row per mode).
/// `None` when the prior is not over the task's modes.
pub fn table_from_prior(task: Task, prior: &MarkovPrior) -> Option<PriorTable> {
    let m = task.mode_count();
    if prior.modes() != m {
        return None;
    }
    let mut probabilities = heapless::Vec::new();
    for from in core::iter::once(None).chain((0..m).map(|i| Some(ModeId(i as u8)))) {
        for to in 0..m {
            probabilities
                .push(prior.probability(from, ModeId(to as u8)))
                .ok()?;
        }
    }
    Some(PriorTable {
        task: task.into(),
        probabilities,
    })
}

/// The `SetSampler` settings of a sampler configuration; `None` when it has a setting the
/// wire does not carry (a `clip_denoised` other than the default: firmware always clips at
/// [`crate::diffusion::DEFAULT_DENOISED_CLIP`]).
pub fn settings_from_sampler(config: &SamplerConfig) -> Option<SamplerSettings> {
    if config.clip_denoised.to_bits() != SamplerConfig::default().clip_denoised.to_bits() {
        return None;
    }
    let method = match config.method {
        SamplingMethod::Ddpm { noise_factor } => SamplerMethod::Ddpm { noise_factor },
        SamplingMethod::Ddim { steps, eta: 0.0 } => SamplerMethod::Ddim { steps },
        SamplingMethod::Ddim { steps, eta } => SamplerMethod::DdimEta { steps, eta },
        SamplingMethod::DdpmStrided {
            steps,
            noise_factor,
        } => SamplerMethod::DdpmStrided {
            steps,
            noise_factor,
        },
    };
    Some(SamplerSettings {
        method,
        guidance_weight: config.guidance_weight,
    })
}

/// Answer a plan request: check it ([`PlanInputs::from_request`]; a bad field is
/// [`WireError::InvalidRequest`]), run the planner with the given models, and convert the
/// report. Every outcome of the search, failures included, is a [`PlanReply`] status.
/// Never allocates.
pub fn plan_request<const K: usize, const N: usize, const O: usize, const S: usize, Sa, Sc, Cl>(
    planner: &mut Planner<K, N, O, S>,
    request: &PlanRequest,
    prior: &MarkovPrior,
    sampler: &mut Sa,
    scorer: &mut Sc,
    clock: &mut Cl,
) -> Result<PlanReply, WireError>
where
    Sa: SegmentSampler,
    Sc: SegmentScorer,
    Cl: Clock,
{
    let inputs =
        PlanInputs::from_request(request).map_err(|field| WireError::InvalidRequest { field })?;
    // The sampler is already built; its settings are not the spec's to change here.
    let spec = inputs.into_spec(*prior, SamplerConfig::default());
    let report = plan_with_adapters(planner, &spec, sampler, scorer, clock);
    Ok(PlanReply::from(&report))
}
