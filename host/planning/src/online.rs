//! The online methods of the paper's experiments (`docs/contracts.md` §5, spec §3.5): DIPS and its
//! ablations, each an episode in which contact modes are chosen and CSVTO is initialised.
//!
//! - **DIPS** (`dips`): before each mode, one A* planning call in the kernel from the measured
//!   state (goal: yaw − π/3, card y = −6 cm; the search depth: [`SearchDepth`], the modes
//!   left); the first planned mode is executed by CSVTO initialised with fresh diffusion
//!   samples conditioned on the mode and the state, anchored at it as the search's are
//!   (`dips_kernel::session::start_anchor`); then replan. The episode stops at the mode limit
//!   (7 / 5) or when a plan holds no mode.
//! - `dips-k1` (one particle per node), `dips-max-likelihood` (single trajectory per node, the
//!   best-scored of k samples kept): the same loop with the search changed.
//! - `dips-no-replan`: one planning call (screwdriver goal fixed at −1.7 rad), its whole plan
//!   executed.
//! - `dips-sampled`: the prior's sequence, CSVTO initialised by diffusion samples.
//! - `csvto-sampled`: the prior's sequence, CSVTO's default initialisation.
//! - `diffusion-policy`: the baseline, a diffusion policy on the state alone
//!   ([`crate::policy`]).

use std::time::Instant;

use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::mode::{ModeId, ModeSet, Task};
use dips_kernel::name::UnknownValue;
use dips_kernel::prior::{MarkovPrior, PriorError};
use dips_kernel::rng::KernelRng;
use dips_kernel::search::{SearchConfig, SearchOverrides, SearchVariant};
use dips_kernel::session::{PlanSpec, SpecError};
use dips_kernel::task::CardGoals;

use crate::first_mode::{FirstModeRule, TOUCH_TOLERANCE_M};
use crate::policy::PolicyError;
use crate::sized::PlannerSize;
use crate::stop_rule::{PlanGain, StopRule};
use crate::{
    Models, POLICY_DIR, PlanCallError, PlanService, SampleError, StdClock, sample_trajectories,
};
use dips_exec::episode::{CARD_MODES, SCREWDRIVER_MODES};
use dips_exec::problems::contract::{LayoutError, contract_state, from_contract};
use dips_exec::problems::{AllegroProblem, Mode, ProblemError, ProblemSpec};
use dips_exec::{
    EpisodeResult, ExecError, ExecSettings, ParticleSummary, PlanRecord, fingertip_distances,
    hand_state, mode_goal, prior_sequence_for_seed, run_mode, true_hand_state,
};
use dips_world::hand::Hand;
use dips_world::kinematics::HandModel;
use dips_world::scenes::SceneKind;

/// The screwdriver goal of `dips-no-replan` (rad), the paper's.
pub const NO_REPLAN_YAW_GOAL: f32 = -1.7;

/// A method of the paper's experiments.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Plan before every mode; diffusion-initialised CSVTO.
    Dips,
    /// The prior's sequence; diffusion-initialised CSVTO (ablation 2).
    DipsSampled,
    /// The prior's sequence; CSVTO's default initialisation (ablation 1).
    CsvtoSampled,
    /// One planning call, its plan executed whole (ablation 3).
    DipsNoReplan,
    /// `k = 1`: no variability propagation (ablation 4).
    DipsK1,
    /// One trajectory per node, the best-scored of `k` samples (ablation 5).
    DipsMaxLikelihood,
    /// The Diffusion Policy baseline: no modes, no search (`crate::policy`).
    DiffusionPolicy,
}

impl Method {
    /// Every method, in the paper's order.
    pub const ALL: [Method; 7] = [
        Method::Dips,
        Method::DipsSampled,
        Method::CsvtoSampled,
        Method::DipsNoReplan,
        Method::DipsK1,
        Method::DipsMaxLikelihood,
        Method::DiffusionPolicy,
    ];

