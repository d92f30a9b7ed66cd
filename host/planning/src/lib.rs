//! `dips-planning`: planning with the diffusion models on the host, and what is built on it.
//!
//! The crate root is the planning session: the two models loaded from `.onnx` files (run by
//! tract or by the kernel interpreter) and planned through the kernel's session builder
//! ([`dips_kernel::session`]), which `dips plan`, the tests and the DIPS loop share with the
//! firmware. Built on it: [`online`] (the paper's methods: DIPS's plan → diffusion-initialised
//! CSVTO → replan loop and its ablations, executed by `dips-exec`), [`policy`] (the Diffusion
//! Policy baseline) and [`quality`] (trained models measured the way the planner uses them).
//!
//! A [`Session`] keeps its models, planner and work area across calls, so a replanning loop
//! builds it once and calls [`Session::plan`] with a new [`PlanSpec`] (start, goal, executed
//! mode, seed) each time.
//!
//! Where a plan is made is a [`PlanService`]: the session in this process, or a kernel over
//! the wire (`dips-link`: `dips-firmware-sim` spawned or reached over TCP). Both answer with
//! the same [`PlanOutcome`], bit for bit for the same call.

pub mod first_mode;
pub mod online;
pub mod policy;
pub mod quality;
pub mod sized;
pub mod stop_rule;

use std::path::{Path, PathBuf};
use std::time::Instant;

use dips_kernel::budget::Clock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::mode::ModeId;
use dips_kernel::mode::Task;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{PaperPlanner, ParticleDiagnostics, Planner, SearchReport, SearchStatus};
use dips_kernel::session::{PlanSpec, SessionError, SessionLayout, plan_with_engines};
use dips_kernel::task::CardGoals;
use dips_onnx::{AnyEngine, EngineKind, Expectation, ModelError, Role};

/// `std::time::Instant` as the kernel's clock (microseconds since `self.0`).
#[derive(Debug, Clone, Copy)]
pub struct StdClock(pub Instant);

impl StdClock {
    /// A clock starting now.
    pub fn start() -> Self {
        Self(Instant::now())
    }
}

impl Clock for StdClock {
    fn now_us(&mut self) -> u64 {
        u64::try_from(self.0.elapsed().as_micros()).unwrap_or(u64::MAX)
    }
}

/// A [`StdClock`] that also reports progress: every `interval` of a planning call it hands
/// `report` the seconds so far and how often the planner has read the clock. With a time
/// budget the planner reads it once before every expansion, so the count is the expansions
/// started (plus one at the start).
pub struct ProgressClock<'a> {
    clock: StdClock,
    interval_us: u64,
    next_us: u64,
    reads: u64,
    report: &'a mut dyn FnMut(f64, u64),
}

impl std::fmt::Debug for ProgressClock<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProgressClock")
            .field("clock", &self.clock)
            .field("reads", &self.reads)
            .finish_non_exhaustive()
    }
}

impl<'a> ProgressClock<'a> {
    /// A clock starting now that calls `report(seconds, reads)` every `interval`.
    pub fn start(interval: std::time::Duration, report: &'a mut dyn FnMut(f64, u64)) -> Self {
        let interval_us = u64::try_from(interval.as_micros())
            .unwrap_or(u64::MAX)
            .max(1);
        Self {
            clock: StdClock::start(),
            interval_us,
            next_us: interval_us,
            reads: 0,
            report,
        }
    }
}

impl Clock for ProgressClock<'_> {
    fn now_us(&mut self) -> u64 {
        let now = self.clock.now_us();
        self.reads += 1;
        if now >= self.next_us {
            (self.report)(now as f64 * 1e-6, self.reads);
            self.next_us = now + self.interval_us;
        }
        now
    }
}

/// The threads a model call uses when no `--threads` is given: every core this process may
/// use.
pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The file name of a model role in a models directory.
pub fn model_file(role: Role) -> &'static str {
    match role {
        Role::Denoiser => "denoiser.onnx",
        Role::Discriminator => "discriminator.onnx",
    }
}

/// The file name of the fitted contact-mode prior in a models directory.
pub const PRIOR_FILE: &str = "prior.json";

/// The environment variable naming a directory with one models directory per task.
pub const MODELS_ENV: &str = "DIPS_MODELS";

