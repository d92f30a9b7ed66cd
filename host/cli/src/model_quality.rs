//! `dips model quality` and `dips model card`: the quality figures of trained models on their
//! held-out demos (`dips_planning::quality`), and the model card that gathers them with the
//! training report.

use dips_onnx::EngineKind;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use dips_fs::write_atomic;
use dips_planning::models_dir;
use dips_planning::quality::{QualityOptions, QualityReport, markdown, measure};
use dips_train::REPORT_FILE;
use dips_world::scenes::SceneKind;
use serde_json::Value;

/// The quality report's file name in a models directory.
pub const QUALITY_FILE: &str = "quality.json";
/// The model card's file name.
pub const CARD_FILE: &str = "MODEL_CARD.md";

/// Arguments of `dips model quality`.
#[derive(Debug, Args)]
pub struct QualityArgs {
    /// Task: screwdriver or card.
    #[arg(long, value_parser = crate::search_args::named::<SceneKind>())]
    pub task: SceneKind,
    /// Models directory (with `train_report.json`; default: the shipped models).
    #[arg(long)]
    pub models: Option<PathBuf>,
    /// The dataset the models were trained on (its held-out demos give the start states).
    #[arg(long)]
    pub data: PathBuf,
    /// Held-out trajectories per set.
    #[arg(long, default_value_t = 256)]
    pub trajectories: usize,
    /// DDIM step counts measured beside DDPM, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "8,32")]
    pub ddim: Vec<u16>,
    /// Open-loop executions of diffused object-moving modes.
    #[arg(long, default_value_t = 10)]
    pub trials: usize,
    /// Sampler seed.
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
    pub seed: u64,
    /// Engine that runs the denoiser.
    #[arg(long, value_parser = crate::search_args::named::<EngineKind>(), default_value = "kernel")]
    pub engine: EngineKind,
}

/// Arguments of `dips model card`.
#[derive(Debug, Args)]
pub struct CardArgs {
    /// Task: screwdriver or card.
    #[arg(long, value_parser = crate::search_args::named::<SceneKind>())]
    pub task: SceneKind,
    /// Models directory (with `train_report.json` and `quality.json`; default: the shipped
    /// models).
    #[arg(long)]
    pub models: Option<PathBuf>,
    /// The command that made the models, quoted into the card.
    #[arg(long)]
    pub command: Option<String>,
}

fn read_json(path: &Path) -> anyhow::Result<Value> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{} is not valid JSON", path.display()))
}

/// Run `dips model quality`.
pub fn run_quality(args: QualityArgs) -> anyhow::Result<()> {
    let scene = args.task;
    let dir = models_dir(args.models.as_deref(), scene.task())?;
    if args.trajectories == 0 {
        bail!("--trajectories must be at least 1");
    }
    let report_path = dir.join(REPORT_FILE);
    let report = read_json(&report_path)?;
    let seeds: Vec<u64> = report["held_out_seeds"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_u64).collect())
        .unwrap_or_default();
    let opts = QualityOptions {
        trajectories: args.trajectories,
        ddim_steps: args.ddim,
        open_loop_trials: args.trials,
        seed: args.seed,
        engine: args.engine,
        drop_modes_after_invalid: report["settings"]["drop_modes_after_invalid"]
            .as_bool()
            .unwrap_or(false),
    };
    let q = measure(scene, &dir, &args.data, &seeds, &opts, |what| {
        crate::note!("dips model quality: {what}");
    })?;
    let path = dir.join(QUALITY_FILE);
    write_atomic(&path, serde_json::to_string_pretty(&q)?.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))?;
    crate::output::line(&markdown(&q))?;
    Ok(())
}

/// Run `dips model card`.
pub fn run_card(args: CardArgs) -> anyhow::Result<()> {
    let scene = args.task;
    let dir = models_dir(args.models.as_deref(), scene.task())?;
    let report = read_json(&dir.join(REPORT_FILE))?;
    let quality: QualityReport = {
        let p = dir.join(QUALITY_FILE);
        let v = read_json(&p)?;
        // Written by this binary: the JSON fields are the report's.
        serde_json::from_value(v)
            .with_context(|| format!("{} is not a quality report", p.display()))?
    };
    let card = card_text(scene, &dir, &report, &quality, args.command.as_deref())?;
    let path = dir.join(CARD_FILE);
    write_atomic(&path, card.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))?;
    crate::output::line(&path.display().to_string())?;
    Ok(())
}

