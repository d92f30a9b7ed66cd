//! What the models predict from the states an episode actually reached, beside what the
//! world did (the screwdriver diagnosis in `docs/results/README.md`).
//!
//! For every executed mode of each `result.json` given (written by `dips episode` or
//! `dips eval`), samples 64 segments of that mode from its executed start state, as the
//! planner does (`--sampler`, default `dips_cli::search_args::DEFAULT_SAMPLER`, the task's
//! invariant angle) and prints: the executed and the mean diffused change of the task's
//! progress coordinate (yaw in rad, card y in m), the mean first-step joint jump `‖q₁ − q₀‖`
//! of the diffused segments (the model's start consistency), the share of segments with a
//! joint more than 0.05 rad outside the Allegro hand's limits after row 0 and the mean of their
//! largest excess (rad), and Ψ's mean score, its effective sample size over the 64 and its
//! correlation with the segments' first-step jumps.
//!
//! ```sh
//! cargo run --release -p dips-cli --example mode_probe -- \
//!     [--models DIR] [--sampler ddpm] target/eval-work/screwdriver/episodes/dips/seed-1009/result.json
//! ```

use std::path::PathBuf;

use anyhow::{Context, bail};
use dips_cli::output::line;
use dips_host::planning::{Models, models_dir, parse_sampler, sample_trajectories};
use dips_host::problems::contract::contract_state;
use dips_kernel::diffusion::normalize::normalize_in_place;
use dips_kernel::engine::DiscriminatorEngine;
use dips_kernel::mode::{Task, TaskMode};
use dips_kernel::rng::KernelRng;
use dips_kernel::session::invariant_angle;

/// Segments sampled per executed mode.
const SAMPLES: usize = 64;