    /// The `--method` name.
    pub const fn name(self) -> &'static str {
        match self {
            Method::Dips => "dips",
            Method::DipsSampled => "dips-sampled",
            Method::CsvtoSampled => "csvto-sampled",
            Method::DipsNoReplan => "dips-no-replan",
            Method::DipsK1 => "dips-k1",
            Method::DipsMaxLikelihood => "dips-max-likelihood",
            Method::DiffusionPolicy => "diffusion-policy",
        }
    }

    /// Every method's name, in [`Method::ALL`] order.
    pub const NAMES: [&'static str; 7] = [
        Method::Dips.name(),
        Method::DipsSampled.name(),
        Method::CsvtoSampled.name(),
        Method::DipsNoReplan.name(),
        Method::DipsK1.name(),
        Method::DipsMaxLikelihood.name(),
        Method::DiffusionPolicy.name(),
    ];

    /// Whether the method needs the diffusion models.
    pub const fn needs_models(self) -> bool {
        !matches!(self, Method::CsvtoSampled)
    }

    /// Whether the method searches for its modes.
    pub const fn searches(self) -> bool {
        !matches!(
            self,
            Method::DipsSampled | Method::CsvtoSampled | Method::DiffusionPolicy
        )
    }
}

impl std::str::FromStr for Method {
    type Err = UnknownValue;

