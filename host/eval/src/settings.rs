//! What an evaluation is, and its `eval.json`.

use std::path::{Path, PathBuf};

use dips_batch::{ProgressMode, Shard};
use dips_exec::{ExecProfile, ExecSettings, PoseEstimate, Press, ProfileError, RegraspGuard};
use dips_kernel::diffusion::SamplingMethod;
use dips_kernel::search::CostToCome;
use dips_kernel::task::CardGoals;
use dips_link::KernelTarget;
use dips_onnx::EngineKind;
use dips_planning::first_mode::FirstModeRule;
use dips_planning::online::{
    Method, OnlineSettings, SearchDepth, TimeBudgetError, check_time_budget_s,
};
use dips_planning::sized::PlannerSize;
use dips_planning::stop_rule::StopRule;
use dips_world::hand::{HandKind, TrackerNoise};
use dips_world::scenes::SceneKind;
use serde::{Deserialize, Deserializer, Serialize};

/// What makes two episodes of one method and seed the same: a resumed evaluation must agree
/// on all of it (`eval.json`), or its table would mix settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeSettings {
    /// The task.
    #[serde(with = "crate::by_name")]
    pub task: SceneKind,
    /// The sampler's method (`ddpm`, `ddpm:S`, `ddim:S`), its guidance and clip the
    /// defaults.
    #[serde(with = "crate::by_name")]
    pub sampler: SamplingMethod,
    /// Wall-clock budget of one planning call (s).
    pub time_budget_s: f64,
    /// Most expansions per planning call (0: the planner's capacity); the task's when none
    /// was given.
    pub node_budget: u32,
    /// Mode limit per episode (`None`: the task's).
    pub max_modes: Option<usize>,
    /// How the search formed `g`. Files written before it was recorded were all
    /// `cumulative`.
    #[serde(default = "cumulative", with = "crate::by_name")]
    pub cost_to_come: CostToCome,
    /// How deep the planning calls searched. Files written before it was recorded (without
    /// it, or with `""`) used the task's rule of then, which [`EvalFile`] fills in when it is
    /// read.
    #[serde(with = "crate::by_name")]
    pub search_depth: SearchDepth,
    /// The heuristic's `α` when `--alpha` set it (absent: the task's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<f32>,
    /// The heuristic's `β` when `--beta` set it (absent: the task's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f32>,
    /// Models directory (absolute; in a protocol, where they were when it was written).
    pub models: PathBuf,
    /// Engine of the models.
    #[serde(with = "crate::by_name")]
    pub engine: EngineKind,
    /// The hand that executed the episodes (`--hand`). Written only when it is not our world,
    /// so that the files of our world's runs, and the protocols that hold them, read as before:
    /// absent means `world`.
    #[serde(default, skip_serializing_if = "is_world")]
    pub hand: HandKind,
    /// The simulated tracker's noise (`--noise-position`, `--noise-rotation`; absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracker_noise: Option<TrackerNoise>,
    /// The card's goals (`--card-goals`). Written only when they are not ours, so that files
    /// and protocols written before they could differ read as before: absent means `capped`.
    #[serde(default, skip_serializing_if = "CardGoals::is_capped")]
    pub card_goals: CardGoals,
    /// When a searching method stopped before its mode limit (`--stop-rule`). Written only
    /// when it is not the paper's, so that earlier files and protocols read as before: absent
    /// means `goal-reached`.
    #[serde(default, skip_serializing_if = "StopRule::is_paper")]
    pub stop_rule: StopRule,
    /// Which modes a plan could begin with (`--first-mode`). Written only when it is not the
    /// paper's: absent means `any`.
    #[serde(default, skip_serializing_if = "FirstModeRule::is_paper")]
    pub first_mode: FirstModeRule,
    /// The in-process planner's capacities (`--planner-size`). Written only when they are
    /// not the firmware's: absent means `paper`.
    #[serde(default, skip_serializing_if = "PlannerSize::is_paper")]
    pub planner_size: PlannerSize,
    /// The CSVTO settings the modes are executed with (`--exec-profile`). Written only when
    /// they are not the simulation's: absent means `simulation`.
    #[serde(default, skip_serializing_if = "ExecProfile::is_simulation")]
    pub exec_profile: ExecProfile,
    /// The object pose the modes' solves start from (`--pose-estimate`). Written only when
    /// it is not the tracker's: absent means `tracker`.
    #[serde(default, skip_serializing_if = "PoseEstimate::is_tracker")]
    pub pose_estimate: PoseEstimate,
    /// Whether regrasping fingers' commands are guarded (`--regrasp-guard`). Written only
    /// when on: absent means `off`.
    #[serde(default, skip_serializing_if = "RegraspGuard::is_off")]
    pub regrasp_guard: RegraspGuard,
    /// How hard the contact fingers pressed (`--press`). Written only when not light:
    /// absent means `light`.
    #[serde(default, skip_serializing_if = "Press::is_light")]
    pub press: Press,
}