/// The shipped models' directory (`onnx/models`) in the repository this binary was built from,
/// spelled `<repo>/host/../onnx/models` as it was before this crate moved to `host/planning/`:
/// `eval.json` records the models' path, and a resumed evaluation compares it.
fn repo_models() -> PathBuf {
    let host = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap_or(Path::new(".."));
    host.join("../onnx/models")
}

/// The models directory of `task` when none is given: `$DIPS_MODELS/<task>` when the variable
/// is set, else `onnx/models/<task>` under the current directory, else the shipped models of the
/// repository this binary was built from. The error lists what was tried.
pub fn default_models_dir(task: Task) -> Result<PathBuf, ModelsError> {
    let mut tried = Vec::new();
    if let Some(root) = std::env::var_os(MODELS_ENV) {
        let dir = PathBuf::from(root).join(task.name());
        if dir.is_dir() {
            return Ok(dir);
        }
        return Err(ModelsError::EnvNotADirectory { dir });
    }
    for root in [PathBuf::from("onnx/models"), repo_models()] {
        let dir = root.join(task.name());
        if dir.join(model_file(Role::Denoiser)).is_file() {
            return Ok(dir);
        }
        tried.push(dir);
    }
    Err(ModelsError::NotFound { task, tried })
}

/// `given`, or else [`default_models_dir`] of `task`: how every command picks its models.
pub fn models_dir(given: Option<&Path>, task: Task) -> Result<PathBuf, ModelsError> {
    match given {
        Some(d) => Ok(d.to_path_buf()),
        None => default_models_dir(task),
    }
}

/// Sample one trajectory per row of `context` (`[n, F]`) with row 0's state inpainted from
/// `starts` (`[n, state_dim]`, raw), drawing from `rng`; `[n, T, D]` raw rows. The sampler's
/// chunking (at most 48 trajectories per engine call pair) does not change the bits.
///
/// `anchor` makes each trajectory continue from its start as the planner's sampler does
/// (`dips_kernel::session::start_anchor`, `DiffusionSegmentSampler::set_start_anchor`);
/// `StartAnchor::NONE` samples the model as it is.
pub fn sample_trajectories(
    engine: &mut AnyEngine,
    config: &dips_kernel::diffusion::SamplerConfig,
    context: &[f32],
    starts: &[f32],
    anchor: dips_kernel::adapters::StartAnchor,
    rng: &mut dips_kernel::rng::KernelRng,
) -> Result<Vec<f32>, SampleError> {
    use dips_kernel::diffusion::{SampleRequest, SamplerScratch, ScratchLayout, sample};
    let dims = DenoiserEngine::dims(engine);
    let mut canonical = starts.to_vec();
    if let Some(a) = anchor.clamp_angle(dims.state_dim) {
        a.clamp_starts(&mut canonical, dims.state_dim);
    }
    let n = context.len() / dims.fingers.max(1);
    let chunk = 48.min(engine.max_batch() / 2).max(1);
    let layout = ScratchLayout::new(dims, chunk);
    let mut buf = vec![0f32; layout.total()];
    let mut scratch = SamplerScratch::split(&mut buf, &layout).map_err(SampleError::Scratch)?;
    let mut out = vec![0f32; n * dims.floats_per_trajectory()];
    sample(
        engine,
        config,
        &SampleRequest {
            context,
            start_states: Some(&canonical),
        },
        rng,
        &mut scratch,
        &mut out,
    )
    .map_err(SampleError::Sampling)?;
    anchor.apply(
        &mut out,
        starts,
        context,
        &dips_kernel::adapters::segment_dims(dims),
    );
    Ok(out)
}

/// A task's denoiser and discriminator, checked against the task's contract, and the prior
/// fitted with them when the directory has one.
#[derive(Debug)]
pub struct Models {
    /// The denoiser `M(c, s₀)`.
    pub denoiser: AnyEngine,
    /// The discriminator `Ψ`.
    pub discriminator: AnyEngine,
    /// The prior of `prior.json` (fitted from the training data), `None` when the directory
    /// has none.
    pub prior: Option<MarkovPrior>,
    /// The directory they were loaded from.
    pub dir: PathBuf,
    /// The Diffusion Policy baseline's denoiser (`dir/policy/denoiser.onnx`), when the
    /// directory has one (`crate::policy`).
    pub policy: Option<AnyEngine>,
    /// The samplers Ψ's negatives came from, as the discriminator's metadata names them
    /// (`dips.psi_negatives`: `ddpm:16+anchor` for the planner's anchored strided DDPM);
    /// `None` for models that do not say (trained before it was recorded).
    pub psi_negatives: Option<Vec<String>>,
    /// The card goals the denoiser's demos were made with (`dips.card_goals`); `None` for
    /// models that do not say (screwdriver models, and card models trained on ours before it
    /// was recorded).
    pub card_goals: Option<CardGoals>,
}

