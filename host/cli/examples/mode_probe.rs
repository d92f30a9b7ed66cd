//! What the models predict from given start states, beside what the world and the training
//! data did there (the screwdriver diagnoses in `docs/decisions.md`).
//!
//! Two sources of start states:
//!
//! - **Episodes**: for every executed mode of each `result.json` given (written by
//!   `dips episode` or `dips eval`), the mode's executed start state. With `--all-modes`,
//!   every mode the search expands is probed there, the executed one marked `*` (the others'
//!   "executed" change is 0: they were not executed).
//! - **Demos** (`--demos DIR`): the modes of a datagen directory's demos, optionally only
//!   mode `--mode M` right after mode `--after P` (`start` for a demo's first mode), starting
//!   below `--below X` in the task's progress coordinate, of the models' held-out demos
//!   (`--held-out`, from `train_report.json`), at most `--limit N` (default 40). Modes after a
//!   demo's first invalid one (the object already fell) are skipped. Each line then also gives
//!   the mean change and first-step jump of the demo's own trajectories of that mode (every
//!   online step and particle: what the denoiser was fitted to there), and a summary closes
//!   the list: the means, the correlation of the model's change with the data's over the
//!   states, and the mean absolute difference.
//!
//! From each start state it samples 64 segments of the mode as the planner does (`--sampler`,
//! default `dips_cli::search_args::DEFAULT_SAMPLER`, the task's start anchor
//! `dips_kernel::session::start_anchor`; `--guidance W`, `--noise-factor F` and `--yaw-min RAD`
//! change the guidance weight, DDPM's noise factor and the lowest start yaw the models are asked
//! about; `--raw` keeps the models' rows as drawn, only the yaw clamped, as the committed
//! mode-probe tables measured them) and prints: the executed and the mean
//! diffused change of the task's progress coordinate (yaw in rad, card y in m), the mean
//! first-step joint jump `‖q₁ − q₀‖` of the
//! diffused segments (the model's start consistency), the share of segments with a joint more
//! than 0.05 rad outside the Allegro hand's limits after row 0 and the mean of their largest
//! excess (rad), and Ψ's mean score, its effective sample size over the 64 and its correlation
//! with the segments' first-step jumps. `--profile` adds the mean change of the progress
//! coordinate at every row (diffused, and the data's with `--demos`).
//!
//! ```sh
//! cargo run --release -p dips-cli --example mode_probe -- \
//!     [--models DIR] [--sampler ddpm] target/eval-work/screwdriver/episodes/dips/seed-1009/result.json
//! cargo run --release -p dips-cli --example mode_probe -- --models DIR \
//!     --demos target/data/screwdriver --mode turn --after turn --below -1.0
//! ```

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use dips_cli::output::line;
use dips_exec::problems::contract::contract_state;
use dips_kernel::adapters::StartAnchor;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::diffusion::normalize::normalize_in_place;
use dips_kernel::engine::DiscriminatorEngine;
use dips_kernel::mode::{Task, TaskMode};
use dips_kernel::rng::KernelRng;
use dips_kernel::session::start_anchor;
use dips_planning::{Models, models_dir, sample_trajectories};

/// Segments sampled per start state.
const SAMPLES: usize = 64;

/// Start states probed from demos when `--limit` is not given.
const DEFAULT_LIMIT: usize = 40;

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

/// Which demo modes `--demos` probes.
#[derive(Debug, Default)]
struct DemoFilter {
    mode: Option<String>,
    after: Option<String>,
    below: Option<f64>,
    held_out: bool,
    limit: Option<usize>,
}

/// One start state to probe.
struct Run {
    /// Where it comes from (a demo's seed and mode index), empty for episodes.
    label: String,
    mode: TaskMode,
    /// World state `[q, o]` at the mode's start and end (object angle in radians).
    start: Vec<f64>,
    end: Vec<f64>,
    /// The demo's own trajectories of this mode.
    data: Option<SegmentStats>,
}

/// What the models make of one start state.
struct Probe {
    stats: SegmentStats,
    outside: usize,
    excess: f32,
    psi_mean: f32,
    ess: f32,
    psi_jump_correlation: f32,
}