fn card_text(
    scene: SceneKind,
    dir: &Path,
    r: &Value,
    q: &QualityReport,
    command: Option<&str>,
) -> anyhow::Result<String> {
    let task = scene.task().name();
    let d = &r["denoiser"];
    let c = &r["discriminator"];
    let s = &r["settings"];
    let f = |v: &Value| v.as_f64().map_or("—".to_string(), |x| format!("{x:.4}"));
    let size = |name: &str| {
        std::fs::metadata(dir.join(name)).map_or("—".to_string(), |m| {
            format!("{:.2} MB", m.len() as f64 / 1e6)
        })
    };
    // Which models these are: the task's default directory, or another (a training seed, the
    // paper's card goals).
    let name = dir
        .file_name()
        .map_or(task.to_string(), |n| n.to_string_lossy().into_owned());
    let role = if name == task {
        format!("The default models of `dips plan` for the {task} task")
    } else {
        format!("Models for the {task} task (`--models onnx/models/{name}`)")
    };
    let goals = match dips_planning::models_card_goals(dir)? {
        Some(g) => format!(
            " Trained on demos whose card pushes aimed with the `{g}` card goals \
             (`dips.card_goals`; `docs/search.md`, \"The card's goals\"); the planner plans and \
             executes with them."
        ),
        None => String::new(),
    };
    let mut t = String::new();
    t.push_str(&format!("# Model card: {name}\n\n"));
    t.push_str(&format!(
        "{role}: `denoiser.onnx` (the diffusion \
         model M(c, s₀), contract v1), `discriminator.onnx` (Ψ) and `prior.json` (the contact-mode \
         prior fitted from the demos' mode sequences, p_min {}). Made by the project's own \
         pipeline: `dips datagen` (CSVTO in the world), `dips train` (burn, CPU), `dips model \
         quality`.{goals}\n\n",
        r["prior"]["p_min"]
    ));
    if let Some(cmd) = command {
        t.push_str(&format!("Made by:\n\n```sh\n{cmd}\n```\n\n"));
    }
    t.push_str("## Data\n\n");
    t.push_str(&format!(
        "| | |\n|---|---|\n| demos | {} ({} held out: seeds {}) |\n| trajectories | {} (train {}, held out {}) |\n| mode sequences in the prior | {} |\n\n",
        r["demos"],
        r["held_out_seeds"].as_array().map_or(0, Vec::len),
        r["held_out_seeds"],
        r["samples"],
        d["train_samples"],
        d["held_out_samples"],
        r["prior"]["sequences"],
    ));
    t.push_str("## Training\n\n");
    t.push_str(&format!(
        "| | denoiser | discriminator |\n|---|---|---|\n| parameters | {} | {} |\n| file size | {} | {} |\n| optimiser steps (batch) | {} ({}) | {} ({}) |\n| epochs | {} | — |\n| time per step | {} s | {} s |\n| training time | {:.0} s | {:.0} s (of which sampling the diffused trajectories {:.0} s) |\n| held-out loss (masked ε MSE): initial → raw / EMA | {} → {} / **{}** | — |\n| held-out accuracy / **AUC** (real vs diffused) | — | {} / **{}** |\n\n",
        d["params"], c["params"],
        size("denoiser.onnx"), size("discriminator.onnx"),
        s["denoiser"]["steps"], s["denoiser"]["batch"],
        s["discriminator"]["steps"], s["discriminator"]["batch"],
        f(&d["epochs"]),
        f(&d["step_time_s"]), f(&c["step_time_s"]),
        d["seconds"].as_f64().unwrap_or(0.0),
        c["seconds"].as_f64().unwrap_or(0.0),
        c["sampling_s"].as_f64().unwrap_or(0.0),
        f(&d["held_out_loss_initial"]), f(&d["held_out_loss_raw"]), f(&d["held_out_loss"]),
        f(&c["held_out_accuracy"]), f(&c["held_out_auc"]),
    ));
    t.push_str(&format!(
        "Settings (`settings.json`):\n\n```json\n{}\n```\n\n",
        serde_json::to_string_pretty(s)?
    ));
    t.push_str("## Quality\n\n");
    t.push_str(&markdown(q));
    t.push_str(
        "\nΔq residual: how far a row's joints are from the previous row's joints plus its \
         joint deltas (the executed prefix of real data carries the world's tracking error). \
         Friction excess: how far a contact finger's force lies outside the planner's friction \
         cone (μ = 0.95) around the surface normal at the next row. Lifted-finger sdf: the \
         signed distance of the regrasping fingers at the inner rows (δ = 1.5 cm).\n",
    );
    Ok(t)
}