/// The card goals the denoiser in `dir` was trained for (`dips.card_goals`), `None` when it
/// does not say or `dir` holds no denoiser (a run of methods that need none).
pub fn models_card_goals(dir: &Path) -> Result<Option<CardGoals>, ModelsError> {
    let file = dir.join(model_file(Role::Denoiser));
    if !file.is_file() {
        return Ok(None);
    }
    dips_onnx::contract::read_proto(&file)
        .and_then(|p| dips_onnx::contract::card_goals(&p))
        .map_err(|source| ModelsError::Load { file, source })
}

/// Card goals asked for that are not those the models were trained for: a planner whose `J`
/// and goal test aim elsewhere than its denoiser's pushes plans neither.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "the models in {} were trained on demos with card goals {trained}, not {given}",
    models.display()
)]
pub struct CardGoalsMismatch {
    /// The goals asked for.
    pub given: CardGoals,
    /// The goals the models were trained for.
    pub trained: CardGoals,
    /// The models' directory.
    pub models: PathBuf,
}

/// The card goals of an episode or evaluation: `given`, else those the models
/// (`(directory, goals)`, [`Models::trained_card_goals`]) were trained for, else ours.
/// [`CardGoalsMismatch`] when `given` and the models' differ.
pub fn resolve_card_goals(
    given: Option<CardGoals>,
    models: Option<(&Path, CardGoals)>,
) -> Result<CardGoals, CardGoalsMismatch> {
    match (given, models) {
        (Some(given), Some((dir, trained))) if given != trained => Err(CardGoalsMismatch {
            given,
            trained,
            models: dir.to_path_buf(),
        }),
        (_, Some((_, trained))) => Ok(trained),
        (given, None) => Ok(given.unwrap_or_default()),
    }
}

/// The name of the samples the planner draws for `task` with `config`: the sampler's name,
/// `+anchor` where the task's start anchor moves them (as `dips.psi_negatives` spells it).
pub fn planner_sample_name(config: &SamplerConfig, task: Task) -> String {
    let anchored =
        dips_kernel::session::start_anchor(task) != dips_kernel::adapters::StartAnchor::NONE;
    dips_onnx::contract::psi_sample_name(&config.method, anchored)
}

/// Why a Ψ whose negatives came from `negatives` (`dips.psi_negatives`) must not score the
/// planner's samples of `config` for `task`, or `None` when it may: when they are among its
/// negatives, or when Ψ was trained the paper's way only (the full DDPM and DDIM fakes, no
/// planner sampler among them: the shipped recipe, measured on the planner's samples in
/// docs/particles.md). A Ψ trained for one planner sampler (`discriminator.planner_fakes`)
/// refuses another.
fn psi_mismatch(negatives: &[String], config: &SamplerConfig, task: Task) -> Option<PsiMismatch> {
    let name = planner_sample_name(config, task);
    let for_a_planner = negatives
        .iter()
        .any(|n| n.ends_with("+anchor") || n.starts_with("ddpm:"));
    if negatives.contains(&name) || !for_a_planner {
        return None;
    }
    // The samplers among the negatives that the planner draws as they were drawn.
    let usable: Vec<String> = negatives
        .iter()
        .filter_map(|n| {
            let base = n.strip_suffix("+anchor").unwrap_or(n);
            (planner_sample_name(&base.parse().ok()?, task) == *n).then(|| base.to_string())
        })
        .collect();
    Some(PsiMismatch {
        negatives: negatives.to_vec(),
        planner: name,
        usable,
        planner_steps: match config.method {
            dips_kernel::diffusion::SamplingMethod::DdpmStrided { steps, .. } => Some(steps),
            _ => None,
        },
    })
}

