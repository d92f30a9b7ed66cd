//! `dips datagen`: CSVTO demos driven by the task's prior, recorded as a dataset
//! (`docs/datagen.md`), and `dips datagen index` to rebuild a directory's manifest (merging
//! shards).

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use dips_datagen::{DatagenSettings, Shard, generate, index};
use dips_host::scenes::SceneKind;

/// `dips datagen` arguments.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct DatagenArgs {
    /// `index`: rebuild a dataset directory's manifest.json from its demo files.
    #[command(subcommand)]
    pub command: Option<DatagenCommand>,
    /// Task: screwdriver or card.
    #[arg(long)]
    pub task: Option<String>,
    /// Demos in the whole dataset (the paper's: screwdriver 240, card 480).
    #[arg(long)]
    pub demos: Option<usize>,
    /// Output directory (demos/*.safetensors and manifest.json); an existing one is resumed.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the first demo; demo i has seed FIRST_SEED + i.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub first_seed: u64,
    /// This machine's part of the seeds, I/N (a job array's task index and count).
    #[arg(long, default_value = "0/1")]
    pub shard: Shard,
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
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `dips datagen` subcommands.
#[derive(Debug, Subcommand)]
pub enum DatagenCommand {
    /// Rebuild DIR/manifest.json from DIR/demos (after copying shards together).
    Index {
        /// Task: screwdriver or card.
        #[arg(long)]
        task: String,
        /// The dataset directory.
        #[arg(long)]
        data: PathBuf,
    },
}

fn parse_task(name: &str) -> anyhow::Result<SceneKind> {
    SceneKind::from_name(name)
        .with_context(|| format!("unknown task {name:?}; available: screwdriver, card"))
}

/// Run `dips datagen`.
pub fn run(args: DatagenArgs) -> anyhow::Result<()> {
    if let Some(DatagenCommand::Index { task, data }) = &args.command {
        let manifest = index(data, parse_task(task)?)?;
        crate::output::line(&serde_json::to_string_pretty(&manifest)?)?;
        return Ok(());
    }
    let task = parse_task(args.task.as_deref().context("--task is required")?)?;
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
    settings.sequences = dips_host::execute::SequenceSource::from_name(&args.sequences)
        .with_context(|| {
            format!(
                "unknown --sequences {:?}; available: {}",
                args.sequences,
                dips_dataset::SEQUENCE_SOURCES.join(", ")
            )
        })?;
    settings.shard = args.shard;
    settings.progress = !args.quiet;
    let report = generate(&settings, &out)?;
    crate::output::line(&serde_json::to_string_pretty(&report)?)?;
    Ok(())
}