/// Everything but the files: the models, the sampler and the start-angle range.
struct Setup {
    models_arg: Option<PathBuf>,
    sampler: SamplerConfig,
    yaw_min: Option<f32>,
    /// Sample without the start anchor (only the yaw clamped): the models' rows as drawn.
    raw: bool,
    /// Print the mean change of the progress coordinate at every row.
    profile: bool,
    /// Probe every mode of the task at each executed start, not only the executed one.
    all_modes: bool,
}

fn probe() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let mut models_arg = None;
    let mut sampler_arg = dips_cli::search_args::DEFAULT_SAMPLER.to_string();
    let mut guidance: Option<f32> = None;
    let mut noise: Option<f32> = None;
    let mut yaw_min: Option<f32> = None;
    let mut profile = false;
    let mut raw = false;
    let mut all_modes = false;
    let mut demos: Option<PathBuf> = None;
    let mut task_arg: Option<String> = None;
    let mut filter = DemoFilter::default();
    let mut files = Vec::new();
    while let Some(a) = args.next() {
        let mut value = |what: &str| args.next().with_context(|| format!("{a} needs {what}"));
        match a.as_str() {
            "--models" => models_arg = Some(PathBuf::from(value("a directory")?)),
            "--sampler" => sampler_arg = value("a sampler, e.g. ddpm or ddim:16")?,
            "--guidance" => guidance = Some(value("a weight")?.parse()?),
            "--noise-factor" => noise = Some(value("a factor")?.parse()?),
            "--yaw-min" => yaw_min = Some(value("an angle in radians")?.parse()?),
            "--demos" => demos = Some(PathBuf::from(value("a datagen directory")?)),
            "--task" => task_arg = Some(value("a task name")?),
            "--mode" => filter.mode = Some(value("a mode name")?),
            "--after" => filter.after = Some(value("a mode name or `start`")?),
            "--below" => filter.below = Some(value("a progress value")?.parse()?),
            "--limit" => filter.limit = Some(value("a count")?.parse()?),
            "--held-out" => filter.held_out = true,
            "--profile" => profile = true,
            "--raw" => raw = true,
            "--all-modes" => all_modes = true,
            _ if a.starts_with("--") => bail!("unknown option {a}"),
            _ => files.push(PathBuf::from(a)),
        }
    }
    let mut sampler = sampler_arg.parse::<SamplerConfig>()?;
    if let Some(w) = guidance {
        sampler.guidance_weight = w;
    }
    if let Some(f) = noise {
        use dips_kernel::diffusion::SamplingMethod;
        match &mut sampler.method {
            SamplingMethod::Ddpm { noise_factor }
            | SamplingMethod::DdpmStrided { noise_factor, .. } => {
                *noise_factor = f;
            }
            SamplingMethod::Ddim { .. } => bail!("--noise-factor applies to DDPM samplers only"),
        }
    }
    let setup = Setup {
        models_arg,
        sampler,
        yaw_min,
        raw,
        profile,
        all_modes,
    };
    match demos {
        Some(dir) => {
            if !files.is_empty() {
                bail!("give either --demos or result files, not both");
            }
            if setup.all_modes {
                bail!("--all-modes probes the executed starts of result files, not --demos");
            }
            let task: Task = task_arg
                .as_deref()
                .unwrap_or("screwdriver")
                .parse()
                .map_err(|e| anyhow::anyhow!("--task: {e}"))?;
            probe_demos(&setup, task, &dir, &filter)
        }
        None if files.is_empty() => bail!(
            "usage: mode_probe [--models DIR] [--sampler S] [--guidance W] [--noise-factor F] [--yaw-min RAD] \
             [--raw] [--profile] \
             ([--all-modes] RESULT.json ... | --demos DIR [--task T] [--mode M] [--after M|start] [--below X] \
             [--held-out] [--limit N])"
        ),
        None => {
            for file in files {
                probe_result(&setup, &file)?;
            }
            Ok(())
        }
    }
}

