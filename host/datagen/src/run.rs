//! Many demos on all cores: resumable (finished demos are files and are skipped), atomic (a
//! kill loses at most the demos in flight), with a progress bar, for one shard of the seeds.

use std::path::{Path, PathBuf};
use std::time::Instant;

use dips_batch::{ProgressMode, RunShardError, Shard, ShardRun, run_shard};
use dips_csvto::CsvtoError;
use dips_dataset::{DatasetError, read_demo, write_demo};
use dips_exec::{ExecError, ExecSettings, SequenceSource};
use dips_world::scenes::SceneKind;

use crate::manifest::{Manifest, index};
use crate::record::record_demo;
use crate::settings_file::claim_dir;

/// The git revision this generator was built at (`-dirty` when built from a modified tree).
pub const GIT_REVISION: &str = env!("DIPS_GIT_REV");

/// What to generate.
#[derive(Debug, Clone)]
pub struct DatagenSettings {
    /// The task.
    pub task: SceneKind,
    /// Demos in the whole dataset (over all shards).
    pub demos: usize,
    /// Seed of the first demo; demo `i` has seed `first_seed + i`.
    pub first_seed: u64,
    /// The part of the seeds this run generates.
    pub shard: Shard,
    /// Demos run at once (each also spreads its particles over the cores).
    pub jobs: usize,
    /// Where the demos' contact sequences come from (the paper's pattern by default).
    pub sequences: SequenceSource,
    /// CSVTO and execution settings (the task's defaults).
    pub exec: ExecSettings,
    /// Progress on stderr: a bar on a terminal, log lines otherwise, or none.
    pub progress: ProgressMode,
    /// Stop after this many new demos (tests simulate a kill with it).
    pub stop_after: Option<usize>,
}

impl DatagenSettings {
    /// The paper's dataset for a task: screwdriver 240 demos × 7 modes, card 480 × 5, with
    /// the task's execution settings, both cores.
    pub fn paper(task: SceneKind) -> DatagenSettings {
        DatagenSettings {
            task,
            demos: match task {
                SceneKind::Screwdriver => 240,
                SceneKind::Card => 480,
            },
            first_seed: 0,
            shard: Shard::ALL,
            jobs: std::thread::available_parallelism().map_or(2, |n| n.get()),
            sequences: SequenceSource::Pattern,
            exec: ExecSettings::for_task(task),
            progress: ProgressMode::Auto,
            stop_after: None,
        }
    }

    /// Check the settings.
    pub fn validate(&self) -> Result<(), DatagenError> {
        if self.demos == 0 {
            return Err(DatagenError::NoDemos);
        }
        if self.jobs == 0 {
            return Err(DatagenError::NoJobs);
        }
        if self.first_seed.checked_add(self.demos as u64).is_none() {
            return Err(DatagenError::SeedOverflow {
                first_seed: self.first_seed,
                demos: self.demos,
            });
        }
        self.exec.validate().map_err(DatagenError::Exec)
    }
}

/// What to do about a directory of other settings ([`DatagenError::OtherSettings`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Remedy {
    /// Make demos of other seeds, or into another directory.
    OtherSeedsOrDirectory,
    /// Make the demos into another directory.
    OtherDirectory,
    /// Merge datasets of one task only.
    OneTask,
}

impl std::fmt::Display for Remedy {
    /// The remedy as a clause.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::OtherSeedsOrDirectory => "give other seeds or another output directory",
            Self::OtherDirectory => "give another output directory",
            Self::OneTask => "merge datasets of one task",
        })
    }
}

/// Why data generation stopped. Each message names the setting or file, its value and what
/// is allowed.
#[derive(Debug, thiserror::Error)]
pub enum DatagenError {
    /// No demos asked for.
    #[error("invalid datagen settings: demos: 0, must be at least 1")]
    NoDemos,
    /// No demos at once.
    #[error("invalid datagen settings: jobs: 0, must be at least 1")]
    NoJobs,
    /// The seeds run past `u64::MAX`.
    #[error(
        "invalid datagen settings: first seed {first_seed} + {demos} demos overflows the seed \
         range"
    )]
    SeedOverflow {
        /// The first seed.
        first_seed: u64,
        /// The demos.
        demos: usize,
    },
    /// CSVTO's or the execution's settings are out of range.
    #[error("invalid datagen settings: {0}")]
    Exec(CsvtoError),
    /// The worker threads cannot be started.
    #[error("thread pool: {0}")]
    ThreadPool(rayon::ThreadPoolBuildError),
    /// A demo already there was made from other contact sequences.
    #[error(
        "{} was made with sequences {made}, this run asks for {asked}; {}",
        path.display(),
        Remedy::OtherSeedsOrDirectory
    )]
    OtherSequences {
        /// The demo file.
        path: PathBuf,
        /// The sequences it was made with.
        made: String,
        /// This run's.
        asked: &'static str,
    },
    /// A merge source is not a directory.
    #[error("{} is not a directory (give the shards' dataset directories)", dir.display())]
    NotADirectory {
        /// The source.
        dir: PathBuf,
    },
    /// A merge source has no `datagen.json`.
    #[error(
        "{} has no datagen.json: not a dips datagen output (or made before it was recorded; \
         copy its demos/ by hand and index the dataset)",
        dir.display()
    )]
    NoSettingsFile {
        /// The source.
        dir: PathBuf,
    },
    /// `datagen.json` is not one.
    #[error("{} is not a datagen settings file ({error}); delete it to start over", path.display())]
    SettingsFile {
        /// The file.
        path: PathBuf,
        /// What serde found.
        error: serde_json::Error,
    },
    /// A file or directory could not be written or read.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A demo file could not be written or read back.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// A shard record or a settings file could not be written or read.
    #[error(transparent)]
    Batch(#[from] dips_batch::BatchError),
    /// The directory holds demos of other settings.
    #[error("{path} was made with {field} {theirs}, this run asks for {ours}; {remedy}")]
    OtherSettings {
        /// The settings file.
        path: PathBuf,
        /// The first setting that differs, as its field in `datagen.json` (`task`,
        /// `sequences`, `seeds`, `exec.horizon`, ...).
        field: String,
        /// Its value in the file.
        theirs: String,
        /// This run's value.
        ours: String,
        /// What to do.
        remedy: Remedy,
    },
    /// A merge found demos missing.
    #[error("{dir}: {missing} of {expected} demos are missing ({detail}); rerun those shards")]
    Incomplete {
        /// The merged directory.
        dir: PathBuf,
        /// Demos missing.
        missing: usize,
        /// Demos expected.
        expected: usize,
        /// Which shards and seeds.
        detail: String,
    },
    /// An episode failed (the world or the problem); the demos before it are kept.
    #[error("demo seed {seed}: {source}")]
    Episode {
        /// The demo's seed.
        seed: u64,
        /// What failed.
        source: ExecError,
    },
}

