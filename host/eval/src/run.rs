//! The episodes of one shard on `jobs` threads: resumable, atomic, with a progress bar.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use dips_batch::{BatchError, RunShardError, Shard, ShardRun, run_shard};
use dips_exec::EpisodeResult;
use dips_fs::write_atomic;
use dips_link::{LinkError, RemoteError, RemotePlanner};
use dips_planning::online::{Method, OnlineError, run_online};
use dips_planning::{Models, ModelsError, PlanService};
use dips_world::hand::{HandError, HandKind, HandOptions, Hands, TrackerNoise, WorldHands};
use serde::{Deserialize, Serialize};

use crate::settings::{EvalFileError, EvalSettings, SettingsError, claim_dir, episode_dir};

/// Why an evaluation run stopped (finished episodes stay). An episode that fails is not
/// one of these: it is recorded as a failed trial ([`EpisodeWall::error`]).
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The settings are not an evaluation.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// The hand cannot be opened.
    #[error("hand {hand}")]
    Hand {
        /// The hand asked for.
        hand: HandKind,
        /// Why it cannot be opened.
        #[source]
        source: HandError,
    },
    /// The output directory cannot be claimed.
    #[error(transparent)]
    Dir(#[from] EvalFileError),
    /// The models cannot be loaded.
    #[error("loading the models in {}", dir.display())]
    Models {
        /// The models' directory.
        dir: PathBuf,
        /// Why.
        #[source]
        source: Box<ModelsError>,
    },
    /// The sampler cannot run on the models.
    #[error(transparent)]
    Sampler(Box<ModelsError>),
    /// The worker threads cannot be started.
    #[error("thread pool: {0}")]
    ThreadPool(rayon::ThreadPoolBuildError),
    /// A directory cannot be made.
    #[error("creating {}", dir.display())]
    Create {
        /// The directory.
        dir: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A file cannot be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A result cannot be written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The shard's record cannot be written.
    #[error("recording shard {shard} in {}", dir.display())]
    Record {
        /// The shard.
        shard: Shard,
        /// The evaluation directory.
        dir: PathBuf,
        /// Why.
        #[source]
        source: BatchError,
    },
}

/// Why one episode failed: recorded in its `wall.json`, counted as a failed trial.
#[derive(Debug, thiserror::Error)]
enum EpisodeError {
    #[error(transparent)]
    Models(#[from] ModelsError),
    #[error(transparent)]
    Hand(#[from] HandError),
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(transparent)]
    Remote(#[from] RemoteError),
    #[error(transparent)]
    Online(#[from] OnlineError),
    #[error(transparent)]
    Profile(#[from] dips_exec::ProfileError),
}

/// `e` and its causes on one line, each after a `: `.
fn with_causes(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text.push_str(": ");
        text.push_str(&c.to_string());
        cause = c.source();
    }
    text
}

fn write_error(path: &Path) -> impl FnOnce(std::io::Error) -> RunError + '_ {
    move |source| RunError::Write {
        path: path.to_path_buf(),
        source,
    }
}

/// `wall.json` of an episode: its wall time, and the error that ended it, if one did.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EpisodeWall {
    /// Wall time of the episode (s), with `jobs` episodes in flight.
    pub seconds: f64,
    /// Episodes that ran at once.
    pub jobs: usize,
    /// Threads of each model call.
    #[serde(default = "one")]
    pub model_threads: usize,
    /// Why the episode stopped without a result (the world or the optimiser failed); such an
    /// episode counts as a failed trial and is not run again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// `wall.json` files written before `model_threads` was recorded ran on one thread.
fn one() -> usize {
    1
}

/// The file of an episode's wall time.
pub const WALL_FILE: &str = "wall.json";

/// Whether the episode in `dir` has finished (a result, or a recorded error).
pub fn finished(dir: &Path) -> bool {
    let wall = std::fs::read_to_string(dir.join(WALL_FILE))
        .ok()
        .and_then(|t| serde_json::from_str::<EpisodeWall>(&t).ok());
    match wall {
        Some(w) if w.error.is_some() => true,
        Some(_) => std::fs::read_to_string(dir.join("result.json"))
            .ok()
            .is_some_and(|t| serde_json::from_str::<serde_json::Value>(&t).is_ok()),
        None => false,
    }
}

/// Write `result` to `dir/result.json` (atomically), with the tracker noise it ran under as
/// `tracker_noise` when there was some (`result.json`'s `hand` names the executing hand).
pub fn write_result(
    result: &EpisodeResult,
    dir: &Path,
    noise: Option<TrackerNoise>,
) -> Result<(), RunError> {
    let file = dir.join("result.json");
    let Some(noise) = noise else {
        return result.write(dir).map_err(write_error(&file));
    };
    let mut value = serde_json::to_value(result)?;
    if let Some(map) = value.as_object_mut() {
        map.insert("tracker_noise".into(), serde_json::to_value(noise)?);
    }
    std::fs::create_dir_all(dir).map_err(|source| RunError::Create {
        dir: dir.to_path_buf(),
        source,
    })?;
    write_atomic(&file, serde_json::to_string_pretty(&value)?.as_bytes())
        .map_err(write_error(&file))
}

/// What a run did.
#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    /// Episodes run by this call.
    pub ran: usize,
    /// Episodes of this shard that were already there (resumed).
    pub skipped: usize,
    /// Episodes that ended with an error (recorded, counted as failures).
    pub errors: usize,
    /// Wall time of this call (s).
    pub seconds: f64,
}

/// Run one episode into `dir`: `result.json` (or the error in `wall.json`), `log.txt`,
/// `wall.json` last, so that an episode counts as finished only when all is written.
fn run_episode(
    hands: &dyn Hands,
    settings: &EvalSettings,
    method: Method,
    seed: u64,
    dir: &Path,
) -> Result<Option<String>, RunError> {
    std::fs::create_dir_all(dir).map_err(|source| RunError::Create {
        dir: dir.to_path_buf(),
        source,
    })?;
    let t0 = Instant::now();
    let mut log = Vec::new();
    let outcome = (|| -> Result<EpisodeResult, EpisodeError> {
        let models = if method.needs_models() {
            let mut m = Models::load(settings.engine, &settings.models, settings.task.task())?;
            m.set_threads(settings.model_threads);
            Some(m)
        } else {
            None
        };
        let exec = settings.exec_settings()?;
        // Opened on this worker thread: a hand need not be `Send`.
        let mut hand = hands.open(
            &settings.hand,
            settings.task,
            &HandOptions {
                noise: settings.tracker_noise,
                seed,
            },
        )?;
        let mut progress = |line: &str| {
            let _ = writeln!(log, "[{:8.1} s] {line}", t0.elapsed().as_secs_f64());
        };
        // A kernel over the wire for the methods that plan (one link per episode).
        let link = if method.searches() {
            settings.kernel.open()?
        } else {
            None
        };
        let mut remote = match link {
            Some(link) => Some(RemotePlanner::new(
                link,
                &settings.models,
                settings.task.task(),
            )?),
            None => None,
        };
        Ok(run_online(
            &mut *hand,
            method,
            seed,
            models,
            remote.as_mut().map(|r| r as &mut dyn PlanService),
            &exec,
            &settings.online,
            &mut progress,
        )?)
    })();
    let error = match outcome {
        Ok(result) => {
            write_result(&result, dir, settings.tracker_noise)?;
            None
        }
        Err(e) => Some(with_causes(&e)),
    };
    write_atomic(&dir.join("log.txt"), &log).map_err(write_error(&dir.join("log.txt")))?;
    let wall = EpisodeWall {
        seconds: t0.elapsed().as_secs_f64(),
        jobs: settings.jobs,
        model_threads: settings.model_threads,
        error: error.clone(),
    };
    write_atomic(
        &dir.join(WALL_FILE),
        serde_json::to_string_pretty(&wall)?.as_bytes(),
    )
    .map_err(write_error(&dir.join(WALL_FILE)))?;
    Ok(error)
}

/// Run this shard's unfinished episodes into `dir`, `settings.jobs` at a time.
///
/// The models are loaded once up front, so a missing or broken model fails here and not in
/// every episode. An I/O failure stops the run (finished episodes stay); an episode whose
/// world or optimiser fails is recorded as a failed trial and the run goes on. The episodes
/// run on our world ([`run_eval_on`] takes the hands).
pub fn run_eval(settings: &EvalSettings, dir: &Path) -> Result<EvalReport, RunError> {
    run_eval_on(settings, dir, &WorldHands)
}

/// [`run_eval`] with the episodes executed on `settings.hand`, opened by `hands` (one fresh
/// hand per episode, on its worker thread).
pub fn run_eval_on(
    settings: &EvalSettings,
    dir: &Path,
    hands: &dyn Hands,
) -> Result<EvalReport, RunError> {
    settings.validate()?;
    // A hand that cannot be opened (not in this binary, a missing library, noise on our
    // world) fails here, before the directory is claimed.
    hands
        .open(
            &settings.hand,
            settings.task,
            &HandOptions {
                noise: settings.tracker_noise,
                seed: settings.first_seed,
            },
        )
        .map_err(|source| RunError::Hand {
            hand: settings.hand.clone(),
            source,
        })?;
    claim_dir(dir, settings)?;
    if settings.methods.iter().any(|m| m.needs_models()) {
        Models::load(settings.engine, &settings.models, settings.task.task())
            .map_err(|source| RunError::Models {
                dir: settings.models.clone(),
                source: Box::new(source),
            })?
            .check_sampler(&settings.online.sampler, settings.task.task())
            .map_err(|e| RunError::Sampler(Box::new(e)))?;
    }
    let episodes = settings.episodes();
    let pending: Vec<(Method, u64)> = episodes
        .iter()
        .copied()
        .filter(|(m, s)| !finished(&episode_dir(dir, *m, *s)))
        .collect();
    let skipped = episodes.len() - pending.len();
    // `jobs` workers take episodes from one queue; the pool has `jobs × model_threads`
    // threads, so an episode's CSVTO (rayon) uses the cores its model calls use.
    let run = ShardRun {
        label: format!("eval {} shard {}", settings.task.name(), settings.shard),
        units: ("episode", "episodes"),
        progress: settings.progress,
        jobs: settings.jobs,
        threads_per_job: settings.model_threads,
        stop_after: settings.stop_after,
    };
    let name = |&(method, seed): &(Method, u64)| format!("{} seed {seed}", method.name());
    let outcome = run_shard(&run, pending, skipped, name, |&(method, seed)| {
        let ep_dir = episode_dir(dir, method, seed);
        Ok(run_episode(hands, settings, method, seed, &ep_dir)?
            .map(|e| format!("{} failed: {e}", name(&(method, seed)))))
    })
    .map_err(|e| match e {
        RunShardError::ThreadPool(e) => RunError::ThreadPool(e),
        RunShardError::Item(e) => e,
    })?;
    let report = EvalReport {
        ran: outcome.ran,
        skipped,
        errors: outcome.noted,
        seconds: outcome.seconds,
    };
    outcome
        .record(dir, settings.shard, &report)
        .map_err(|source| RunError::Record {
            shard: settings.shard,
            dir: dir.to_path_buf(),
            source,
        })?;
    Ok(report)
}