/// Probe every executed mode of one `result.json`.
fn probe_result(setup: &Setup, file: &Path) -> anyhow::Result<()> {
    let text =
        std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
    let r: serde_json::Value = serde_json::from_str(&text)?;
    let task: Task = r["task"].as_str().context("no task")?.parse()?;
    let columns: Vec<&str> = r["state_columns"]
        .as_array()
        .map(|c| c.iter().filter_map(serde_json::Value::as_str).collect())
        .unwrap_or_default();
    let mut runs = Vec::new();
    for run in r["mode_runs"].as_array().context("no mode_runs")? {
        let name = run["mode"].as_str().context("mode")?;
        let executed = TaskMode::from_name(task, name).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let start: Vec<f64> = serde_json::from_value(run["start_state"].clone())?;
        let end: Vec<f64> = serde_json::from_value(run["end_state"].clone())?;
        let modes: Vec<TaskMode> = if setup.all_modes {
            task.candidate_modes()
                .filter_map(|id| TaskMode::from_id(task, id))
                .collect()
        } else {
            vec![executed]
        };
        for mode in modes {
            // Another mode than the executed one has no executed change: its end is its start.
            let end = if mode == executed {
                end.clone()
            } else {
                start.clone()
            };
            let label = if setup.all_modes && mode == executed {
                "* "
            } else if setup.all_modes {
                "  "
            } else {
                ""
            };
            runs.push(Run {
                label: label.to_string(),
                mode,
                start: start.clone(),
                end,
                data: None,
            });
        }
    }
    line(&format!("{}:", file.display()))?;
    let dir = models_dir(setup.models_arg.as_deref(), task)?;
    probe_runs(setup, task, &dir, &columns, &runs)
}

/// Probe the modes of a datagen directory's demos that `filter` selects.
fn probe_demos(setup: &Setup, task: Task, dir: &Path, filter: &DemoFilter) -> anyhow::Result<()> {
    let models = models_dir(setup.models_arg.as_deref(), task)?;
    let held_out: Option<Vec<u64>> = if filter.held_out {
        let path = models.join("train_report.json");
        let report: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(&path)
                .with_context(|| format!("reading {} (for --held-out)", path.display()))?,
        )?;
        Some(
            serde_json::from_value(report["held_out_seeds"].clone())
                .with_context(|| format!("{}: no held_out_seeds list", path.display()))?,
        )
    } else {
        None
    };
    let ds = dips_dataset::read_dir(dir, task)?;
    let dims = task.dims();
    let layout = task.layout();
    let progress = progress_index(task);
    let nq = layout.object();
    let limit = filter.limit.unwrap_or(DEFAULT_LIMIT);
    let mut runs = Vec::new();
    'demos: for demo in &ds.demos {
        if held_out.as_ref().is_some_and(|h| !h.contains(&demo.seed)) {
            continue;
        }
        let Some(outcome) = demo.outcome() else {
            continue;
        };
        let Some(modes) = outcome["modes"].as_array() else {
            continue;
        };
        let last = demo.first_invalid_mode().unwrap_or(usize::MAX);
        for (i, m) in modes.iter().enumerate().take(last.saturating_add(1)) {
            let name = m["mode"].as_str().context("a demo mode without a name")?;
            let prev = if i == 0 {
                "start"
            } else {
                modes[i - 1]["mode"].as_str().unwrap_or("")
            };
            let start: Vec<f64> = serde_json::from_value(m["start_state"].clone())?;
            let end: Vec<f64> = serde_json::from_value(m["end_state"].clone())?;
            if filter.mode.as_deref().is_some_and(|f| f != name)
                || filter.after.as_deref().is_some_and(|f| f != prev)
                || filter
                    .below
                    .is_some_and(|b| start.get(nq + progress).is_none_or(|&p| p >= b))
            {
                continue;
            }
            let rows: Vec<&[f32]> = (0..demo.len())
                .filter(|&j| demo.mode_index[j] == i as i64)
                .map(|j| demo.trajectory(j))
                .collect();
            let stats = segment_stats(task, dims, nq, rows.iter().copied());
            runs.push(Run {
                label: format!("seed {} mode {i} ", demo.seed),
                mode: TaskMode::from_name(task, name).map_err(|e| anyhow::anyhow!("{e:?}"))?,
                start,
                end,
                data: Some(stats),
            });
            if runs.len() >= limit {
                break 'demos;
            }
        }
    }
    if runs.is_empty() {
        bail!("no demo mode in {} matches the filter", dir.display());
    }
    line(&format!("{} ({} modes):", dir.display(), runs.len()))?;
    probe_runs(setup, task, &models, task.state_columns(), &runs)
}