/// A Ψ trained against other samplers' samples than the planner's ([`Models::check_psi`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PsiMismatch {
    /// The samplers of Ψ's negatives (`dips.psi_negatives`).
    pub negatives: Vec<String>,
    /// The planner's samples ([`planner_sample_name`]), not among them.
    pub planner: String,
    /// The samplers among the negatives that the planner draws as Ψ saw them (the
    /// samplers that may plan with this Ψ); may be empty.
    pub usable: Vec<String>,
    /// The planner's steps when it draws a strided DDPM (`ddpm:S`), for which Ψ could be
    /// retrained.
    pub planner_steps: Option<u16>,
}

impl PsiMismatch {
    /// The retraining that would make Ψ fit the planner's sampler.
    pub fn retrain(&self) -> String {
        match self.planner_steps {
            Some(steps) => {
                format!("retrain Ψ with discriminator.planner_fakes = [{steps}] (docs/training.md)")
            }
            None => "retrain Ψ with discriminator.planner_fakes for a ddpm:S sampler".to_string(),
        }
    }

    /// What Ψ saw and the planner draws (the message's first half).
    pub fn what(&self) -> String {
        format!(
            "Ψ was trained against samples of {} and never saw the planner's {}",
            self.negatives.join(", "),
            self.planner
        )
    }
}

impl std::fmt::Display for PsiMismatch {
    /// What Ψ saw, what the planner draws, and the samplers that may plan with it instead.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.usable.is_empty() {
            write!(f, "{}; {}", self.what(), self.retrain())
        } else {
            write!(
                f,
                "{}; plan with the sampler {}, or {}",
                self.what(),
                self.usable.join(" or "),
                self.retrain()
            )
        }
    }
}

/// Why models cannot be found, loaded, or used as asked. Each message names the directory or
/// file and what is allowed.
#[derive(Debug, thiserror::Error)]
pub enum ModelsError {
    /// `$DIPS_MODELS` is set but holds no directory for the task.
    #[error(
        "$DIPS_MODELS is set but {} is not a directory (unset it to use the shipped models)",
        dir.display()
    )]
    EnvNotADirectory {
        /// The task's directory under `$DIPS_MODELS`.
        dir: PathBuf,
    },
    /// No models directory was given and none of the default places has the task's models.
    #[error(
        "no {task} models found (tried {}); give a models directory or set $DIPS_MODELS",
        tried.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")
    )]
    NotFound {
        /// The task.
        task: Task,
        /// The directories tried, in order.
        tried: Vec<PathBuf>,
    },
    /// A model file the run needs is not there.
    #[error("no {role:?} model at {}", file.display())]
    Missing {
        /// The model's role.
        role: Role,
        /// The file looked for.
        file: PathBuf,
    },
    /// A model file cannot be read, or is not a model of the task's contract.
    #[error("loading {}", file.display())]
    Load {
        /// The file.
        file: PathBuf,
        /// What is wrong with it.
        #[source]
        source: ModelError,
    },
    /// The fitted prior cannot be read.
    #[error("loading {}", file.display())]
    Prior {
        /// The file.
        file: PathBuf,
        /// What is wrong with it.
        #[source]
        source: dips_dataset::DatasetError,
    },
    /// The Diffusion Policy baseline's model cannot be loaded.
    #[error("the diffusion-policy baseline needs its model in {}", dir.display())]
    Policy {
        /// The policy's folder in the models directory ([`POLICY_DIR`]).
        dir: PathBuf,
        /// Why it cannot be loaded.
        #[source]
        source: Box<ModelsError>,
    },
    /// A strided sampler asks for more steps than the denoiser was trained with.
    #[error(
        "sampler {name}:{steps}: the denoiser in {} was trained with {trained} diffusion steps; \
         use ddim:S or ddpm:S with 1 ≤ S ≤ {trained}, or ddpm",
        dir.display()
    )]
    TooManySteps {
        /// The sampler's kind (`ddim` or `ddpm`).
        name: &'static str,
        /// The steps asked for.
        steps: u16,
        /// The steps the denoiser was trained with (the most allowed).
        trained: usize,
        /// The models' directory.
        dir: PathBuf,
    },
    /// Ψ was trained for another planner sampler than this one ([`Models::check_psi`]).
    #[error("the discriminator in {}: {mismatch}", dir.display())]
    Psi {
        /// The models' directory.
        dir: PathBuf,
        /// What Ψ saw and what the planner draws.
        mismatch: PsiMismatch,
    },
}

