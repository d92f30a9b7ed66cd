//! What an evaluation is, and its `eval.json`.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use dips_batch::{ProgressMode, Shard};
use dips_host::hand::{HandKind, TrackerNoise};
use dips_host::online::{Method, OnlineSettings, SearchDepth, check_time_budget_s};
use dips_host::scenes::SceneKind;
use dips_kernel::search::CostToCome;
use dips_kernel::task::CardGoals;
use dips_link::KernelTarget;
use dips_onnx::EngineKind;
use serde::{Deserialize, Serialize};

/// What makes two episodes of one method and seed the same: a resumed evaluation must agree
/// on all of it (`eval.json`), or its table would mix settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeSettings {
    /// Task name.
    pub task: String,
    /// Sampler name (`ddpm` or `ddim:S`).
    pub sampler: String,
    /// Wall-clock budget of one planning call (s).
    pub time_budget_s: f64,
    /// Most expansions per planning call (0: the planner's capacity); the task's when none
    /// was given.
    pub node_budget: u32,
    /// Mode limit per episode (`None`: the task's).
    pub max_modes: Option<usize>,
    /// How the search formed `g` ([`CostToCome::name`]). Files written before it was
    /// recorded were all `cumulative`.
    #[serde(default = "cumulative")]
    pub cost_to_come: String,
    /// How deep the planning calls searched ([`SearchDepth::name`]). Files written before it
    /// was recorded used the task's rule of then, which is filled in when they are read.
    #[serde(default)]
    pub search_depth: String,
    /// The heuristic's `α` when `--alpha` set it (absent: the task's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<f32>,
    /// The heuristic's `β` when `--beta` set it (absent: the task's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f32>,
    /// Models directory (absolute).
    pub models: String,
    /// Engine of the models (`kernel` or `tract`).
    pub engine: String,
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
}

impl EpisodeSettings {
    /// The first setting where `self` (the directory's) and `other` (this run's) differ, as
    /// (its name, its value in `self`, its value in `other`), values as JSON writes them; the
    /// name is the flag's where there is one (`--sampler`, `--node-budget`, ...).
    pub fn first_difference(&self, other: &Self) -> (String, String, String) {
        let (a, b) = (
            serde_json::to_value(self).unwrap_or_default(),
            serde_json::to_value(other).unwrap_or_default(),
        );
        if a == b {
            return ("settings".into(), String::new(), String::new());
        }
        let (field, there, here) = dips_batch::first_difference(&a, &b, "");
        (
            format!("--{}", field.trim_start_matches('.').replace('_', "-")),
            there,
            here,
        )
    }
}

fn is_world(hand: &HandKind) -> bool {
    *hand == HandKind::World
}

/// What [`EpisodeSettings::cost_to_come`] was before it was recorded.
fn cumulative() -> String {
    CostToCome::Cumulative.name().to_string()
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
    /// Threads of each model call inside an episode ([`dips_host::planning::Models::set_threads`]).
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
    /// [`dips_host::planning::resolve_card_goals`]).
    pub card_goals: CardGoals,
    /// The run's registration under a protocol (`dips eval --protocol`,
    /// [`crate::protocol::ProtocolFile::register`]), written to `registration.json` when the
    /// directory is claimed; `None` for a run without a protocol.
    pub registration: Option<crate::protocol::Registration>,
}

impl EvalSettings {
    /// Check the settings; the error names the flag and what is allowed.
    pub fn validate(&self) -> anyhow::Result<()> {
        if self.methods.is_empty() {
            bail!(
                "--methods is empty; available: {}",
                Method::ALL.map(Method::name).join(", ")
            );
        }
        for (i, m) in self.methods.iter().enumerate() {
            if self.methods[..i].contains(m) {
                bail!("--methods names {} twice", m.name());
            }
        }
        if self.trials == 0 {
            bail!("--trials must be at least 1");
        }
        if self.jobs == 0 {
            bail!("--jobs must be at least 1");
        }
        if self.model_threads == 0 {
            bail!("--model-threads must be at least 1");
        }
        if self.first_seed.checked_add(self.trials as u64).is_none() {
            bail!("--first-seed + --trials overflows the seed range");
        }
        check_time_budget_s(self.online.time_budget_s)?;
        if self.online.max_modes == Some(0) {
            bail!("--max-modes must be at least 1");
        }
        if matches!(self.kernel, KernelTarget::Tcp(_)) && self.jobs > 1 {
            bail!(
                "--kernel {}: a TCP kernel serves one connection at a time; use --jobs 1, or \
                 --kernel spawn (one firmware per episode)",
                self.kernel
            );
        }
        Ok(())
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
            methods: self.methods.iter().map(|m| m.name().to_string()).collect(),
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
            task: self.task.name().to_string(),
            sampler: self.online.sampler.method.to_string(),
            time_budget_s: self.online.time_budget_s,
            node_budget: search.node_budget,
            max_modes: self.online.max_modes,
            cost_to_come: search.cost_to_come.name().to_string(),
            search_depth: self.online.depth_rule(self.task).name().to_string(),
            alpha: self.online.search.alpha,
            beta: self.online.search.beta,
            models: std::path::absolute(&self.models)
                .unwrap_or_else(|_| self.models.clone())
                .display()
                .to_string(),
            engine: match self.engine {
                EngineKind::Kernel => "kernel",
                EngineKind::Tract => "tract",
            }
            .to_string(),
            hand: self.hand,
            tracker_noise: self.tracker_noise,
            card_goals: self.card_goals,
        }
    }
}