/// The pose index of the task's progress coordinate (screwdriver yaw, card y).
fn progress_index(task: Task) -> usize {
    if task == Task::Screwdriver { 2 } else { 1 }
}

/// Mean change of the progress coordinate (last row minus row 0), mean first-step joint
/// jump, and the mean change at every row (the profile), over segments.
fn segment_stats<'a>(
    task: Task,
    dims: dips_kernel::mode::SegmentDims,
    nq: usize,
    segments: impl Iterator<Item = &'a [f32]>,
) -> SegmentStats {
    let d = dims.dim();
    let layout = task.layout();
    let progress = progress_index(task);
    let pose = |row: &[f32]| layout.pose(row).unwrap_or([f32::NAN; 3])[progress];
    let mut profile = vec![0.0f32; dims.horizon];
    let (mut jump, mut n) = (0.0, 0usize);
    for seg in segments {
        let start = pose(seg);
        for (r, p) in profile.iter_mut().enumerate() {
            let change = pose(&seg[r * d..]) - start;
            *p += if task == Task::Screwdriver {
                dips_kernel::task::wrap_angle(change)
            } else {
                change
            };
        }
        jump += joint_jump(seg, d, nq);
        n += 1;
    }
    let n = n.max(1) as f32;
    profile.iter_mut().for_each(|p| *p /= n);
    SegmentStats {
        delta: profile.last().copied().unwrap_or(f32::NAN),
        jump: jump / n,
        profile,
    }
}

/// What [`segment_stats`] measures.
struct SegmentStats {
    delta: f32,
    jump: f32,
    profile: Vec<f32>,
}

/// `‖q₁ − q₀‖` of one segment.
fn joint_jump(seg: &[f32], d: usize, nq: usize) -> f32 {
    (0..nq)
        .map(|j| (seg[d + j] - seg[j]).powi(2))
        .sum::<f32>()
        .sqrt()
}

/// Probe each run and print a line per run; with data, a summary line after them.
fn probe_runs(
    setup: &Setup,
    task: Task,
    models_dir: &Path,
    columns: &[impl AsRef<str>],
    runs: &[Run],
) -> anyhow::Result<()> {
    let mut models = Models::load(dips_onnx::EngineKind::Kernel, models_dir, task)?;
    let limits = joint_limits(columns);
    let mut anchor = start_anchor(task);
    if let (Some(a), Some(lo)) = (anchor.angle.as_mut(), setup.yaw_min) {
        a.lo = lo;
    }
    let progress = progress_index(task);
    let mut summary: Vec<(f32, f32, f32, f32, f32)> = Vec::new();
    for run in runs {
        let nq = run.start.len() - 3;
        let run_limits = limits.as_deref().filter(|l| l.len() == nq);
        let p = probe_one(&mut models, setup, anchor, task, run, run_limits)?;
        let executed = (run.end[nq + progress] - run.start[nq + progress]) as f32;
        let limits_note = if run_limits.is_some() {
            format!(
                "; outside the joint limits {}/{SAMPLES} (mean excess {:.3})",
                p.outside, p.excess
            )
        } else {
            String::new()
        };
        let data_note = match &run.data {
            Some(data) => {
                summary.push((p.stats.delta, data.delta, executed, p.stats.jump, data.jump));
                format!("; data {:+.3}, jump {:.3}", data.delta, data.jump)
            }
            None => String::new(),
        };
        line(&format!(
            "  {}{:22} start {:+.3}: executed {:+.3}, diffused {:+.3}; first-step joint jump {:.3}{data_note}{limits_note}; Ψ {:.3} (ESS {:.1}/{SAMPLES}, correlation with the jump {:+.2})",
            run.label,
            run.mode.name(),
            run.start[nq + progress],
            executed,
            p.stats.delta,
            p.stats.jump,
            p.psi_mean,
            p.ess,
            p.psi_jump_correlation
        ))?;
        if setup.profile {
            line(&format!(
                "    profile, diffused: {}",
                fmt_profile(&p.stats.profile)
            ))?;
            if let Some(data) = &run.data {
                line(&format!(
                    "    profile, data:     {}",
                    fmt_profile(&data.profile)
                ))?;
            }
        }
    }
    if !summary.is_empty() {
        let n = summary.len() as f32;
        let mean =
            |f: fn(&(f32, f32, f32, f32, f32)) -> f32| summary.iter().map(f).sum::<f32>() / n;
        let model: Vec<f32> = summary.iter().map(|s| s.0).collect();
        let data: Vec<f32> = summary.iter().map(|s| s.1).collect();
        line(&format!(
            "  summary over {} modes: diffused {:+.3}, data {:+.3}, executed {:+.3}; first-step jump diffused {:.3}, data {:.3}; correlation of diffused with data {:+.2}; mean |diffused − data| {:.3}",
            summary.len(),
            mean(|s| s.0),
            mean(|s| s.1),
            mean(|s| s.2),
            mean(|s| s.3),
            mean(|s| s.4),
            correlation(&model, &data),
            mean(|s| (s.0 - s.1).abs()),
        ))?;
    }
    Ok(())
}