/// Why diffusion sampling ([`sample_trajectories`]) failed.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    /// The sampler's work area cannot be laid out for the engine.
    #[error("sampler scratch: {0}")]
    Scratch(dips_kernel::diffusion::SamplerError),
    /// The sampler or the engine failed.
    #[error("sampling failed: {0:?}")]
    Sampling(dips_kernel::diffusion::SampleError<ModelError>),
}

/// Why a planning call ([`PlanService::plan_call`]) failed.
#[derive(Debug, thiserror::Error)]
pub enum PlanCallError {
    /// The in-process session refused the call or its engines failed.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// A service elsewhere (a kernel over the wire, `dips-link`) failed; its own error says
    /// how.
    #[error(transparent)]
    Remote(Box<dyn std::error::Error + Send + Sync>),
}

impl Models {
    /// The card goals the denoiser was trained for (`dips.card_goals`), ours when it does not
    /// say (every card model made before they could differ).
    pub fn trained_card_goals(&self) -> CardGoals {
        self.card_goals.unwrap_or_default()
    }

    /// Check that a Ψ trained for the planner's own samples (`discriminator.planner_fakes`)
    /// scores the samples it was trained for: when its negatives name a planner sampler, the
    /// planner's (`config` with the task's start anchor, [`planner_sample_name`]) must be one
    /// of them; an error, not a silent drift. A Ψ trained the paper's way only (the shipped
    /// recipe) and models that do not name their negatives pass.
    pub fn check_psi(&self, config: &SamplerConfig, task: Task) -> Result<(), ModelsError> {
        match self
            .psi_negatives
            .as_deref()
            .and_then(|n| psi_mismatch(n, config, task))
        {
            Some(mismatch) => Err(ModelsError::Psi {
                dir: self.dir.clone(),
                mismatch,
            }),
            None => Ok(()),
        }
    }

    /// Check that `config` can run on the denoiser (a strided sampler cannot take more steps
    /// than the model was trained with) and that Ψ was trained against its samples for
    /// `task` ([`Self::check_psi`]). The error names the models and what is allowed.
    pub fn check_sampler(&self, config: &SamplerConfig, task: Task) -> Result<(), ModelsError> {
        self.check_steps(config)?;
        self.check_psi(config, task)
    }

    fn check_steps(&self, config: &SamplerConfig) -> Result<(), ModelsError> {
        use dips_kernel::diffusion::SamplingMethod;
        let n = DenoiserEngine::dims(&self.denoiser).diffusion_steps;
        let (name, steps) = match config.method {
            SamplingMethod::Ddim { steps, .. } => ("ddim", steps),
            SamplingMethod::DdpmStrided { steps, .. } => ("ddpm", steps),
            SamplingMethod::Ddpm { .. } => return Ok(()),
        };
        if usize::from(steps) > n {
            return Err(ModelsError::TooManySteps {
                name,
                steps,
                trained: n,
                dir: self.dir.clone(),
            });
        }
        Ok(())
    }

    /// Let every model call use up to `threads` threads ([`AnyEngine::set_threads`]: the
    /// kernel engine splits its batch, with the same bits as one thread; tract ignores it).
    pub fn set_threads(&mut self, threads: usize) {
        self.denoiser.set_threads(threads);
        self.discriminator.set_threads(threads);
        if let Some(p) = &mut self.policy {
            p.set_threads(threads);
        }
    }

    /// Load `denoiser.onnx`, `discriminator.onnx` and, when present, `prior.json` and
    /// `policy/denoiser.onnx` from `dir` for `task` with `kind`.
    pub fn load(kind: EngineKind, dir: &Path, task: Task) -> Result<Self, ModelsError> {
        let prior_path = dir.join(PRIOR_FILE);
        let prior = if prior_path.is_file() {
            Some(
                dips_dataset::PriorFile::load(&prior_path, task)
                    .map(|(_, p)| p)
                    .map_err(|source| ModelsError::Prior {
                        file: prior_path,
                        source,
                    })?,
            )
        } else {
            None
        };
        Ok(Self {
            denoiser: load_model(kind, dir, Role::Denoiser, task)?,
            discriminator: load_model(kind, dir, Role::Discriminator, task)?,
            prior,
            card_goals: models_card_goals(dir)?,
            psi_negatives: {
                let file = dir.join(model_file(Role::Discriminator));
                dips_onnx::contract::read_proto(&file)
                    .and_then(|p| dips_onnx::contract::psi_negatives(&p))
                    .map_err(|source| ModelsError::Load { file, source })?
            },
            dir: dir.to_path_buf(),
            policy: if dir
                .join(POLICY_DIR)
                .join(model_file(Role::Denoiser))
                .is_file()
            {
                Some(load_policy(kind, dir, task)?)
            } else {
                None
            },
        })
    }
}

