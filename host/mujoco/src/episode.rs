//! DIPS episodes executed on either hand (`dips-mujoco episode`, `dips-mujoco eval`): the
//! planner, the shipped models and CSVTO's internal model are `dips episode`'s
//! (`dips_host::online::run_online`); only the hand that executes the actions changes.
//! `result.json` records it in its `hand` field. See docs/mujoco.md, "DIPS on the MuJoCo hand".

use std::path::{Path, PathBuf};
use std::time::Instant;

use dips_host::execute::{EpisodeResult, ExecSettings};
use dips_host::online::{Method, OnlineSettings, run_online};
use dips_host::planning::{Models, models_dir};
use dips_onnx::EngineKind;
use dips_world::scenes::SceneKind;
use serde::{Deserialize, Serialize};

use crate::run::{AnyHand, HandKind};
use crate::{MujocoError, PoseNoise};

/// Errors of an episode or an evaluation.
#[derive(Debug, thiserror::Error)]
pub enum EpisodeError {
    /// The MuJoCo hand could not be built.
    #[error(transparent)]
    Hand(#[from] MujocoError),
    /// The models could not be loaded, or the episode failed (planner, CSVTO, the hand).
    #[error("{0}")]
    Episode(String),
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The report could not be written.
    #[error("report in {path}: {message}")]
    Report {
        /// The episode folder.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

fn episode_err(e: anyhow::Error) -> EpisodeError {
    EpisodeError::Episode(format!("{e:#}"))
}

/// What an episode runs: the method and its settings, and the hand that executes it.
#[derive(Debug, Clone)]
pub struct EpisodeSpec {
    /// The task.
    pub task: SceneKind,
    /// The method (`dips`, `dips-sampled`, ...).
    pub method: Method,
    /// The episode's seed.
    pub seed: u64,
    /// Which hand executes the actions.
    pub hand: HandKind,
    /// Tracker noise of the MuJoCo hand's object pose (`None`: exact).
    pub noise: Option<PoseNoise>,
    /// Models folder (`None`: the shipped models, `dips_host::planning::default_models_dir`).
    pub models: Option<PathBuf>,
    /// Threads of each model call.
    pub threads: usize,
    /// The planner's and samplers' settings, as `dips episode` takes them.
    pub online: OnlineSettings,
}

/// Run one episode of `spec` on a fresh hand from the task's start state.
pub fn run_episode(
    spec: &EpisodeSpec,
    progress: &mut dyn FnMut(&str),
) -> Result<EpisodeResult, EpisodeError> {
    let models = if spec.method.needs_models() {
        let dir = models_dir(spec.models.as_deref(), spec.task.task()).map_err(episode_err)?;
        let mut m =
            Models::load(EngineKind::Kernel, &dir, spec.task.task()).map_err(episode_err)?;
        m.set_threads(spec.threads);
        m.check_sampler(&spec.online.sampler, spec.task.task()).map_err(episode_err)?;
        Some(m)
    } else {
        None
    };
    let mut hand = AnyHand::new(spec.hand, spec.task, spec.noise)?;
    let exec = ExecSettings::for_task(spec.task);
    run_online(
        hand.hand(),
        spec.method,
        spec.seed,
        models,
        None,
        &exec,
        &spec.online,
        progress,
    )
    .map_err(episode_err)
}

/// Write `result` into `dir` (`result.json`, atomically) and its report (`dips episode`'s:
/// plots over time and `report.html`; the animation `episode.gif` when `animate`).
pub fn write_episode(
    dir: &Path,
    result: &EpisodeResult,
    animate: bool,
) -> Result<(), EpisodeError> {
    let file = dir.join("result.json");
    result.write(dir).map_err(|source| EpisodeError::Io {
        path: file.clone(),
        source,
    })?;
    let report = |message: String| EpisodeError::Report {
        path: dir.to_path_buf(),
        message,
    };
    let rec = dips_report::Recording::read(&file).map_err(|e| report(e.to_string()))?;
    dips_report::write_episode_report(dir, &rec, animate, &mut |_, _| {})
        .map_err(|e| report(e.to_string()))
}

/// `wall.json` of an evaluation's episode: written last, so an episode with one is finished.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EpisodeWall {
    /// Wall time of the episode (s).
    pub seconds: f64,
    /// Why the episode stopped without a result, if it did (counted as a failed trial and
    /// not run again).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The folder of one episode of an evaluation: `dips eval`'s layout,
/// `DIR/episodes/<method>/seed-<seed>`.
pub fn episode_dir(dir: &Path, method: Method, seed: u64) -> PathBuf {
    dir.join("episodes")
        .join(method.name())
        .join(format!("seed-{seed}"))
}

/// Whether the episode in `dir` has finished (its `wall.json` is there and readable).
pub fn finished(dir: &Path) -> bool {
    std::fs::read_to_string(dir.join("wall.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<EpisodeWall>(&t).ok())
        .is_some()
}

/// One finished episode of an evaluation, as `summary.json` lists it.
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeSummary {
    /// The method.
    pub method: &'static str,
    /// The seed.
    pub seed: u64,
    /// `result.json`'s `hand`.
    pub hand: String,
    /// Modes executed.
    pub modes: Vec<String>,
    /// Screwdriver: final yaw (rad).
    pub final_yaw: Option<f64>,
    /// Card: final distance to the goal (m).
    pub final_distance_m: Option<f64>,
    /// Card: displacement along y (m).
    pub final_dy_m: Option<f64>,
    /// The object stayed valid.
    pub valid: bool,
    /// The task's success rule.
    pub success: bool,
    /// Wall time (s).
    pub seconds: f64,
    /// The error that ended the episode, if one did.
    pub error: Option<String>,
}

/// Every episode of `methods` × `seeds` under `dir` that is not finished yet, run one after
/// the other on fresh hands (`dir/episodes/<method>/seed-<seed>/`: `result.json`,
/// `log.txt`, `wall.json` last); then the summary of all of them. An episode that fails is
/// recorded as a failed trial and the evaluation goes on.
pub fn run_eval(
    base: &EpisodeSpec,
    methods: &[Method],
    seeds: &[u64],
    dir: &Path,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<EpisodeSummary>, EpisodeError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| EpisodeError::Io { path, source }
    };
    for &method in methods {
        for &seed in seeds {
            let ep = episode_dir(dir, method, seed);
            if finished(&ep) {
                progress(&format!("{} seed {seed}: finished already", method.name()));
                continue;
            }
            std::fs::create_dir_all(&ep).map_err(io(&ep))?;
            progress(&format!("{} seed {seed}: running", method.name()));
            let spec = EpisodeSpec {
                method,
                seed,
                ..base.clone()
            };
            let t0 = Instant::now();
            let mut log = String::new();
            let outcome = run_episode(&spec, &mut |line| {
                log.push_str(&format!("[{:8.1} s] {line}\n", t0.elapsed().as_secs_f64()));
            });
            let error = match outcome {
                Ok(result) => {
                    result.write(&ep).map_err(io(&ep.join("result.json")))?;
                    None
                }
                Err(e) => Some(e.to_string()),
            };
            std::fs::write(ep.join("log.txt"), log).map_err(io(&ep.join("log.txt")))?;
            let wall = EpisodeWall {
                seconds: t0.elapsed().as_secs_f64(),
                error: error.clone(),
            };
            let text = serde_json::to_string_pretty(&wall).map_err(|e| EpisodeError::Io {
                path: ep.join("wall.json"),
                source: std::io::Error::other(e),
            })?;
            std::fs::write(ep.join("wall.json"), text).map_err(io(&ep.join("wall.json")))?;
            progress(&format!(
                "{} seed {seed}: {} in {:.0} s",
                method.name(),
                error.as_deref().unwrap_or("done"),
                wall.seconds
            ));
        }
    }
    summarize(methods, seeds, dir)
}

/// The finished episodes of `methods` × `seeds` under `dir` (unfinished ones are left out).
pub fn summarize(
    methods: &[Method],
    seeds: &[u64],
    dir: &Path,
) -> Result<Vec<EpisodeSummary>, EpisodeError> {
    let mut out = Vec::new();
    for &method in methods {
        for &seed in seeds {
            let ep = episode_dir(dir, method, seed);
            let read = |name: &str| -> Result<Option<serde_json::Value>, EpisodeError> {
                let path = ep.join(name);
                match std::fs::read_to_string(&path) {
                    Ok(t) => serde_json::from_str(&t)
                        .map(Some)
                        .map_err(|e| EpisodeError::Io {
                            path,
                            source: std::io::Error::other(e),
                        }),
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                    Err(source) => Err(EpisodeError::Io { path, source }),
                }
            };
            let Some(wall) = read("wall.json")? else {
                continue;
            };
            let seconds = wall["seconds"].as_f64().unwrap_or(f64::NAN);
            let error = wall["error"].as_str().map(str::to_string);
            let r = read("result.json")?.unwrap_or(serde_json::Value::Null);
            out.push(EpisodeSummary {
                method: method.name(),
                seed,
                // A result.json from before the field ran on our world.
                hand: r["hand"].as_str().unwrap_or("world").to_string(),
                modes: r["modes"]
                    .as_array()
                    .map(|m| {
                        m.iter()
                            .filter_map(|v| v.as_str().map(str::to_string))
                            .collect()
                    })
                    .unwrap_or_default(),
                final_yaw: r["final_yaw"].as_f64(),
                final_distance_m: r["final_distance_m"].as_f64(),
                final_dy_m: r["final_dy_m"].as_f64(),
                valid: r["valid"].as_bool().unwrap_or(false),
                success: r["success"].as_bool().unwrap_or(false),
                seconds,
                error,
            });
        }
    }
    Ok(out)
}