fn main() -> std::process::ExitCode {
    match probe() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // A reader that stops early (`| head`) ends the output, not in an error.
        Err(e) if dips_cli::output::is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mode_probe: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn probe() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let mut models_arg = None;
    let mut sampler_arg = dips_cli::search_args::DEFAULT_SAMPLER.to_string();
    let mut files = Vec::new();
    while let Some(a) = args.next() {
        if a == "--models" {
            models_arg = Some(PathBuf::from(
                args.next().context("--models needs a directory")?,
            ));
        } else if a == "--sampler" {
            sampler_arg = args
                .next()
                .context("--sampler needs a sampler, e.g. ddpm or ddim:16")?;
        } else {
            files.push(PathBuf::from(a));
        }
    }
    if files.is_empty() {
        bail!("usage: mode_probe [--models DIR] [--sampler S] RESULT.json ...");
    }
    let sampler = parse_sampler(&sampler_arg)?;
    for file in files {
        let text = std::fs::read_to_string(&file)
            .with_context(|| format!("reading {}", file.display()))?;
        let r: serde_json::Value = serde_json::from_str(&text)?;
        let task = Task::from_name(r["task"].as_str().context("no task")?)
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let dir = models_dir(models_arg.as_deref(), task)?;
        let mut models = Models::load(dips_onnx::EngineKind::Kernel, &dir, task)?;
        let dims = task.dims();
        let (td, d, sd, f) = (dims.floats(), dims.dim(), dims.state_dim, dims.fingers);
        let h = dims.horizon - 1;
        let layout = task.layout();
        let progress = if task == Task::Screwdriver { 2 } else { 1 };
        let limits = joint_limits(&r);
        line(&format!("{}:", file.display()))?;
        for run in r["mode_runs"].as_array().context("no mode_runs")? {
            let name = run["mode"].as_str().context("mode")?;
            let mode = TaskMode::from_name(task, name).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            let world: Vec<f64> = serde_json::from_value(run["start_state"].clone())?;
            let end: Vec<f64> = serde_json::from_value(run["end_state"].clone())?;
            let nq = world.len() - 3;
            let limits = limits.as_deref().filter(|l| l.len() == nq);
            // The world's [q, o] with o's angle as (cos, sin), the models' raw state.
            let state: Vec<f32> = contract_state(&world).iter().map(|&v| v as f32).collect();
            if state.len() != sd {
                bail!(
                    "{name}: state of {} values, the models take {sd}",
                    state.len()
                );
            }
            let mut ctx = vec![0f32; f];
            mode.contact_mode().write_signs(&mut ctx);
            let context: Vec<f32> = ctx.iter().copied().cycle().take(SAMPLES * f).collect();
            let starts: Vec<f32> = state.iter().copied().cycle().take(SAMPLES * sd).collect();
            let mut rng = KernelRng::seed_from_u64(7);
            let out = sample_trajectories(
                &mut models.denoiser,
                &sampler,
                &context,
                &starts,
                invariant_angle(task),
                &mut rng,
            )?;
            let pose = |row: &[f32]| layout.pose(row).unwrap_or([f32::NAN; 3])[progress];
            let wrap = |a: f32| {
                if task == Task::Screwdriver {
                    dips_kernel::task::wrap_angle(a)
                } else {
                    a
                }
            };
            let mut delta = 0.0;
            let mut jump = 0.0;
            let mut jumps = Vec::with_capacity(SAMPLES);
            let (mut outside, mut excess) = (0usize, 0.0f32);
            for seg in out.chunks(td) {
                if let Some(l) = limits {
                    let worst = (1..=h)
                        .flat_map(|t| (0..nq).map(move |j| (t, j)))
                        .map(|(t, j)| {
                            let q = seg[t * d + j];
                            (l[j].0 - q).max(q - l[j].1).max(0.0)
                        })
                        .fold(0.0f32, f32::max);
                    excess += worst;
                    outside += usize::from(worst > 0.05);
                }
                delta += wrap(pose(&seg[h * d..]) - pose(seg));
                let jmp = (0..nq)
                    .map(|j| (seg[d + j] - seg[j]).powi(2))
                    .sum::<f32>()
                    .sqrt();
                jump += jmp;
                jumps.push(jmp);
            }
            let mut x = out.clone();
            normalize_in_place(&models.discriminator.normalization(), &mut x);
            let mut psi = vec![0f32; SAMPLES];
            models
                .discriminator
                .p_real(SAMPLES, &x, &context, &mut psi)
                .map_err(|e| anyhow::anyhow!("Ψ: {e:?}"))?;
            let sum: f32 = psi.iter().sum();
            let ess = sum * sum
                / psi
                    .iter()
                    .map(|p| p * p)
                    .sum::<f32>()
                    .max(f32::MIN_POSITIVE);
            let executed = end[nq + progress] - world[nq + progress];
            let limits_note = if limits.is_some() {
                format!(
                    "; outside the joint limits {}/{SAMPLES} (mean excess {:.3})",
                    outside,
                    excess / SAMPLES as f32
                )
            } else {
                String::new()
            };
            line(&format!(
                "  {name:22} start {:+.3}: executed {:+.3}, diffused {:+.3}; first-step joint jump {:.3}{limits_note}; Ψ {:.3} (ESS {:.1}/{SAMPLES}, correlation with the jump {:+.2})",
                world[nq + progress],
                executed,
                delta / SAMPLES as f32,
                jump / SAMPLES as f32,
                sum / SAMPLES as f32,
                ess,
                correlation(&jumps, &psi)
            ))?;
        }
    }
    Ok(())
}

/// Each joint's `(lower, upper)` limits on the Allegro hand, in the order of the result's
/// `q_<finger>_<j>` state columns; `None` when a column does not name a joint of the hand.
fn joint_limits(r: &serde_json::Value) -> Option<Vec<(f32, f32)>> {
    let hand = dips_host::kinematics::HandModel::allegro_v4();
    r["state_columns"]
        .as_array()?
        .iter()
        .filter_map(|c| c.as_str()?.strip_prefix("q_"))
        .map(|c| {
            let (finger, j) = c.rsplit_once('_')?;
            let finger = dips_host::kinematics::Finger::from_name(finger)?;
            let (lo, hi) = *hand.joint_limits(finger).get(j.parse::<usize>().ok()?)?;
            Some((lo as f32, hi as f32))
        })
        .collect()
}

/// Pearson correlation of two equally long samples (NaN when either is constant).
fn correlation(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len()) as f32;
    let (ma, mb) = (a.iter().sum::<f32>() / n, b.iter().sum::<f32>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}