fn load_model(
    kind: EngineKind,
    dir: &Path,
    role: Role,
    task: Task,
) -> Result<AnyEngine, ModelsError> {
    let file = dir.join(model_file(role));
    if !file.is_file() {
        return Err(ModelsError::Missing { role, file });
    }
    AnyEngine::load(kind, &file, &Expectation::new(role, task.name()))
        .map_err(|source| ModelsError::Load { file, source })
}

/// The Diffusion Policy baseline's folder inside a models directory (`crate::policy`).
pub const POLICY_DIR: &str = "policy";

/// Load the Diffusion Policy baseline's denoiser from `models/policy/denoiser.onnx`, checked
/// against `task`'s contract (`crate::policy`).
pub fn load_policy(kind: EngineKind, models: &Path, task: Task) -> Result<AnyEngine, ModelsError> {
    let dir = models.join(POLICY_DIR);
    load_model(kind, &dir, Role::Denoiser, task).map_err(|source| ModelsError::Policy {
        dir,
        source: Box::new(source),
    })
}

/// What a planning call answers, wherever it ran: the fields of the kernel's
/// [`SearchReport`] that the CLI and the online loop record.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOutcome {
    /// How the search ended.
    pub status: SearchStatus,
    /// The planned modes after the executed one.
    pub modes: Vec<ModeId>,
    /// The expected (particle-mean) raw state at the plan's end.
    pub terminal_state: Vec<f32>,
    /// The expected progress there (screwdriver yaw in rad, card y in m).
    pub expected_progress: f32,
    /// Nodes expanded.
    pub nodes_expanded: u32,
    /// Nodes created, the root included.
    pub nodes_generated: u32,
    /// Sampler calls.
    pub sampler_calls: u32,
    /// Scorer (discriminator) calls.
    pub scorer_calls: u32,
    /// Segments sampled.
    pub segments_sampled: u32,
    /// Particles at the plan's terminal node.
    pub particles: u8,
    /// Their effective number.
    pub effective_particles: f32,
}

impl From<&SearchReport> for PlanOutcome {
    fn from(r: &SearchReport) -> Self {
        Self {
            status: r.status,
            modes: r.modes.to_vec(),
            terminal_state: r.terminal_state.to_vec(),
            expected_progress: r.expected_progress,
            nodes_expanded: r.stats.nodes_expanded,
            nodes_generated: r.stats.nodes_generated,
            sampler_calls: r.stats.sampler_calls,
            scorer_calls: r.stats.scorer_calls,
            segments_sampled: r.stats.segments_sampled,
            particles: r.particles,
            effective_particles: r.effective_particles,
        }
    }
}

/// Something that makes plans: the in-process [`Session`], or a kernel over the wire.
pub trait PlanService {
    /// Plan `spec`; `clock` is read before every expansion (in process) or for progress
    /// (over the wire, where the kernel keeps its own time).
    fn plan_call(
        &mut self,
        spec: &PlanSpec,
        clock: &mut dyn Clock,
    ) -> Result<PlanOutcome, PlanCallError>;

    /// Where the plans are made, for messages and result files (`in-process`,
    /// `firmware-sim (spawned)`, `tcp://HOST:PORT`).
    fn location(&self) -> String;

    /// What the particles and Ψ did in the last call (`docs/particles.md`), where the service
    /// can see it: in process yes, over the wire not (the kernel keeps them to itself).
    fn last_diagnostics(&self) -> Option<ParticleDiagnostics> {
        None
    }
}