impl EpisodeSettings {
    /// The first setting where `self` (the directory's) and `other` (this run's) differ, as
    /// (its field in `eval.json`'s `episode`, its value in `self`, its value in `other`),
    /// values as JSON writes them (`sampler`, `node_budget`, `tracker_noise.rotation`, ...).
    pub fn first_difference(&self, other: &Self) -> (String, String, String) {
        let (a, b) = (
            serde_json::to_value(self).unwrap_or_default(),
            serde_json::to_value(other).unwrap_or_default(),
        );
        if a == b {
            return ("settings".into(), String::new(), String::new());
        }
        let (field, there, here) = dips_batch::first_difference(&a, &b, "");
        (field.trim_start_matches('.').to_string(), there, here)
    }
}

fn is_world(hand: &HandKind) -> bool {
    *hand == HandKind::World
}

/// What [`EpisodeSettings::cost_to_come`] was before it was recorded.
fn cumulative() -> CostToCome {
    CostToCome::Cumulative
}

/// The search depth of every evaluation written before [`EpisodeSettings::search_depth`] was
/// recorded: the screwdriver's fixed depth, the card's modes left.
fn depth_before_recorded(scene: SceneKind) -> SearchDepth {
    match scene {
        SceneKind::Screwdriver => SearchDepth::Fixed,
        SceneKind::Card => SearchDepth::ModesLeft,
    }
}

/// One evaluation run (this machine's shard of it).
#[derive(Debug, Clone)]
pub struct EvalSettings {
    /// The task.
    pub task: SceneKind,
    /// The methods, in table order.
    pub methods: Vec<Method>,
    /// Trials per method.
    pub trials: usize,
    /// Seed of trial 0; trial `i` has seed `first_seed + i` for every method.
    pub first_seed: u64,
    /// The episodes (method × trial, in that order) this run takes.
    pub shard: Shard,
    /// Episodes run at once.
    pub jobs: usize,
    /// Threads of each model call inside an episode ([`dips_planning::Models::set_threads`]).
    pub model_threads: usize,
    /// The sampler, the search's settings over the task's, the budgets and the mode limit.
    pub online: OnlineSettings,
    /// Models directory.
    pub models: PathBuf,
    /// Engine of the models.
    pub engine: EngineKind,
    /// Progress on stderr: a bar on a terminal, log lines otherwise, or none.
    pub progress: ProgressMode,
    /// Stop after this many new episodes (tests simulate a kill with it).
    pub stop_after: Option<usize>,
    /// Where the planning calls are made (`--kernel`); the results are the same bit for bit,
    /// so it is not part of [`EpisodeSettings`].
    pub kernel: KernelTarget,
    /// The hand that executes the episodes (`--hand`); each worker thread opens its own.
    pub hand: HandKind,
    /// Tracker noise of the executing hand (`None`: the exact pose); episode `s` seeds it with
    /// `s`.
    pub tracker_noise: Option<TrackerNoise>,
    /// The card's goals every method executes and plans with (resolved against the models',
    /// [`dips_planning::resolve_card_goals`]).
    pub card_goals: CardGoals,
    /// Which of the paper's CSVTO settings execute the modes (`--exec-profile`).
    pub exec_profile: ExecProfile,
    /// The object pose the modes' solves start from (`--pose-estimate`).
    pub pose_estimate: PoseEstimate,
    /// Whether regrasping fingers' commands are guarded (`--regrasp-guard`).
    pub regrasp_guard: RegraspGuard,
    /// How hard the contact fingers of executed modes press (`--press`).
    pub press: Press,
    /// The run's registration under a protocol (`dips eval --protocol`,
    /// [`crate::protocol::ProtocolFile::register`]), written to `registration.json` when the
    /// directory is claimed; `None` for a run without a protocol.
    pub registration: Option<crate::protocol::Registration>,
}