/// A profile's values, 3 decimals each.
fn fmt_profile(profile: &[f32]) -> String {
    profile
        .iter()
        .map(|v| format!("{v:+.3}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Sample [`SAMPLES`] segments of `run`'s mode from its start state and measure them.
fn probe_one(
    models: &mut Models,
    setup: &Setup,
    anchor: StartAnchor,
    task: Task,
    run: &Run,
    limits: Option<&[(f32, f32)]>,
) -> anyhow::Result<Probe> {
    let dims = task.dims();
    let (td, d, sd, f) = (dims.floats(), dims.dim(), dims.state_dim, dims.fingers);
    let h = dims.horizon - 1;
    let nq = run.start.len() - 3;
    // The world's [q, o] with o's angle as (cos, sin), the models' raw state.
    let state: Vec<f32> = contract_state(&run.start)
        .iter()
        .map(|&v| v as f32)
        .collect();
    if state.len() != sd {
        bail!(
            "{}: state of {} values, the models take {sd}",
            run.mode.name(),
            state.len()
        );
    }
    let mut ctx = vec![0f32; f];
    run.mode.contact_mode().write_signs(&mut ctx);
    let context: Vec<f32> = ctx.iter().copied().cycle().take(SAMPLES * f).collect();
    let mut starts: Vec<f32> = state.iter().copied().cycle().take(SAMPLES * sd).collect();
    // Raw: the yaw clamped, nothing anchored; the changes below are relative to row 0, so the
    // clamp does not bias them.
    let anchor = if setup.raw {
        if let Some(a) = anchor.clamp_angle(sd) {
            a.clamp_starts(&mut starts, sd);
        }
        StartAnchor::NONE
    } else {
        anchor
    };
    let mut rng = KernelRng::seed_from_u64(7);
    let out = sample_trajectories(
        &mut models.denoiser,
        &setup.sampler,
        &context,
        &starts,
        anchor,
        &mut rng,
    )?;
    let stats = segment_stats(task, dims, nq, out.chunks(td));
    let jumps: Vec<f32> = out.chunks(td).map(|s| joint_jump(s, d, nq)).collect();
    let (mut outside, mut excess) = (0usize, 0.0f32);
    if let Some(l) = limits {
        for seg in out.chunks(td) {
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
    Ok(Probe {
        stats,
        outside,
        excess: excess / SAMPLES as f32,
        psi_mean: sum / SAMPLES as f32,
        ess,
        psi_jump_correlation: correlation(&jumps, &psi),
    })
}

/// Each joint's `(lower, upper)` limits on the Allegro hand, in the order of the state's
/// `q_<finger>_<j>` columns; `None` when a column does not name a joint of the hand.
fn joint_limits(columns: &[impl AsRef<str>]) -> Option<Vec<(f32, f32)>> {
    let hand = dips_world::kinematics::HandModel::allegro_v4();
    columns
        .iter()
        .filter_map(|c| c.as_ref().strip_prefix("q_"))
        .map(|c| {
            let (finger, j) = c.rsplit_once('_')?;
            let finger = dips_world::kinematics::Finger::from_name(finger)?;
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