/// What a run did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DatagenReport {
    /// Demos generated by this run.
    pub generated: usize,
    /// Demos of this shard that were already there (resumed).
    pub skipped: usize,
    /// Wall time of this run (s).
    pub seconds: f64,
    /// Wall time per generated demo (s), with `jobs` demos in flight.
    pub seconds_per_demo: f64,
    /// The shard this run generated.
    pub shard: String,
    /// The dataset directory's manifest after the run (all shards present).
    pub manifest: Manifest,
}

/// The file of demo `seed`.
pub fn demo_path(dir: &Path, task: SceneKind, seed: u64) -> PathBuf {
    dir.join("demos")
        .join(format!("{}-{seed:06}.safetensors", task.name()))
}

/// Generate this shard's demos into `dir` (`dir/demos/*.safetensors`), skipping demos whose
/// files are already there and readable, then rebuild `dir/manifest.json` from every demo in
/// the directory.
pub fn generate(settings: &DatagenSettings, dir: &Path) -> Result<DatagenReport, DatagenError> {
    settings.validate()?;
    claim_dir(dir, settings)?;
    let demos_dir = dir.join("demos");
    std::fs::create_dir_all(&demos_dir).map_err(|source| DatagenError::Io {
        path: demos_dir.clone(),
        source,
    })?;
    let kernel_task = settings.task.task();
    let seeds = settings.shard.seeds(settings.first_seed, settings.demos);
    let mut pending = Vec::new();
    for &seed in &seeds {
        let path = demo_path(dir, settings.task, seed);
        // A file that does not read back (cut off by a full disk, say) is made again; one
        // made from other sequences is never taken for this run's.
        match path.exists().then(|| read_demo(&path, kernel_task)) {
            Some(Ok(demo)) => {
                let made = demo.sequence_source();
                if made != settings.sequences.name() {
                    return Err(DatagenError::OtherSequences {
                        path,
                        made: made.to_string(),
                        asked: settings.sequences.name(),
                    });
                }
            }
            _ => pending.push(seed),
        }
    }
    let skipped = seeds.len() - pending.len();
    let run = ShardRun {
        label: format!("datagen {} shard {}", settings.task.name(), settings.shard),
        units: ("demo", "demos"),
        progress: settings.progress,
        jobs: settings.jobs,
        threads_per_job: 1,
        stop_after: settings.stop_after,
    };
    let outcome = run_shard(
        &run,
        pending,
        skipped,
        |seed| format!("seed {seed}"),
        |&seed| {
            let t0 = Instant::now();
            let (mut record, _) = record_demo(
                settings.task,
                seed,
                settings.sequences,
                &settings.exec,
                &mut |_| {},
            )
            .map_err(|source| DatagenError::Episode { seed, source })?;
            record
                .metadata
                .insert("git_revision".into(), GIT_REVISION.into());
            record.metadata.insert(
                "seconds".into(),
                format!("{:.3}", t0.elapsed().as_secs_f64()),
            );
            write_demo(&demo_path(dir, settings.task, seed), &record)?;
            Ok(None)
        },
    );
    let outcome = match outcome {
        Ok(outcome) => outcome,
        Err(RunShardError::ThreadPool(e)) => return Err(DatagenError::ThreadPool(e)),
        Err(RunShardError::Item(e)) => {
            // Keep what finished: the manifest lists it, a re-run resumes after it.
            let _ = index(dir, settings.task);
            return Err(e);
        }
    };
    let generated = outcome.ran;
    let seconds = outcome.seconds;
    let manifest = index(dir, settings.task)?;
    let report = DatagenReport {
        generated,
        skipped,
        seconds,
        seconds_per_demo: if generated > 0 {
            seconds / generated as f64
        } else {
            0.0
        },
        shard: settings.shard.to_string(),
        manifest,
    };
    let counts = serde_json::json!({
        "generated": generated,
        "skipped": skipped,
        "seconds_per_demo": report.seconds_per_demo,
    });
    outcome.record(dir, settings.shard, &counts)?;
    Ok(report)
}
