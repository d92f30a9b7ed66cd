//! `dips-train`: offline training of the DIPS models in Rust on burn (`flex` CPU backend) and
//! their export to ONNX under model contract v1.
//!
//! - [`train_denoiser`]: the temporal U-Net ε-denoiser (spec §4.1–§4.3);
//! - [`train_discriminator`]: Ψ on real versus diffused trajectories (spec §4.5);
//! - [`export`]: contract-v1 ONNX written with `tract_onnx::pb`;
//! - [`run`]: all of it, writing `denoiser.onnx`, `discriminator.onnx` and
//!   `train_report.json` into a model directory.
//!
//! burn is used for the forward and backward passes only; parameters, Adam, the EMA, random
//! streams and checkpoints are ours (see [`params`]), so a run is deterministic for its seed and
//! a resumed run equals an uninterrupted one bit for bit. See `docs/training.md`.

pub mod data;
pub mod denoiser;
pub mod discriminator;
pub mod error;
pub mod export;
mod graph;
pub mod net;
pub mod params;
pub mod progress;
pub mod settings;
mod stage;
pub mod synthetic;

use std::path::{Path, PathBuf};

use dips_kernel::mode::Task;
use serde::Serialize;

pub use denoiser::{DenoiserReport, TrainedDenoiser, train_denoiser};
pub use discriminator::{DiscriminatorReport, TrainedDiscriminator, train_discriminator};
pub use error::{Result, TrainError};
pub use graph::OPSET;
pub use progress::RunOptions;
pub use settings::{DenoiserSettings, DiscriminatorSettings, NetSettings, TrainSettings};

use crate::error::io_err;

/// File names in a model directory.
pub const DENOISER_FILE: &str = "denoiser.onnx";
/// The discriminator's file name.
pub const DISCRIMINATOR_FILE: &str = "discriminator.onnx";
/// The report's file name.
pub const REPORT_FILE: &str = "train_report.json";
/// The fitted contact-mode prior's file name.
pub const PRIOR_FILE: &str = "prior.json";
/// The floor of the fitted prior (the paper's `p_min`).
pub const PRIOR_P_MIN: f32 = 0.1;

/// What [`run`] writes to `train_report.json`.
#[derive(Debug, Clone, Serialize)]
pub struct TrainReport {
    /// The task.
    pub task: String,
    /// The dataset directory.
    pub data_dir: PathBuf,
    /// Demos and trajectories read.
    pub demos: usize,
    /// Trajectories trained on.
    pub samples: usize,
    /// Trajectories left out because their mode followed the object's fall
    /// ([`TrainSettings::drop_modes_after_invalid`]).
    pub dropped_after_invalid: usize,
    /// Trajectories left out because they were recorded before online step
    /// [`TrainSettings::min_executed_rows`] of their mode.
    pub dropped_early_steps: usize,
    /// Seeds of the held-out demos.
    pub held_out_seeds: Vec<u64>,
    /// The settings.
    pub settings: TrainSettings,
    /// The denoiser's figures.
    pub denoiser: DenoiserReport,
    /// The discriminator's figures.
    pub discriminator: DiscriminatorReport,
    /// The normalisation written into both models.
    pub norm_mean: Vec<f32>,
    /// The normalisation's standard deviations.
    pub norm_std: Vec<f32>,
    /// The prior fitted from the demos' mode sequences (also in `prior.json`).
    pub prior: dips_dataset::PriorFile,
}

/// What [`run_policy`] writes to `train_report.json`.
#[derive(Debug, Clone, Serialize)]
pub struct PolicyReport {
    /// The task.
    pub task: String,
    /// What was trained.
    pub model: &'static str,
    /// The dataset directory.
    pub data_dir: PathBuf,
    /// Demos read.
    pub demos: usize,
    /// Training windows over all demos.
    pub windows: usize,
    /// Trajectories left out because their mode followed the object's fall
    /// ([`TrainSettings::drop_modes_after_invalid`]).
    pub dropped_after_invalid: usize,
    /// Trajectories left out because they were recorded before online step
    /// [`TrainSettings::min_executed_rows`] of their mode.
    pub dropped_early_steps: usize,
    /// Seeds of the held-out demos.
    pub held_out_seeds: Vec<u64>,
    /// The settings.
    pub settings: TrainSettings,
    /// The denoiser's figures.
    pub denoiser: DenoiserReport,
    /// The normalisation written into the model.
    pub norm_mean: Vec<f32>,
    /// The normalisation's standard deviations.
    pub norm_std: Vec<f32>,
}

/// Train the Diffusion Policy baseline (spec §5) on the dataset in `data_dir`: the denoiser
/// on windows of the demos' executed rows concatenated across modes, with no contact-mode
/// input (`settings.denoiser.policy` is set). Writes `denoiser.onnx` (contract v1; its
/// context input is always zero) and `train_report.json` into `out_dir`; resumable like
/// [`run`].
pub fn run_policy(
    task: Task,
    data_dir: &Path,
    out_dir: &Path,
    settings: &TrainSettings,
    opts: &RunOptions,
) -> Result<PolicyReport> {
    let mut settings = settings.clone();
    settings.denoiser.policy = true;
    settings.validate()?;
    let (ds, dropped) = read_dataset(task, data_dir, &settings)?;
    std::fs::create_dir_all(out_dir).map_err(io_err(out_dir))?;
    let den = train_denoiser(&ds, &settings, out_dir, opts)?;
    export_denoiser(&den, &out_dir.join(DENOISER_FILE))?;
    let split = ds.split(settings.held_out_fraction);
    let report = PolicyReport {
        task: task.name().to_string(),
        model: "diffusion-policy",
        data_dir: data_dir.to_path_buf(),
        demos: ds.demos.len(),
        windows: ds.demos.iter().map(|d| data::policy_windows(d).1).sum(),
        dropped_after_invalid: dropped.after_invalid,
        dropped_early_steps: dropped.early_steps,
        held_out_seeds: split.held_out.iter().map(|&i| ds.demos[i].seed).collect(),
        settings: settings.clone(),
        denoiser: den.report.clone(),
        norm_mean: den.norm.mean.clone(),
        norm_std: den.norm.std.clone(),
    };
    let path = out_dir.join(REPORT_FILE);
    let json = serde_json::to_vec_pretty(&report).map_err(|e| TrainError::Io {
        path: path.clone(),
        source: std::io::Error::other(e),
    })?;
    dips_fs::write_atomic(&path, &json).map_err(io_err(&path))?;
    Ok(report)
}