    /// A method by its name ([`Method::name`]); the error names the value and the methods.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find("method", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for Method {
    /// The method's name ([`Method::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A planning call's time budget that is not a finite number of seconds ≥ 0
/// ([`check_time_budget_s`]).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("time budget {seconds} s: expected a finite number of seconds ≥ 0 (0: no budget)")]
pub struct TimeBudgetError {
    /// The budget given (s).
    pub seconds: f64,
}

/// A planning call's wall-clock budget `seconds` checked: finite and not negative (0: no
/// budget). The one check of the budget for every command and settings file.
pub fn check_time_budget_s(seconds: f64) -> Result<f64, TimeBudgetError> {
    if !(seconds.is_finite() && seconds >= 0.0) {
        return Err(TimeBudgetError { seconds });
    }
    Ok(seconds)
}

/// Why an online episode ([`run_online`]) stopped. Each message names the method, mode or
/// call and what went wrong.
#[derive(Debug, thiserror::Error)]
pub enum OnlineError {
    /// A mode sequence was given to a method without contact modes.
    #[error(
        "method `diffusion-policy` has no contact modes; a mode sequence is for dips-sampled \
         and csvto-sampled"
    )]
    PolicyWithModes,
    /// A mode sequence was given to a method that plans its own.
    #[error(
        "method `{method}` plans its own modes; a given sequence is for dips-sampled and \
         csvto-sampled"
    )]
    SearchWithModes {
        /// The method.
        method: Method,
    },
    /// The Diffusion Policy baseline was run without models.
    #[error("method `diffusion-policy` needs its model")]
    PolicyNeedsModels,
    /// The models directory has no Diffusion Policy model.
    #[error("no diffusion-policy model at {}", file.display())]
    NoPolicyModel {
        /// The file looked for (`<models>/policy/denoiser.onnx`).
        file: std::path::PathBuf,
    },
    /// A method that needs the diffusion models was run without them.
    #[error("method `{method}` needs the diffusion models")]
    NeedsModels {
        /// The method.
        method: Method,
    },
    /// The paper's prior could not be built.
    #[error("{0}")]
    Prior(PriorError),
    /// The mode's CSVTO problem could not be built.
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// The denoiser's horizon is not CSVTO's.
    #[error("the denoiser makes {rows} rows, CSVTO plans {horizon} (+1)")]
    Horizon {
        /// Rows of the denoiser's trajectories.
        rows: usize,
        /// CSVTO's horizon.
        horizon: usize,
    },
    /// Sampling CSVTO's initialisation failed.
    #[error("diffusion initialisation of {mode}")]
    Initialisation {
        /// The mode.
        mode: &'static str,
        /// Why.
        #[source]
        source: SampleError,
    },
    /// A diffused sample does not convert to CSVTO's layout.
    #[error("diffused {mode} sample: {error}")]
    Layout {
        /// The mode.
        mode: &'static str,
        /// Why.
        error: LayoutError,
    },
    /// The measured state is too short to hold the object's pose.
    #[error("the state is too short")]
    ShortState,
    /// The planning call's settings are not a valid call.
    #[error("planning call: {0}")]
    Spec(SpecError),
    /// A planning call failed.
    #[error("planning before mode {mode} ({location})")]
    Planning {
        /// The mode (1-based) the call was to choose.
        mode: usize,
        /// Where the call was made ([`PlanService::location`]).
        location: String,
        /// Why.
        #[source]
        source: PlanCallError,
    },
    /// A mode's execution failed.
    #[error(transparent)]
    Exec(#[from] ExecError),
    /// The Diffusion Policy baseline's episode failed.
    #[error(transparent)]
    Policy(#[from] PolicyError),
}

/// A budget in seconds as the kernel's `time_budget_ms`, rounded and saturating at `u32::MAX`.
pub fn time_budget_ms(seconds: f64) -> u32 {
    (seconds * 1e3).round().min(f64::from(u32::MAX)) as u32
}

/// Settings of an online episode beside CSVTO's.
#[derive(Debug, Clone)]
pub struct OnlineSettings {
    /// Wall-clock budget of one planning call (s); the best node so far when it runs out.
    pub time_budget_s: f64,
    /// The search settings given over the task's (node budget, cost-to-come; `None` fields:
    /// the task's), resolved for each call by [`SearchOverrides::resolve`] with the call's
    /// depth, seed and [`OnlineSettings::time_budget_s`]. The method sets `k` and the node
    /// variant of its ablation over them.
    pub search: SearchOverrides,
    /// Sampler of the search's edges and of CSVTO's initialisation.
    pub sampler: SamplerConfig,
    /// The sequence a fixed-sequence method executes instead of the prior's draw.
    pub sequence: Option<Vec<Mode>>,
    /// Stop after this many modes (`None`: the task's limit, 7 / 5). The search depth does
    /// not change.
    pub max_modes: Option<usize>,
    /// How deep each planning call searches (`None`: the task's, [`SearchDepth::for_task`]).
    pub search_depth: Option<SearchDepth>,
    /// When a searching method stops before its mode limit ([`StopRule`]; the paper's when
    /// the plan holds no mode).
    pub stop_rule: StopRule,
    /// Which modes a plan may begin with ([`FirstModeRule`]; the paper's: any).
    pub first_mode: FirstModeRule,
    /// The in-process planner's capacities ([`PlannerSize`]; the firmware's by default).
    /// A kernel over the wire has its own.
    pub planner_size: PlannerSize,
}

impl OnlineSettings {
    /// The episode's search depth rule: [`OnlineSettings::search_depth`] when given, else the
    /// task's ([`SearchDepth::for_task`]).
    pub fn depth_rule(&self, scene: SceneKind) -> SearchDepth {
        self.search_depth.unwrap_or(SearchDepth::for_task(scene))
    }
}

/// How deep the planning calls of an episode search.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SearchDepth {
    /// The task's mode limit on every call (7 / 5), whatever the episode has left: the
    /// paper's screwdriver ("the same depth of 7 throughout the task").
    Fixed,
    /// The modes the episode has left (the limit less the modes executed): the paper's card,
    /// and ours for both tasks.
    ModesLeft,
}

impl SearchDepth {
    /// Both rules, in `--search-depth` order.
    pub const ALL: [Self; 2] = [Self::Fixed, Self::ModesLeft];

