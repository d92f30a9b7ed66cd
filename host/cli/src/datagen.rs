//! `dips datagen`: CSVTO demos driven by the task's prior, recorded as a dataset
//! (`docs/datagen.md`); `dips datagen merge` to make one dataset of a job array's shards, and
//! `dips datagen index` to rebuild a directory's manifest.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use dips_batch::ShardSpec;
use dips_datagen::{DatagenSettings, generate, index};
use dips_world::scenes::SceneKind;

use crate::search_args::named;

/// `dips datagen` arguments.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct DatagenArgs {
    /// `merge`: one dataset of a job array's shards; `index`: rebuild a dataset directory's
    /// manifest.json from its demo files.
    #[command(subcommand)]
    pub command: Option<DatagenCommand>,
    /// Task: screwdriver or card.
    #[arg(long, value_parser = named::<SceneKind>())]
    pub task: Option<SceneKind>,
    /// The card's goals the demos' pushes aim for.
    #[command(flatten)]
    pub card_goals: crate::search_args::CardGoalsArgs,
    /// Demos in the whole dataset (the paper's: screwdriver 240, card 480).
    #[arg(long)]
    pub demos: Option<usize>,
    /// Output directory (demos/*.safetensors and manifest.json); an existing one is resumed.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the first demo; demo i has seed FIRST_SEED + i.
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
    pub first_seed: u64,
    /// This machine's part of the seeds, I/N (a job array's task index and count); `auto`
    /// takes it from a Slurm array (`SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_COUNT`), `auto/N`
    /// the index from Slurm or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`) and N given.
    /// Shards may share `--out`; `dips datagen merge` checks that every demo is there.
    #[arg(long, default_value = "0/1", value_parser = crate::batch::parse_shard)]
    pub shard: ShardSpec,
    /// Where the demos' contact sequences come from: `pattern` (the paper's data: screwdriver
    /// turn, then both regrasps in random order, repeated; card uniform) or `markov` (chains
    /// drawn from the paper's Markov prior p(C), which hold every transition a plan can
    /// choose) or `turn-runs` (screwdriver runs of 2–5 turns separated by one or both
    /// regrasps, as the planner executes them). Use new seeds (`--first-seed`) when adding
    /// demos of another source to a dataset.
    #[arg(long, default_value = "pattern")]
    pub sequences: String,
    /// Demos run at once (default: the number of cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// CSVTO particles per demo (default: the task's, 16). Fewer make quick test datasets,
    /// not training data; the value is recorded in every demo and in datagen.json.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub particles: Option<u32>,
    /// Iterations of each mode's warm-up solve (default: the task's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub warmup_iters: Option<u32>,
    /// Iterations of every later solve (default: the task's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub online_iters: Option<u32>,
    /// Reruns of a warm-up that has not converged (default: the task's).
    #[arg(long)]
    pub warmup_retries: Option<u32>,
    /// No progress (a bar on a terminal, a line at most every 30 s in a log).
    #[arg(long)]
    pub quiet: bool,
}

/// `dips datagen` subcommands.
#[derive(Debug, Subcommand)]
pub enum DatagenCommand {
    /// Rebuild DIR/manifest.json from DIR/demos (after copying shards together).
    Index {
        /// Task: screwdriver or card.
        #[arg(long, value_parser = named::<SceneKind>())]
        task: SceneKind,
        /// The dataset directory.
        #[arg(long)]
        data: PathBuf,
    },
    /// Merge a job array's shards into one dataset: the demos of SOURCES (one directory per
    /// shard) copied into --out, or, with no SOURCES, the shards that shared --out; then every
    /// demo of their datagen.json must be there (a missing one is named with its shard) and
    /// manifest.json is rebuilt.
    Merge {
        /// Task: screwdriver or card.
        #[arg(long, value_parser = named::<SceneKind>())]
        task: SceneKind,
        /// The merged dataset's directory (may be one of SOURCES).
        #[arg(long)]
        out: PathBuf,
        /// The shards' dataset directories.
        sources: Vec<PathBuf>,
        /// Index what is there when demos are missing.
        #[arg(long)]
        allow_missing: bool,
    },
}

/// Run `dips datagen`.
pub fn run(args: DatagenArgs) -> anyhow::Result<()> {
    match &args.command {
        Some(DatagenCommand::Index { task, data }) => {
            let manifest = index(data, *task)?;
            crate::output::line(&serde_json::to_string_pretty(&manifest)?)?;
            return Ok(());
        }
        Some(DatagenCommand::Merge {
            task,
            out,
            sources,
            allow_missing,
        }) => {
            let report = dips_datagen::merge(*task, out, sources, *allow_missing)?;
            crate::output::line(&serde_json::to_string_pretty(&report)?)?;
            return Ok(());
        }
        None => {}
    }
    let task = args.task.context("--task is required")?;
    let out = args.out.clone().context("--out DIR is required")?;
    if out.is_file() {
        anyhow::bail!("--out {} is a file; give a directory", out.display());
    }
    let mut settings = DatagenSettings::paper(task);
    if let Some(d) = args.demos {
        settings.demos = d;
    }
    if let Some(j) = args.jobs {
        settings.jobs = j;
    }
    settings.first_seed = args.first_seed;
    settings.exec.card_goals = args.card_goals.given(task.task())?.unwrap_or_default();
    settings.sequences =
        dips_exec::SequenceSource::from_name(&args.sequences).with_context(|| {
            format!(
                "unknown --sequences {:?}; available: {}",
                args.sequences,
                dips_dataset::SEQUENCE_SOURCES.join(", ")
            )
        })?;
    let as_count = |n: u32| n as usize;
    if let Some(n) = args.particles {
        settings.exec.particles = as_count(n);
    }
    if let Some(n) = args.warmup_iters {
        settings.exec.warmup_iters = as_count(n);
    }
    if let Some(n) = args.online_iters {
        settings.exec.online_iters = as_count(n);
    }
    if let Some(n) = args.warmup_retries {
        settings.exec.warmup_retries = as_count(n);
    }
    settings.shard = crate::batch::resolve_shard(args.shard)?;
    settings.progress = crate::batch::progress_mode(args.quiet);
    let report = generate(&settings, &out)?;
    crate::output::line(&serde_json::to_string_pretty(&report)?)?;
    Ok(())
}