/// Write the denoiser to `path` (validated against contract v1 first).
pub fn export_denoiser(d: &TrainedDenoiser, path: &Path) -> Result<dips_onnx::Contract> {
    export::write_model(path, &d.onnx()?)
}

/// Write the discriminator to `path` (validated against contract v1 first).
pub fn export_discriminator(d: &TrainedDiscriminator, path: &Path) -> Result<dips_onnx::Contract> {
    export::write_model(path, &d.onnx()?)
}

/// Trajectories [`read_dataset`] left out, by reason.
#[derive(Debug, Clone, Copy, Default)]
struct Dropped {
    after_invalid: usize,
    early_steps: usize,
}

/// Read the dataset in `data_dir` as `settings` ask (the modes after an object's fall left
/// out when [`TrainSettings::drop_modes_after_invalid`], the early steps' trajectories when
/// [`TrainSettings::min_executed_rows`]); also the trajectories left out.
fn read_dataset(
    task: Task,
    data_dir: &Path,
    settings: &TrainSettings,
) -> Result<(dips_dataset::Dataset, Dropped)> {
    let mut ds = dips_dataset::read_dir(data_dir, task)?;
    let mut dropped = Dropped::default();
    if settings.drop_modes_after_invalid {
        dropped.after_invalid = ds.drop_modes_after_invalid();
    }
    if settings.min_executed_rows > 0 {
        let last = ds.demos.iter().flat_map(|d| d.step.iter().copied()).max();
        dropped.early_steps = ds.keep_steps_from(settings.min_executed_rows);
        if ds.samples() == 0 {
            return Err(TrainError::Settings {
                field: "min_executed_rows".into(),
                reason: format!(
                    "{} keeps no trajectory: the demos in {} record online steps 0 to {} \
                     (allowed: 0 to the last of them)",
                    settings.min_executed_rows,
                    data_dir.display(),
                    last.map_or("none".to_string(), |k| k.to_string()),
                ),
            });
        }
    }
    Ok((ds, dropped))
}

/// Read the dataset in `data_dir`, fit the contact-mode prior, train both models, and write
/// `prior.json`, `denoiser.onnx`, `discriminator.onnx` and `train_report.json` into `out_dir` (checkpoints under
/// `out_dir/checkpoints/`; a killed run resumes from them).
pub fn run(
    task: Task,
    data_dir: &Path,
    out_dir: &Path,
    settings: &TrainSettings,
    opts: &RunOptions,
) -> Result<TrainReport> {
    settings.validate()?;
    discriminator::augment_columns(task, settings)?;
    let (ds, dropped) = read_dataset(task, data_dir, settings)?;
    std::fs::create_dir_all(out_dir).map_err(io_err(out_dir))?;
    let prior = match &settings.prior_sources {
        None => dips_dataset::PriorFile::fit(&ds, PRIOR_P_MIN)?,
        Some(sources) => dips_dataset::PriorFile::fit_where(&ds, PRIOR_P_MIN, |d| {
            sources.iter().any(|s| s == d.sequence_source())
        })?,
    };
    prior.save(&out_dir.join(PRIOR_FILE))?;
    // The planner plans and executes with the goals the demos were made with.
    let card_goals = (task == Task::Card).then(|| ds.card_goals()).transpose()?;
    let mut den = train_denoiser(&ds, settings, out_dir, opts)?;
    den.card_goals = card_goals;
    export_denoiser(&den, &out_dir.join(DENOISER_FILE))?;
    let disc = train_discriminator(&ds, settings, &den, out_dir, opts)?;
    export_discriminator(&disc, &out_dir.join(DISCRIMINATOR_FILE))?;
    let split = ds.split(settings.held_out_fraction);
    let report = TrainReport {
        task: task.name().to_string(),
        data_dir: data_dir.to_path_buf(),
        demos: ds.demos.len(),
        samples: ds.samples(),
        dropped_after_invalid: dropped.after_invalid,
        dropped_early_steps: dropped.early_steps,
        held_out_seeds: split.held_out.iter().map(|&i| ds.demos[i].seed).collect(),
        settings: settings.clone(),
        denoiser: den.report.clone(),
        discriminator: disc.report.clone(),
        norm_mean: den.norm.mean.clone(),
        norm_std: den.norm.std.clone(),
        prior,
    };
    let path = out_dir.join(REPORT_FILE);
    let json = serde_json::to_vec_pretty(&report).map_err(|e| TrainError::Io {
        path: path.clone(),
        source: std::io::Error::other(e),
    })?;
    dips_fs::write_atomic(&path, &json).map_err(io_err(&path))?;
    Ok(report)
}