    /// Both rules' names, in [`SearchDepth::ALL`] order.
    pub const NAMES: [&'static str; 2] = [Self::Fixed.name(), Self::ModesLeft.name()];

    /// The task's rule (`docs/online.md`, "Search depth"): the modes left for both. The
    /// screwdriver departs from the paper's fixed depth since its segments are anchored at
    /// their starts (`dips_kernel::session::start_anchor`), measured there.
    pub fn for_task(scene: SceneKind) -> Self {
        match scene {
            SceneKind::Screwdriver | SceneKind::Card => Self::ModesLeft,
        }
    }

    /// The name used by `--search-depth` and `eval.json`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Fixed => "fixed",
            Self::ModesLeft => "modes-left",
        }
    }

    /// The depth of the planning call made after `executed` of the episode's `limit` modes
    /// (at least 1).
    pub fn depth(self, limit: usize, executed: usize) -> u8 {
        let d = match self {
            Self::Fixed => limit,
            Self::ModesLeft => limit.saturating_sub(executed),
        };
        d.clamp(1, u8::MAX as usize) as u8
    }
}

impl std::str::FromStr for SearchDepth {
    type Err = UnknownValue;

    /// A rule by its name ([`SearchDepth::name`]); the error names the value and the rules.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        UnknownValue::find("search depth", name, &Self::ALL, &Self::NAMES, Self::name)
    }
}

impl std::fmt::Display for SearchDepth {
    /// The rule's name ([`SearchDepth::name`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Default for OnlineSettings {
    /// The paper's: 300 s, DDPM-256 with guidance 1.2 and noise factor 0.5.
    fn default() -> Self {
        Self {
            time_budget_s: 300.0,
            search: SearchOverrides::default(),
            sampler: SamplerConfig::default(),
            sequence: None,
            max_modes: None,
            search_depth: None,
            stop_rule: StopRule::default(),
            first_mode: FirstModeRule::default(),
            planner_size: PlannerSize::default(),
        }
    }
}

/// The task's mode limit per episode.
pub fn mode_limit(task: SceneKind) -> usize {
    match task {
        SceneKind::Screwdriver => SCREWDRIVER_MODES,
        SceneKind::Card => CARD_MODES,
    }
}

/// Diffusion samples of `mode` from the current state of `hand`, as CSVTO particles of the
/// mode's problem (the one `run_mode` builds: horizon, start and goal as there).
pub fn diffusion_particles<H: Hand + ?Sized>(
    models: &mut Models,
    hand: &H,
    model: &HandModel,
    mode: Mode,
    settings: &ExecSettings,
    sampler: &SamplerConfig,
    rng: &mut KernelRng,
) -> Result<Vec<Vec<f64>>, OnlineError> {
    let task = hand.scene();
    let start = hand_state(hand);
    let problem = AllegroProblem::new(
        model,
        &ProblemSpec {
            task,
            mode,
            horizon: settings.horizon,
            start: start.clone(),
            goal: mode_goal(mode, &start, settings.card_goals),
        },
    )?;
    let engine = &mut models.denoiser;
    let dims = DenoiserEngine::dims(engine);
    if dims.horizon != settings.horizon + 1 {
        return Err(OnlineError::Horizon {
            rows: dims.horizon,
            horizon: settings.horizon,
        });
    }
    let n = settings.particles;
    let td = dims.floats_per_trajectory();
    let f = dims.fingers;
    let mut ctx1 = vec![0f32; f];
    mode.contact_mode().write_signs(&mut ctx1);
    let context: Vec<f32> = (0..n).flat_map(|_| ctx1.iter().copied()).collect();
    let s0: Vec<f32> = contract_state(&start).iter().map(|&v| v as f32).collect();
    let starts: Vec<f32> = (0..n).flat_map(|_| s0.iter().copied()).collect();
    let anchor = dips_kernel::session::start_anchor(hand.scene().task());
    let out =
        sample_trajectories(engine, sampler, &context, &starts, anchor, rng).map_err(|source| {
            OnlineError::Initialisation {
                mode: mode.name(),
                source,
            }
        })?;
    out.chunks_exact(td)
        .map(|t| {
            let rows: Vec<f64> = t.iter().map(|&v| f64::from(v)).collect();
            from_contract(&problem, &rows).map_err(|error| OnlineError::Layout {
                mode: mode.name(),
                error,
            })
        })
        .collect()
}