/// Settings that no evaluation can run with ([`EvalSettings::validate`]). Each message names
/// the setting, its value and what is allowed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// No method was asked for.
    #[error("the method list is empty; available: {}", Method::NAMES.join(", "))]
    NoMethods,
    /// A method was asked for twice.
    #[error("the method list names {0} twice")]
    MethodTwice(Method),
    /// No trials.
    #[error("trials: 0, must be at least 1")]
    NoTrials,
    /// No episodes at once.
    #[error("jobs: 0, must be at least 1")]
    NoJobs,
    /// No threads per model call.
    #[error("model threads: 0, must be at least 1")]
    NoModelThreads,
    /// The seeds run past `u64::MAX`.
    #[error("first seed {first_seed} + {trials} trials overflows the seed range")]
    SeedOverflow {
        /// The first seed.
        first_seed: u64,
        /// The trials.
        trials: usize,
    },
    /// The planning call's time budget is not a budget.
    #[error(transparent)]
    TimeBudget(#[from] TimeBudgetError),
    /// A mode limit of 0.
    #[error("mode limit: 0, must be at least 1")]
    NoModes,
    /// Several episodes at once on one TCP kernel.
    #[error(
        "kernel {kernel}: a TCP kernel serves one connection at a time; run {jobs} jobs on a \
         spawned kernel (one firmware per episode), or one job on it"
    )]
    TcpJobs {
        /// The kernel.
        kernel: KernelTarget,
        /// The episodes asked to run at once.
        jobs: usize,
    },
    /// The CSVTO profile does not exist for the task.
    #[error(transparent)]
    Profile(#[from] ProfileError),
}