impl<const K: usize, const N: usize, const O: usize, const S: usize> PlanService
    for Session<K, N, O, S>
{
    fn plan_call(
        &mut self,
        spec: &PlanSpec,
        clock: &mut dyn Clock,
    ) -> Result<PlanOutcome, PlanCallError> {
        let report = self.plan(spec, &mut &mut *clock)?;
        self.last_diagnostics = Some(report.particle_diagnostics);
        Ok(PlanOutcome::from(&report))
    }

    fn location(&self) -> String {
        "in-process".into()
    }

    fn last_diagnostics(&self) -> Option<ParticleDiagnostics> {
        self.last_diagnostics
    }
}

/// A planning session over loaded models: planner (capacities `K, N, O, S`, by default the
/// [`PaperPlanner`]'s) and adapter work area, kept across calls.
#[derive(Debug)]
pub struct Session<
    const K: usize = 16,
    const N: usize = 512,
    const O: usize = 256,
    const S: usize = 481,
> {
    models: Models,
    planner: Box<Planner<K, N, O, S>>,
    work: Vec<f32>,
    last_diagnostics: Option<ParticleDiagnostics>,
}

/// The session with the paper's capacities.
pub type PaperSession = Session<PAPER_K, 512, 256, 481>;

/// Particles per node of [`PaperSession`] (the paper's k = 16).
pub const PAPER_K: usize = 16;

const _: () = assert!(
    std::mem::size_of::<PaperSession>() > 0
        && std::mem::size_of::<Planner<16, 512, 256, 481>>() == std::mem::size_of::<PaperPlanner>()
);

impl<const K: usize, const N: usize, const O: usize, const S: usize> Session<K, N, O, S> {
    /// A session over `models`.
    pub fn new(models: Models) -> Self {
        Self {
            models,
            planner: Box::new(Planner::new()),
            work: Vec::new(),
            last_diagnostics: None,
        }
    }

    /// The models.
    pub fn models_mut(&mut self) -> &mut Models {
        &mut self.models
    }

    /// Plan `spec` (engines → adapters → planner, [`plan_with_engines`]); every engine call
    /// takes a whole sampler batch.
    pub fn plan(
        &mut self,
        spec: &PlanSpec,
        clock: &mut impl Clock,
    ) -> Result<SearchReport, SessionError> {
        let dims = DenoiserEngine::dims(&self.models.denoiser);
        let segments = spec.segments_per_call();
        let layout = SessionLayout::new(dims, segments, segments);
        self.work.clear();
        self.work.resize(layout.total(), 0.0);
        plan_with_engines(
            &mut self.planner,
            spec,
            &mut self.models.denoiser,
            &mut self.models.discriminator,
            &layout,
            &mut self.work,
            clock,
        )
    }
}

#[cfg(test)]
mod psi_tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn psi_must_have_seen_the_planners_samples() {
        let ddpm16: SamplerConfig = "ddpm:16".parse().unwrap();
        let trained = names(&["ddpm", "ddim:8", "ddpm:16+anchor"]);
        // The screwdriver anchors its samples, the card does not.
        assert_eq!(
            planner_sample_name(&ddpm16, Task::Screwdriver),
            "ddpm:16+anchor"
        );
        assert_eq!(planner_sample_name(&ddpm16, Task::Card), "ddpm:16");
        assert_eq!(psi_mismatch(&trained, &ddpm16, Task::Screwdriver), None);
        // Trained for ddpm:16 with the anchor: another planner sampler is refused.
        let ddpm32: SamplerConfig = "ddpm:32".parse().unwrap();
        let e = psi_mismatch(&trained, &ddpm32, Task::Screwdriver)
            .unwrap()
            .to_string();
        assert!(e.contains("never saw the planner's ddpm:32+anchor"), "{e}");
        assert!(e.contains("planner_fakes = [32]"), "{e}");
        // The card does not anchor: none of the screwdriver-trained Ψ's planner samplers
        // applies, but the paper's ddpm and ddim:8 are drawn as Ψ saw them.
        let m = psi_mismatch(&trained, &ddpm16, Task::Card).unwrap();
        assert_eq!(m.usable, ["ddpm", "ddim:8"]);
        let e = m.to_string();
        assert!(e.contains("plan with the sampler ddpm or ddim:8"), "{e}");
        // The paper's negatives alone (the shipped recipe) pass with any planner sampler.
        let paper = names(&["ddpm", "ddim:8"]);
        assert_eq!(psi_mismatch(&paper, &ddpm16, Task::Screwdriver), None);
        assert_eq!(psi_mismatch(&paper, &ddpm32, Task::Card), None);
    }
}