/// The search settings of `method` for one call: the settings' overrides with the call's
/// depth and the method's ablation, resolved by [`SearchOverrides::resolve`].
fn search_config(
    method: Method,
    task: Task,
    depth: u8,
    settings: &OnlineSettings,
    seed: u64,
) -> SearchConfig {
    let mut overrides = SearchOverrides {
        max_depth: Some(depth),
        ..settings.search
    };
    match method {
        Method::DipsK1 => overrides.k = Some(1),
        Method::DipsMaxLikelihood => overrides.variant = Some(SearchVariant::MaxLikelihood),
        _ => {}
    }
    overrides.resolve(task, seed, time_budget_ms(settings.time_budget_s))
}

/// One planning call from the hand's state.
#[allow(clippy::too_many_arguments)]
fn plan_call<H: Hand + ?Sized>(
    planner: &mut dyn PlanService,
    prior: MarkovPrior,
    method: Method,
    hand: &H,
    executed: &[Mode],
    depth: u8,
    settings: &OnlineSettings,
    card_goals: CardGoals,
    seed: u64,
) -> Result<(Vec<Mode>, PlanRecord), OnlineError> {
    let scene = hand.scene();
    let task = scene.task();
    let start: Vec<f32> = contract_state(&hand_state(hand))
        .iter()
        .map(|&v| v as f32)
        .collect();
    let goal = match (method, task) {
        (Method::DipsNoReplan, Task::Screwdriver) => NO_REPLAN_YAW_GOAL,
        _ => PlanSpec::paper_goal(task, &start).ok_or(OnlineError::ShortState)?,
    };
    let config = search_config(method, task, depth, settings, seed);
    let mut spec = PlanSpec::with_settings(task, &start, goal, config, prior)
        .map_err(OnlineError::Spec)?
        .with_card_goals(card_goals);
    spec.sampler = settings.sampler;
    spec.executed = executed.last().map(|m| m.id());
    if !settings.first_mode.is_paper() {
        let distances = fingertip_distances(hand, &HandModel::allegro_v4())?;
        spec.first_modes = settings.first_mode.first_modes(task, &distances);
    }
    spec.check().map_err(OnlineError::Spec)?;
    let t0 = Instant::now();
    let report = planner
        .plan_call(&spec, &mut StdClock(t0))
        .map_err(|source| OnlineError::Planning {
            mode: executed.len() + 1,
            location: planner.location(),
            source,
        })?;
    let seconds = t0.elapsed().as_secs_f64();
    let modes: Vec<Mode> = report
        .modes
        .iter()
        .filter_map(|&id: &ModeId| Mode::from_id(task, id))
        .collect();
    let record = PlanRecord {
        executed: executed.len(),
        goal,
        depth,
        modes: modes.iter().map(|m| m.name()).collect(),
        status: format!("{:?}", report.status),
        expected_terminal_state: report
            .terminal_state
            .iter()
            .map(|&v| v.is_finite().then_some(v))
            .collect(),
        nodes_expanded: report.nodes_expanded,
        segments_sampled: report.segments_sampled,
        particles: report.particles,
        effective_particles: report
            .effective_particles
            .is_finite()
            .then_some(report.effective_particles),
        seconds,
        particles_diagnostics: planner.last_diagnostics().and_then(|d| {
            let modes: Vec<ModeId> = task.candidate_modes().collect();
            ParticleSummary::of(&d, |i| {
                modes
                    .get(i)
                    .and_then(|&id| Mode::from_id(task, id))
                    .map(|m| m.name().to_string())
            })
        }),
        first_modes: (spec.first_modes != ModeSet::all(task)).then(|| {
            task.candidate_modes()
                .filter(|&id| spec.first_modes.contains(id))
                .filter_map(|id| Mode::from_id(task, id))
                .map(|m| m.name())
                .collect()
        }),
        stopped_no_gain: settings.stop_rule == StopRule::NoGain
            && !modes.is_empty()
            && PlanGain::of(task, &start, goal, card_goals, report.expected_progress)
                .is_none_or(|g| g.no_gain()),
    };
    Ok((modes, record))
}