/// Why `eval.json` cannot be read, or an output directory cannot be claimed
/// ([`read_eval_file`], [`claim_dir`]). Each message names the file and the setting.
#[derive(Debug, thiserror::Error)]
pub enum EvalFileError {
    /// The file cannot be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not an `eval.json`.
    #[error("{} is not an eval settings file (delete it to start over)", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What serde found.
        #[source]
        source: serde_json::Error,
    },
    /// The output directory cannot be made.
    #[error("cannot create the output directory {}", dir.display())]
    Create {
        /// The directory.
        dir: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The directory holds an evaluation of other settings.
    #[error(
        "{} holds an evaluation with other settings: {field} is {there} there and {here} here; \
         use another output directory, or the same task, sampler, budgets, mode limit, \
         cost-to-come, search depth, models, engine, hand, tracker noise and card goals",
        file.display()
    )]
    OtherSettings {
        /// The directory's `eval.json`.
        file: PathBuf,
        /// The first setting that differs ([`EpisodeSettings::first_difference`]).
        field: String,
        /// Its value there, as JSON.
        there: String,
        /// Its value in this run, as JSON.
        here: String,
    },
    /// The directory's evaluation starts at another seed.
    #[error("{} was started with first seed {there}; this run asks for {here}", file.display())]
    OtherFirstSeed {
        /// The directory's `eval.json`.
        file: PathBuf,
        /// Its first seed.
        there: u64,
        /// This run's.
        here: u64,
    },
    /// The directory holds another registration's results.
    #[error(transparent)]
    Protocol(#[from] crate::protocol::ProtocolError),
    /// The file cannot be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The settings cannot be written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

impl EvalSettings {
    /// Check the settings; the error names the setting and what is allowed.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.methods.is_empty() {
            return Err(SettingsError::NoMethods);
        }
        for (i, m) in self.methods.iter().enumerate() {
            if self.methods[..i].contains(m) {
                return Err(SettingsError::MethodTwice(*m));
            }
        }
        if self.trials == 0 {
            return Err(SettingsError::NoTrials);
        }
        if self.jobs == 0 {
            return Err(SettingsError::NoJobs);
        }
        if self.model_threads == 0 {
            return Err(SettingsError::NoModelThreads);
        }
        if self.first_seed.checked_add(self.trials as u64).is_none() {
            return Err(SettingsError::SeedOverflow {
                first_seed: self.first_seed,
                trials: self.trials,
            });
        }
        check_time_budget_s(self.online.time_budget_s)?;
        if self.online.max_modes == Some(0) {
            return Err(SettingsError::NoModes);
        }
        if matches!(self.kernel, KernelTarget::Tcp(_)) && self.jobs > 1 {
            return Err(SettingsError::TcpJobs {
                kernel: self.kernel.clone(),
                jobs: self.jobs,
            });
        }
        self.exec_settings()?;
        Ok(())
    }

    /// How every episode executes its modes: the task's CSVTO settings under
    /// [`EvalSettings::exec_profile`], aiming at [`EvalSettings::card_goals`], starting each
    /// solve from [`EvalSettings::pose_estimate`], with [`EvalSettings::regrasp_guard`] and
    /// [`EvalSettings::press`].
    pub fn exec_settings(&self) -> Result<ExecSettings, ProfileError> {
        Ok(ExecSettings {
            card_goals: self.card_goals,
            pose_estimate: self.pose_estimate,
            regrasp_guard: self.regrasp_guard,
            press: self.press,
            ..ExecSettings::for_profile(self.task, self.exec_profile)?
        })
    }

    /// The seed of trial `i`.
    pub fn seed(&self, trial: usize) -> u64 {
        self.first_seed + trial as u64
    }

    /// Every (method, seed) of the evaluation in table order, and this shard's part of it.
    pub fn episodes(&self) -> Vec<(Method, u64)> {
        let all: Vec<(Method, u64)> = self
            .methods
            .iter()
            .flat_map(|&m| (0..self.trials).map(move |i| (m, i)))
            .map(|(m, i)| (m, self.seed(i)))
            .collect();
        self.shard.take(&all)
    }

    /// This run's `eval.json`: its episode settings, methods and seeds.
    pub fn eval_file(&self) -> EvalFile {
        EvalFile {
            episode: self.episode_settings(),
            methods: self.methods.clone(),
            first_seed: self.first_seed,
            trials: self.trials,
        }
    }

    /// The settings every episode of the directory must share: the search's as its planning
    /// calls resolve them ([`SearchOverrides::resolve`](dips_kernel::search::SearchOverrides::resolve)).
    pub fn episode_settings(&self) -> EpisodeSettings {
        let task = self.task.task();
        let search = self.online.search.resolve(task, 0, 0);
        EpisodeSettings {
            task: self.task,
            sampler: self.online.sampler.method,
            time_budget_s: self.online.time_budget_s,
            node_budget: search.node_budget,
            max_modes: self.online.max_modes,
            cost_to_come: search.cost_to_come,
            search_depth: self.online.depth_rule(self.task),
            alpha: self.online.search.alpha,
            beta: self.online.search.beta,
            models: std::path::absolute(&self.models).unwrap_or_else(|_| self.models.clone()),
            engine: self.engine,
            hand: self.hand.clone(),
            tracker_noise: self.tracker_noise,
            card_goals: self.card_goals,
            stop_rule: self.online.stop_rule,
            first_mode: self.online.first_mode,
            planner_size: self.online.planner_size,
            exec_profile: self.exec_profile,
            pose_estimate: self.pose_estimate,
            regrasp_guard: self.regrasp_guard,
            press: self.press,
        }
    }
}

