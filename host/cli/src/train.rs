//! `dips train`: the denoiser and the discriminator of a task, trained on a dataset with burn
//! and exported under contract v1 (`docs/training.md`).

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use dips_kernel::mode::Task;
use dips_train::{RunOptions, TrainSettings};

/// `dips train` arguments.
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Task: screwdriver or card.
    #[arg(long, value_parser = crate::search_args::named::<Task>())]
    pub task: Task,
    /// Dataset directory (from `dips datagen`).
    #[arg(long)]
    pub data: PathBuf,
    /// Model directory: denoiser.onnx, discriminator.onnx, train_report.json, checkpoints/.
    /// A run with a checkpoint there resumes.
    #[arg(long)]
    pub out: PathBuf,
    /// Settings as JSON (the `settings` object of a train_report.json); flags override it.
    #[arg(long)]
    pub settings: Option<PathBuf>,
    /// Seed of the initialisation, data order, masks and noise.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::search_args::parse_seed)]
    pub seed: Option<u64>,
    /// Denoiser optimiser steps.
    #[arg(long)]
    pub steps: Option<usize>,
    /// Discriminator optimiser steps.
    #[arg(long)]
    pub disc_steps: Option<usize>,
    /// Channel widths of the U-Net stages, e.g. 32,64,128.
    #[arg(long, value_delimiter = ',')]
    pub widths: Option<Vec<usize>>,
    /// Denoiser batch size.
    #[arg(long)]
    pub batch: Option<usize>,
    /// Where the denoiser measures the object from: `world` or `segment-start` (the object's
    /// coordinates less the segment's start, `docs/training.md`).
    #[arg(long)]
    pub object_frame: Option<dips_kernel::engine::ObjectFrame>,
    /// Start over even when a checkpoint exists.
    #[arg(long)]
    pub fresh: bool,
    /// Train the Diffusion Policy baseline (`--method diffusion-policy`): the denoiser only,
    /// on windows of the demos' executed rows across modes, without contact-mode input.
    #[arg(long)]
    pub policy: bool,
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// Run `dips train`.
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    let task = args.task;
    let mut settings = match &args.settings {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read settings file {}", p.display()))?;
            serde_json::from_str::<TrainSettings>(&text)
                .with_context(|| format!("settings file {} is not valid", p.display()))?
        }
        None => TrainSettings::default(),
    };
    if let Some(s) = args.seed {
        settings.seed = s;
    }
    if let Some(s) = args.steps {
        settings.denoiser.steps = s;
    }
    if let Some(s) = args.disc_steps {
        settings.discriminator.steps = s;
    }
    if let Some(w) = args.widths {
        settings.net.widths = w;
    }
    if let Some(b) = args.batch {
        settings.denoiser.batch = b;
    }
    if let Some(f) = args.object_frame {
        settings.denoiser.object_frame = f;
    }
    let opts = RunOptions {
        progress: !args.quiet,
        stop_after: None,
        fresh: args.fresh,
    };
    let text = if args.policy || settings.denoiser.policy {
        serde_json::to_string_pretty(&dips_train::run_policy(
            task, &args.data, &args.out, &settings, &opts,
        )?)?
    } else {
        serde_json::to_string_pretty(&dips_train::run(
            task, &args.data, &args.out, &settings, &opts,
        )?)?
    };
    crate::output::line(&text)?;
    Ok(())
}