/// `eval.json`: the episode settings and the union of methods and seeds asked for so far.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalFile {
    /// What every episode shares.
    pub episode: EpisodeSettings,
    /// Methods, in table order (new ones are appended on resume).
    pub methods: Vec<String>,
    /// Seed of trial 0.
    pub first_seed: u64,
    /// Trials per method (the largest asked for).
    pub trials: usize,
}

/// The file name of the settings.
pub const EVAL_FILE: &str = "eval.json";

/// Read `dir/eval.json` if present.
pub fn read_eval_file(dir: &Path) -> anyhow::Result<Option<EvalFile>> {
    let path = dir.join(EVAL_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let mut file: EvalFile = serde_json::from_str(&text).with_context(|| {
        format!(
            "{} is not an eval settings file (delete it to start over)",
            path.display()
        )
    })?;
    if file.episode.search_depth.is_empty() {
        let scene: SceneKind = file
            .episode
            .task
            .parse()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        file.episode.search_depth = depth_before_recorded(scene).name().to_string();
    }
    Ok(Some(file))
}

/// Write `dir/eval.json` for `settings`, merged with the file already there; errors when the
/// directory holds episodes of other settings, or of another registration
/// ([`crate::protocol::claim_registration`], which writes `registration.json`).
pub fn claim_dir(dir: &Path, settings: &EvalSettings) -> anyhow::Result<EvalFile> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the output directory {}", dir.display()))?;
    let mut file = settings.eval_file();
    let episode = file.episode.clone();
    if let Some(old) = read_eval_file(dir)? {
        if old.episode != episode {
            let (name, there, here) = old.episode.first_difference(&episode);
            bail!(
                "{} holds an evaluation with other settings: {name} is {there} there and {here} \
                 here; use another --out, or the same task, sampler, budgets, mode limit, \
                 cost-to-come, search depth, models, engine, hand, tracker noise and card goals",
                dir.join(EVAL_FILE).display(),
            );
        }
        if old.first_seed != settings.first_seed {
            bail!(
                "{} was started with --first-seed {}; this run asks for {}",
                dir.join(EVAL_FILE).display(),
                old.first_seed,
                settings.first_seed
            );
        }
        let mut methods = old.methods.clone();
        for m in &file.methods {
            if !methods.contains(m) {
                methods.push(m.clone());
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
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(file)
}

/// The directory of one episode.
pub fn episode_dir(dir: &Path, method: &str, seed: u64) -> PathBuf {
    dir.join("episodes")
        .join(method)
        .join(format!("seed-{seed}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> EpisodeSettings {
        EpisodeSettings {
            task: "card".into(),
            sampler: "ddpm:16".into(),
            time_budget_s: 300.0,
            node_budget: 0,
            max_modes: None,
            cost_to_come: "cumulative".into(),
            search_depth: "modes-left".into(),
            alpha: None,
            beta: None,
            models: "/m".into(),
            engine: "kernel".into(),
            hand: HandKind::World,
            tracker_noise: None,
            card_goals: CardGoals::Capped,
        }
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
            ("--card-goals".into(), "(absent)".into(), "\"paper\"".into()),
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
            "--hand",
            "a resumed run on another hand is refused"
        );
    }

    #[test]
    fn the_differing_setting_is_named_with_both_values() {
        let there = settings();
        let here = EpisodeSettings {
            sampler: "ddim:8".into(),
            ..settings()
        };
        assert_eq!(
            there.first_difference(&here),
            (
                "--sampler".into(),
                "\"ddpm:16\"".into(),
                "\"ddim:8\"".into()
            )
        );
        let here = EpisodeSettings {
            max_modes: Some(3),
            ..settings()
        };
        assert_eq!(
            there.first_difference(&here),
            ("--max-modes".into(), "null".into(), "3".into())
        );
    }
}