/// `eval.json`: the episode settings and the union of methods and seeds asked for so far.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalFile {
    /// What every episode shares (a search depth not recorded is filled in,
    /// [`EpisodeSettings::search_depth`]).
    #[serde(deserialize_with = "episode_recorded")]
    pub episode: EpisodeSettings,
    /// Methods, in table order (new ones are appended on resume).
    #[serde(with = "crate::by_name::list")]
    pub methods: Vec<Method>,
    /// Seed of trial 0.
    pub first_seed: u64,
    /// Trials per method (the largest asked for).
    pub trials: usize,
}

/// The file name of the settings.
pub const EVAL_FILE: &str = "eval.json";

/// [`EvalFile::episode`] as written, with the search depth of a file written before it was
/// recorded (absent, or `""`) filled in: the task's rule of then ([`depth_before_recorded`]).
/// A task that is not one is left to the settings' own error.
fn episode_recorded<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<EpisodeSettings, D::Error> {
    let mut value = serde_json::Value::deserialize(deserializer)?;
    if let Some(episode) = value.as_object_mut()
        && episode.get("search_depth").is_none_or(|d| d == "")
        && let Some(scene) = episode
            .get("task")
            .and_then(serde_json::Value::as_str)
            .and_then(|t| t.parse::<SceneKind>().ok())
    {
        let depth = depth_before_recorded(scene).name();
        episode.insert("search_depth".into(), depth.into());
    }
    EpisodeSettings::deserialize(value).map_err(serde::de::Error::custom)
}

/// Read `dir/eval.json` if present.
pub fn read_eval_file(dir: &Path) -> Result<Option<EvalFile>, EvalFileError> {
    let path = dir.join(EVAL_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(source) => return Err(EvalFileError::Read { path, source }),
    };
    match serde_json::from_str(&text) {
        Ok(file) => Ok(Some(file)),
        Err(source) => Err(EvalFileError::Parse { path, source }),
    }
}