/// Run one episode of `method` on `hand` from its current state. `models` is needed by every
/// method but `csvto-sampled`; the prior is the models' fitted one, else the paper's. The
/// planning calls go to `remote` when given (a kernel over the wire, `dips-link`), else to a
/// session in this process over `models`; the models also sample CSVTO's initialisation.
#[allow(clippy::too_many_arguments)]
pub fn run_online<H: Hand + ?Sized>(
    hand: &mut H,
    method: Method,
    seed: u64,
    models: Option<Models>,
    mut remote: Option<&mut dyn PlanService>,
    exec: &ExecSettings,
    settings: &OnlineSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<EpisodeResult, OnlineError> {
    let scene = hand.scene();
    let hand_name = hand.name();
    let task = scene.task();
    let model = HandModel::allegro_v4();
    let limit = mode_limit(scene);
    if method == Method::DiffusionPolicy {
        if settings.sequence.is_some() {
            return Err(OnlineError::PolicyWithModes);
        }
        let mut models = models.ok_or(OnlineError::PolicyNeedsModels)?;
        let dir = models.dir.clone();
        let Some(policy) = models.policy.as_mut() else {
            return Err(OnlineError::NoPolicyModel {
                file: dir.join(POLICY_DIR).join("denoiser.onnx"),
            });
        };
        let runs = settings.max_modes.map_or(limit, |m| m.min(limit));
        let mut result = crate::policy::run_policy_episode(
            hand,
            policy,
            seed,
            exec,
            &settings.sampler,
            runs,
            progress,
        )?;
        result.record_execution(hand_name, hand.report(), exec);
        return Ok(result);
    }
    let mut rng = KernelRng::seed_from_u64(seed);
    let mut sampler_rng = KernelRng::seed_from_u64(seed ^ 0xd1ff_0510);
    let mut session = match (models, method.needs_models()) {
        (Some(m), _) => Some(settings.planner_size.session(m)),
        (None, true) => return Err(OnlineError::NeedsModels { method }),
        (None, false) => None,
    };
    let prior = match session.as_mut().and_then(|s| s.models_mut().prior) {
        Some(p) => p,
        None => MarkovPrior::paper(task, SearchConfig::for_task(task).p_min)
            .map_err(OnlineError::Prior)?,
    };
    // Scored on the true pose (a simulated tracker may be noisy); planned on the measured.
    let start = true_hand_state(hand);
    let mut valid = hand.true_object_pose().valid(scene);
    let mut runs = Vec::new();
    let mut executed: Vec<Mode> = Vec::new();
    let mut plans = Vec::new();
    let mut planning_s = Vec::new();
    let mut step_s = Vec::new();
    if method.searches() && settings.sequence.is_some() {
        return Err(OnlineError::SearchWithModes { method });
    }
    let mut queue: Vec<Mode> = if method.searches() {
        Vec::new()
    } else {
        settings
            .sequence
            .clone()
            .unwrap_or_else(|| prior_sequence_for_seed(scene, seed))
    };
    let limit = if method.searches() {
        limit
    } else {
        queue.len()
    };
    queue.reverse();
    let stop = settings.max_modes.map_or(limit, |m| m.min(limit));
    while executed.len() < stop {
        if method.searches() && (method != Method::DipsNoReplan || plans.is_empty()) {
            let planner: &mut dyn PlanService = match (remote.as_deref_mut(), session.as_mut()) {
                (Some(r), _) => r,
                (None, Some(s)) => s,
                (None, None) => return Err(OnlineError::NeedsModels { method }),
            };
            let depth = settings.depth_rule(scene).depth(limit, executed.len());
            progress(&format!(
                "planning call {} (depth {depth})",
                plans.len() + 1
            ));
            let call_seed = seed.wrapping_mul(1000).wrapping_add(plans.len() as u64);
            let (modes, record) = plan_call(
                planner,
                prior,
                method,
                hand,
                &executed,
                depth,
                settings,
                exec.card_goals,
                call_seed,
            )?;
            progress(&if record.modes.is_empty() && record.nodes_expanded == 0 {
                format!(
                    "  {} in {:.1} s: the goal is already reached, nothing left to plan",
                    record.status, record.seconds
                )
            } else {
                format!(
                    "  {} in {:.1} s: {}",
                    record.status,
                    record.seconds,
                    record.modes.join(", ")
                )
            });
            if let Some(first) = &record.first_modes {
                progress(&format!(
                    "  first mode limited to {}: a contact finger of the others is more than \
                     {:.0} mm off the object",
                    first.join(", "),
                    TOUCH_TOLERANCE_M * 1e3
                ));
            }
            planning_s.push(record.seconds);
            let stop_here = record.stopped_no_gain;
            plans.push(record);
            if stop_here {
                progress("  stopped: the plan's expected end is no nearer the goal than here");
                break;
            }
            queue = modes;
            queue.reverse();
        }
        let Some(mode) = queue.pop() else {
            break;
        };
        if method.searches() && method != Method::DipsNoReplan {
            queue.clear();
        }
        // A searching method stops early when the goal is reached, so its count is a limit
        // (the episode's pictures count the modes it executed).
        progress(&if method.searches() {
            format!(
                "mode {} (of at most {stop}): {}",
                executed.len() + 1,
                mode.name()
            )
        } else {
            format!("mode {}/{stop}: {}", executed.len() + 1, mode.name())
        });
        let initial = match session.as_mut() {
            Some(s) if method != Method::CsvtoSampled => Some(diffusion_particles(
                s.models_mut(),
                hand,
                &model,
                mode,
                exec,
                &settings.sampler,
                &mut sampler_rng,
            )?),
            _ => None,
        };
        let run = run_mode(hand, &model, mode, exec, initial, &mut rng, progress)?;
        valid &= run.steps.iter().all(|s| s.valid);
        step_s.extend(run.solve_times());
        runs.push(run);
        executed.push(mode);
    }
    let end = true_hand_state(hand);
    let mut result = EpisodeResult::assemble(
        scene,
        method.name(),
        seed,
        &start,
        &end,
        runs,
        planning_s,
        step_s,
        valid,
    );
    result.plans = plans;
    result.record_execution(hand_name, hand.report(), exec);
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn search_depth_is_the_limit_or_the_modes_left() {
        assert_eq!(SearchDepth::Fixed.depth(7, 0), 7);
        assert_eq!(SearchDepth::Fixed.depth(7, 6), 7);
        assert_eq!(SearchDepth::ModesLeft.depth(7, 0), 7);
        assert_eq!(SearchDepth::ModesLeft.depth(7, 6), 1);
        assert_eq!(SearchDepth::ModesLeft.depth(5, 3), 2);
        // Never 0: a call is only made with a mode left, but the depth stays a valid search.
        assert_eq!(SearchDepth::ModesLeft.depth(5, 5), 1);
        for scene in [SceneKind::Screwdriver, SceneKind::Card] {
            assert_eq!(SearchDepth::for_task(scene), SearchDepth::ModesLeft);
        }
    }
}
