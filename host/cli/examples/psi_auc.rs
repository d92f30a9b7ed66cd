//! How well Ψ tells real trajectories from diffused ones, for the samplers that matter: the
//! planner's own (`ddpm:16` and the task's start anchor, as the search scores them) beside the
//! fakes Ψ was trained on (DDPM-256 and DDIM-8, no anchor). Real segments are a dataset's
//! CSVTO trajectories (every `--every`-th, default 8); each sampler draws one fake from each
//! real segment's start and contact mode. Prints one JSON object: per sampler Ψ's ROC AUC
//! (real against fake), Ψ's mean on both, and the share of fakes Ψ scores below 0.1 and above
//! 0.9; `docs/particles.md` reads it.
//!
//! ```sh
//! dips datagen --task screwdriver --demos 6 --first-seed 900 --out target/particles/sd-heldout
//! cargo run --release -p dips-cli --example psi_auc -- --data target/particles/sd-heldout \
//!     [--task screwdriver] [--models DIR] [--every 8] [--no-ddpm256]
//! ```

use std::path::PathBuf;

use anyhow::{Context, bail};
use dips_dataset::{demo_files, read_demo};
use dips_kernel::adapters::StartAnchor;
use dips_kernel::diffusion::normalize::normalize_in_place;
use dips_kernel::diffusion::{SamplerConfig, SamplingMethod};
use dips_kernel::engine::DiscriminatorEngine;
use dips_kernel::mode::Task;
use dips_kernel::rng::KernelRng;
use dips_kernel::session::start_anchor;
use dips_planning::{Models, models_dir, sample_trajectories};
use dips_train::discriminator::auc;

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if dips_cli::output::is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            dips_cli::output::note(&format!("psi_auc: {e:#}"));
            std::process::ExitCode::FAILURE
        }
    }
}

fn scores(
    models: &mut Models,
    segments: &[f32],
    context: &[f32],
    n: usize,
) -> anyhow::Result<Vec<f32>> {
    let mut x = segments.to_vec();
    normalize_in_place(&models.discriminator.normalization(), &mut x);
    let mut psi = vec![0f32; n];
    let batch = 64usize;
    let (td, f) = (segments.len() / n, context.len() / n);
    for c0 in (0..n).step_by(batch) {
        let c1 = (c0 + batch).min(n);
        models
            .discriminator
            .p_real(
                c1 - c0,
                &x[c0 * td..c1 * td],
                &context[c0 * f..c1 * f],
                &mut psi[c0..c1],
            )
            .map_err(|e| anyhow::anyhow!("Ψ: {e:?}"))?;
    }
    Ok(psi)
}

fn run() -> anyhow::Result<()> {
    let (mut data, mut task_name, mut models_arg, mut every) = (
        None::<PathBuf>,
        "screwdriver".to_string(),
        None::<PathBuf>,
        8usize,
    );
    let mut with_ddpm256 = true;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--data" => data = Some(args.next().context("--data DIR")?.into()),
            "--task" => task_name = args.next().context("--task T")?,
            "--models" => models_arg = Some(args.next().context("--models DIR")?.into()),
            "--every" => every = args.next().context("--every N")?.parse()?,
            "--no-ddpm256" => with_ddpm256 = false,
            f => bail!(
                "unknown argument {f} (--data DIR, --task T, --models DIR, --every N, --no-ddpm256)"
            ),
        }
    }
    let data = data.context("--data DIR is required")?;
    let task = task_name.parse::<Task>()?;
    let dims = task.dims();
    let (td, sd, f) = (dims.floats(), dims.state_dim, dims.fingers);
    let dir = models_dir(models_arg.as_deref(), task)?;
    let mut models = Models::load(dips_onnx::EngineKind::Kernel, &dir, task)?;
    let (mut real, mut context) = (Vec::new(), Vec::new());
    let mut demos = Vec::new();
    for file in demo_files(&data)? {
        let demo = read_demo(&file, task)?;
        demos.push(demo.seed);
        let n = demo.trajectories.len() / td;
        for i in (0..n).step_by(every.max(1)) {
            real.extend_from_slice(&demo.trajectories[i * td..(i + 1) * td]);
            context.extend_from_slice(&demo.contexts[i * f..(i + 1) * f]);
        }
    }
    let n = real.len() / td;
    if n == 0 {
        bail!("{}: no trajectories", data.display());
    }
    let starts: Vec<f32> = real.chunks(td).flat_map(|t| t[..sd].to_vec()).collect();
    let psi_real = scores(&mut models, &real, &context, n)?;
    let samplers: [(&str, SamplerConfig, StartAnchor); 3] = [
        (
            "planner: ddpm:16 + start anchor",
            "ddpm:16".parse::<SamplerConfig>()?,
            start_anchor(task),
        ),
        (
            "training fakes: ddpm (256 steps)",
            SamplerConfig::default(),
            StartAnchor::NONE,
        ),
        (
            "training fakes: ddim:8",
            SamplerConfig::ddim(8),
            StartAnchor::NONE,
        ),
    ];
    let mut rows = Vec::new();
    for (name, config, anchor) in samplers {
        // DDPM-256 costs 16× the others (about 5 min on 2 cores); its fakes do not depend on Ψ.
        if !with_ddpm256 && matches!(config.method, SamplingMethod::Ddpm { .. }) {
            continue;
        }
        let t0 = std::time::Instant::now();
        let mut rng = KernelRng::seed_from_u64(11);
        let fake = sample_trajectories(
            &mut models.denoiser,
            &config,
            &context,
            &starts,
            anchor,
            &mut rng,
        )?;
        let psi_fake = scores(&mut models, &fake, &context, n)?;
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        let share = |v: &[f32], p: fn(f32) -> bool| {
            v.iter().filter(|&&x| p(x)).count() as f32 / v.len() as f32
        };
        rows.push(serde_json::json!({
            "sampler": name,
            "auc_real_vs_fake": auc(&psi_real, &psi_fake),
            "psi_mean_fake": mean(&psi_fake),
            "fake_share_below_0_1": share(&psi_fake, |x| x < 0.1),
            "fake_share_above_0_9": share(&psi_fake, |x| x > 0.9),
            "seconds": t0.elapsed().as_secs_f64(),
        }));
    }
    let out = serde_json::json!({
        "task": task_name,
        "data": data.display().to_string(),
        "demo_seeds": demos,
        "real_segments": n,
        "psi_mean_real": psi_real.iter().sum::<f32>() / n as f32,
        "real_share_below_0_1": psi_real.iter().filter(|&&x| x < 0.1).count() as f32 / n as f32,
        "real_share_above_0_9": psi_real.iter().filter(|&&x| x > 0.9).count() as f32 / n as f32,
        "samplers": rows,
    });
    dips_cli::output::line(&serde_json::to_string_pretty(&out)?)
}