/// Write `dir/eval.json` for `settings`, merged with the file already there; errors when the
/// directory holds episodes of other settings, or of another registration
/// ([`crate::protocol::claim_registration`], which writes `registration.json`).
pub fn claim_dir(dir: &Path, settings: &EvalSettings) -> Result<EvalFile, EvalFileError> {
    std::fs::create_dir_all(dir).map_err(|source| EvalFileError::Create {
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut file = settings.eval_file();
    let episode = file.episode.clone();
    if let Some(old) = read_eval_file(dir)? {
        if old.episode != episode {
            let (field, there, here) = old.episode.first_difference(&episode);
            return Err(EvalFileError::OtherSettings {
                file: dir.join(EVAL_FILE),
                field,
                there,
                here,
            });
        }
        if old.first_seed != settings.first_seed {
            return Err(EvalFileError::OtherFirstSeed {
                file: dir.join(EVAL_FILE),
                there: old.first_seed,
                here: settings.first_seed,
            });
        }
        let mut methods = old.methods.clone();
        for m in &file.methods {
            if !methods.contains(m) {
                methods.push(*m);
            }
        }
        file.methods = methods;
        file.trials = file.trials.max(old.trials);
    }
    // Before eval.json is written: whether the directory held an evaluation decides.
    crate::protocol::claim_registration(dir, settings.registration.as_ref())?;
    let text = serde_json::to_string_pretty(&file)?;
    // Shards on several hosts may claim one directory at once: the atomic writer names its
    // temporary file after the host too, so their writes never share one.
    let path = dir.join(EVAL_FILE);
    dips_fs::write_atomic(&path, text.as_bytes())
        .map_err(|source| EvalFileError::Write { path, source })?;
    Ok(file)
}

/// The directory of one episode.
pub fn episode_dir(dir: &Path, method: Method, seed: u64) -> PathBuf {
    dir.join("episodes")
        .join(method.name())
        .join(format!("seed-{seed}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dips_kernel::diffusion::SamplerConfig;

    fn settings() -> EpisodeSettings {
        EpisodeSettings {
            task: SceneKind::Card,
            sampler: "ddpm:16".parse::<SamplerConfig>().unwrap().method,
            time_budget_s: 300.0,
            node_budget: 0,
            max_modes: None,
            cost_to_come: CostToCome::Cumulative,
            search_depth: SearchDepth::ModesLeft,
            alpha: None,
            beta: None,
            models: "/m".into(),
            engine: EngineKind::Kernel,
            hand: HandKind::World,
            tracker_noise: None,
            card_goals: CardGoals::Capped,
            stop_rule: StopRule::GoalReached,
            first_mode: FirstModeRule::Any,
            planner_size: PlannerSize::Paper,
            exec_profile: ExecProfile::Simulation,
            pose_estimate: PoseEstimate::Tracker,
            regrasp_guard: RegraspGuard::Off,
            press: Press::Light,
        }
    }

    #[test]
    fn the_exec_profile_round_trips_and_the_simulations_is_the_default() {
        let sim = settings();
        assert!(
            serde_json::to_value(&sim)
                .unwrap()
                .get("exec_profile")
                .is_none()
        );
        let hw = EpisodeSettings {
            exec_profile: ExecProfile::Hardware,
            ..sim.clone()
        };
        let v = serde_json::to_value(&hw).unwrap();
        assert_eq!(v["exec_profile"], "hardware");
        let back: EpisodeSettings = serde_json::from_value(v).unwrap();
        assert_eq!(back, hw);
        assert_eq!(
            sim.first_difference(&hw),
            (
                "exec_profile".into(),
                "(absent)".into(),
                "\"hardware\"".into()
            )
        );
        // The pose estimate likewise: absent is the tracker's, `contacts` is written.
        assert!(
            serde_json::to_value(&sim)
                .unwrap()
                .get("pose_estimate")
                .is_none()
        );
        let fused = EpisodeSettings {
            pose_estimate: PoseEstimate::Contacts,
            ..sim.clone()
        };
        let v = serde_json::to_value(&fused).unwrap();
        assert_eq!(v["pose_estimate"], "contacts");
        assert_eq!(serde_json::from_value::<EpisodeSettings>(v).unwrap(), fused);
        assert_eq!(sim.first_difference(&fused).0, "pose_estimate");
        // The regrasp guard likewise: absent is off, `clearance` is written.
        let guarded = EpisodeSettings {
            regrasp_guard: RegraspGuard::Clearance,
            ..sim.clone()
        };
        let v = serde_json::to_value(&guarded).unwrap();
        assert_eq!(v["regrasp_guard"], "clearance");
        assert_eq!(
            serde_json::from_value::<EpisodeSettings>(v).unwrap(),
            guarded
        );
        assert_eq!(sim.first_difference(&guarded).0, "regrasp_guard");
        // The press likewise: absent is light, `firm` is written.
        assert!(serde_json::to_value(&sim).unwrap().get("press").is_none());
        let firm = EpisodeSettings {
            press: Press::Firm,
            ..sim.clone()
        };
        let v = serde_json::to_value(&firm).unwrap();
        assert_eq!(v["press"], "firm");
        assert_eq!(serde_json::from_value::<EpisodeSettings>(v).unwrap(), firm);
        assert_eq!(sim.first_difference(&firm).0, "press");
        assert!(
            serde_json::to_value(&sim)
                .unwrap()
                .get("regrasp_guard")
                .is_none()
        );
    }

    #[test]
    fn the_stop_rule_first_mode_and_planner_size_round_trip_and_the_papers_are_the_default() {
        let paper = serde_json::to_value(settings()).unwrap();
        assert!(paper.get("stop_rule").is_none() && paper.get("planner_size").is_none());
        assert!(paper.get("first_mode").is_none());
        let ours = EpisodeSettings {
            stop_rule: StopRule::NoGain,
            first_mode: FirstModeRule::Touching,
            planner_size: PlannerSize::Host,
            ..settings()
        };
        let v = serde_json::to_value(&ours).unwrap();
        assert_eq!(v["stop_rule"], "no-gain");
        assert_eq!(v["first_mode"], "touching");
        assert_eq!(v["planner_size"], "host");
        assert_eq!(serde_json::from_value::<EpisodeSettings>(v).unwrap(), ours);
        assert_eq!(
            settings().first_difference(&ours).0,
            "first_mode",
            "a resumed run with another rule or planner is refused"
        );
        let host = EpisodeSettings {
            planner_size: PlannerSize::Host,
            ..settings()
        };
        assert_eq!(settings().first_difference(&host).0, "planner_size");
    }

    #[test]
    fn a_search_depth_not_recorded_reads_as_the_tasks_of_then() {
        let file = EvalFile {
            episode: settings(),
            methods: vec![Method::Dips, Method::DipsK1],
            first_seed: 1000,
            trials: 2,
        };
        let written = serde_json::to_value(&file).unwrap();
        assert_eq!(written["methods"], serde_json::json!(["dips", "dips-k1"]));
        assert_eq!(
            serde_json::from_value::<EvalFile>(written.clone()).unwrap(),
            file
        );
        for (task, then) in [
            (SceneKind::Screwdriver, SearchDepth::Fixed),
            (SceneKind::Card, SearchDepth::ModesLeft),
        ] {
            for recorded in [None, Some("")] {
                let mut old = written.clone();
                old["episode"]["task"] = task.name().into();
                let episode = old["episode"].as_object_mut().unwrap();
                match recorded {
                    None => episode.remove("search_depth"),
                    Some(d) => episode.insert("search_depth".into(), d.into()),
                };
                let read: EvalFile = serde_json::from_value(old).unwrap();
                assert_eq!(read.episode.search_depth, then, "{task} {recorded:?}");
            }
        }
        let mut bad = written;
        bad["episode"]["search_depth"] = "deep".into();
        let e = serde_json::from_value::<EvalFile>(bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown search depth `deep`"), "{e}");
    }

    #[test]
    fn the_card_goals_round_trip_and_ours_are_the_default() {
        let ours = serde_json::to_value(settings()).unwrap();
        assert!(ours.get("card_goals").is_none(), "old files read as before");
        let paper = EpisodeSettings {
            card_goals: CardGoals::Paper,
            ..settings()
        };
        let v = serde_json::to_value(&paper).unwrap();
        assert_eq!(v["card_goals"], "paper");
        assert_eq!(serde_json::from_value::<EpisodeSettings>(v).unwrap(), paper);
        assert_eq!(
            settings().first_difference(&paper),
            ("card_goals".into(), "(absent)".into(), "\"paper\"".into()),
            "a resumed run with other card goals is refused"
        );
    }

    #[test]
    fn the_hand_round_trips_and_our_world_is_the_default() {
        let world = serde_json::to_value(settings()).unwrap();
        assert!(world.get("hand").is_none() && world.get("tracker_noise").is_none());
        assert_eq!(
            serde_json::from_value::<EpisodeSettings>(world).unwrap(),
            settings()
        );
        let mujoco = EpisodeSettings {
            hand: HandKind::Mujoco,
            tracker_noise: Some(TrackerNoise {
                position: 0.001,
                rotation: 0.02,
            }),
            ..settings()
        };
        let v = serde_json::to_value(&mujoco).unwrap();
        assert_eq!(v["hand"], "mujoco");
        assert_eq!(v["tracker_noise"]["rotation"], 0.02);
        assert_eq!(
            serde_json::from_value::<EpisodeSettings>(v).unwrap(),
            mujoco
        );
        assert_eq!(
            settings().first_difference(&mujoco).0,
            "hand",
            "a resumed run on another hand is refused"
        );
    }

    #[test]
    fn the_differing_setting_is_named_with_both_values() {
        let there = settings();
        let here = EpisodeSettings {
            sampler: SamplerConfig::ddim(8).method,
            ..settings()
        };
        assert_eq!(
            there.first_difference(&here),
            ("sampler".into(), "\"ddpm:16\"".into(), "\"ddim:8\"".into())
        );
        let here = EpisodeSettings {
            max_modes: Some(3),
            ..settings()
        };
        assert_eq!(
            there.first_difference(&here),
            ("max_modes".into(), "null".into(), "3".into())
        );
    }
}
