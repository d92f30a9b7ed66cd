//! How good trained models are, measured the way the planner uses them (issue 11 §5):
//! physical coherence of diffused trajectories beside held-out real ones ([`coherence`]),
//! diffused mode trajectories executed open loop in the world, and the regrasp clearance.
//! `dips model quality` runs it and writes the figures into the model card.
//!
//! Every trajectory is conditioned on a real start state and contact mode from the demos the
//! models were **not** trained on (`held_out_seeds` of `train_report.json`).

pub mod coherence;

use std::path::{Path, PathBuf};
use std::time::Instant;

use dips_dataset::{Dataset, DatasetError, DemoRecord};
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::mode::Task;
use dips_kernel::rng::KernelRng;
use dips_onnx::{AnyEngine, EngineKind, ModelError};
use serde::Serialize;

use crate::{Models, ModelsError, SampleError, sample_trajectories};
pub use coherence::{Coherence, Dist, world_state};
use dips_world::scenes::SceneKind;
use dips_world::world::{World, WorldError};

/// Why a quality run stopped.
#[derive(Debug, thiserror::Error)]
pub enum QualityError {
    /// The dataset cannot be read.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// The models cannot be loaded.
    #[error(transparent)]
    Models(#[from] ModelsError),
    /// No held-out demo seeds were given.
    #[error("no held-out demo seeds: quality is measured on demos the models were not trained on")]
    NoHeldOut,
    /// The dataset lacks some of the models' held-out demos.
    #[error("{} holds no demo with seed(s) {seeds:?} (the models' held-out demos)", dir.display())]
    MissingDemos {
        /// The dataset directory.
        dir: PathBuf,
        /// The seeds it lacks.
        seeds: Vec<u64>,
    },
    /// A model call failed.
    #[error("{role}: {error:?}")]
    Engine {
        /// The model (`denoiser`, `discriminator`).
        role: &'static str,
        /// Why.
        error: ModelError,
    },
    /// Sampling failed.
    #[error(transparent)]
    Sample(#[from] SampleError),
    /// The world refused a state or an action of an open-loop execution.
    #[error(transparent)]
    World(#[from] WorldError),
}

/// Settings of a quality run.
#[derive(Debug, Clone)]
pub struct QualityOptions {
    /// Held-out trajectories per set (evenly spread over the held-out demos).
    pub trajectories: usize,
    /// DDIM step counts to measure beside DDPM.
    pub ddim_steps: Vec<u16>,
    /// Open-loop executions (one per held-out start of an object-moving mode, up to this many).
    pub open_loop_trials: usize,
    /// Seed of the samplers.
    pub seed: u64,
    /// Engine that runs the denoiser.
    pub engine: EngineKind,
    /// Leave out the held-out modes after an object's fall, as the models' training did
    /// (`drop_modes_after_invalid` of their settings).
    pub drop_modes_after_invalid: bool,
}

impl Default for QualityOptions {
    fn default() -> Self {
        Self {
            trajectories: 256,
            ddim_steps: vec![8, 32],
            open_loop_trials: 10,
            seed: 0,
            engine: EngineKind::Kernel,
            drop_modes_after_invalid: false,
        }
    }
}

/// How the discriminator scores a set of trajectories.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Scores {
    /// `Ψ` (probability of real) over the set.
    pub p_real: Dist,
    /// Logit of `Ψ` over the set (ln p − ln(1 − p)).
    pub logit: Dist,
    /// Effective sample size of `Ψ`-normalised weights in consecutive groups of 16:
    /// `(Σw)²/Σw²`, 16 when every sample weighs the same, 1 when one takes all. Meaningful
    /// for [`QualityReport::particles`], whose groups share a start state and mode as a search
    /// node's k = 16 particles do.
    pub ess_of_16: Dist,
}

/// One set of trajectories and its figures.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct SetQuality {
    /// `real`, `ddpm-256`, `ddim-8`, ...
    pub name: String,
    /// Trajectories measured.
    pub trajectories: usize,
    /// Seconds to sample them (0 for real data).
    pub sample_seconds: f64,
    /// The figures.
    pub coherence: Coherence,
    /// The discriminator's view of the set.
    pub scores: Scores,
    /// The object's motion per contact mode (and, for diffused sets, its error against the
    /// real trajectory from the same start).
    #[serde(default)]
    pub object_motion: Vec<coherence::ModeMotion>,
}

/// Progress that counts as moving the object toward the goal: 0.01 rad of yaw, 1 mm of card.
pub fn progress_threshold(scene: SceneKind) -> f64 {
    match scene {
        SceneKind::Screwdriver => 0.01,
        SceneKind::Card => 0.001,
    }
}

/// One open-loop execution of a diffused trajectory.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct OpenLoopTrial {
    /// Demo seed and mode the start state came from.
    pub demo_seed: u64,
    /// Mode executed.
    pub mode: String,
    /// Object progress: Δyaw (rad, clockwise negative) or Δy of the card (m).
    pub progress: f64,
    /// Whether it moved the object toward the goal (progress below minus
    /// [`progress_threshold`]).
    pub toward_goal: bool,
    /// The progress of CSVTO's own first plan from the same state, executed the same way.
    pub real_progress: f64,
    /// Whether the object stayed valid.
    pub valid: bool,
}

/// Open-loop figures.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct OpenLoop {
    /// Sampler used (DDPM-256, the planner's).
    pub sampler: String,
    /// The trials.
    pub trials: Vec<OpenLoopTrial>,
    /// How many moved the object toward the goal.
    pub toward_goal: usize,
    /// The same executions with the real (CSVTO-planned) first step's plan, for reference:
    /// how many moved the object toward the goal.
    pub real_toward_goal: usize,
}

/// Wall time of one model call.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct InferenceTime {
    /// `denoiser` or `discriminator`.
    pub role: String,
    /// `kernel` or `tract`.
    pub engine: String,
    /// Trajectories per call.
    pub batch: usize,
    /// Median over the calls (ms).
    pub median_ms: f64,
    /// Calls timed (after one warm-up call).
    pub calls: usize,
}

/// Time both models on both engines at `batch` (random inputs, median of `calls`).
fn inference_times(
    models_dir: &Path,
    task: Task,
    batch: usize,
    calls: usize,
) -> Result<Vec<InferenceTime>, QualityError> {
    use dips_kernel::engine::DiscriminatorEngine;
    let mut out = Vec::new();
    let dims = task.dims();
    let (td, f) = (dims.floats(), dims.fingers);
    let mut rng = KernelRng::seed_from_u64(7);
    let mut x = vec![0f32; 2 * batch * td];
    rng.fill_normal(&mut x);
    let ctx: Vec<f32> = (0..2 * batch * f)
        .map(|i| if i % 3 == 0 { -1.0 } else { 1.0 })
        .collect();
    let t: Vec<f32> = (0..2 * batch).map(|i| (i % 256) as f32).collect();
    let mask: Vec<f32> = (0..2 * batch).map(|i| (i % 2) as f32).collect();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    // The median wall time of `calls` calls after one warm-up call.
    let time = |call: &mut dyn FnMut() -> Result<(), QualityError>| -> Result<f64, QualityError> {
        let mut times = Vec::with_capacity(calls);
        for c in 0..=calls {
            let t0 = Instant::now();
            call()?;
            if c > 0 {
                times.push(t0.elapsed().as_secs_f64() * 1e3);
            }
        }
        Ok(median(times))
    };
    for kind in [EngineKind::Kernel, EngineKind::Tract] {
        let engine = format!("{kind:?}").to_lowercase();
        let Models {
            denoiser: mut den,
            discriminator: mut disc,
            ..
        } = Models::load(kind, models_dir, task)?;
        let mut eps = vec![0f32; batch * td];
        let den_ms = time(&mut || {
            den.predict_eps(
                batch,
                &x[..batch * td],
                &t[..batch],
                &ctx[..batch * f],
                &mask[..batch],
                &mut eps,
            )
            .map_err(|error| QualityError::Engine {
                role: "denoiser",
                error,
            })
        })?;
        let mut p = vec![0f32; batch];
        let disc_ms = time(&mut || {
            disc.p_real(batch, &x[..batch * td], &ctx[..batch * f], &mut p)
                .map_err(|error| QualityError::Engine {
                    role: "discriminator",
                    error,
                })
        })?;
        for (role, median_ms) in [("denoiser", den_ms), ("discriminator", disc_ms)] {
            out.push(InferenceTime {
                role: role.into(),
                engine: engine.clone(),
                batch,
                median_ms,
                calls,
            });
        }
    }
    Ok(out)
}

/// Everything `dips model quality` measures.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct QualityReport {
    /// The task.
    pub task: String,
    /// Models measured.
    pub models_dir: PathBuf,
    /// Dataset the start states came from.
    pub data_dir: PathBuf,
    /// Demo seeds used (held out from training).
    pub held_out_seeds: Vec<u64>,
    /// Real and diffused sets.
    pub sets: Vec<SetQuality>,
    /// Diffused object-moving modes executed open loop.
    pub open_loop: OpenLoop,
    /// Ψ on 16 groups of 16 DDPM samples, each group from one held-out start and mode (what
    /// one search node holds).
    pub particles: Scores,
    /// Engine that ran the denoiser.
    pub engine: String,
    /// Both models on both engines at batch 96.
    pub inference: Vec<InferenceTime>,
}

/// Held-out trajectories: `[n, T, D]` raw rows, contexts, and (demo seed, mode) per row.
struct Held {
    x: Vec<f32>,
    context: Vec<f32>,
    n: usize,
}

fn held_out(ds: &Dataset, seeds: &[u64], k: usize) -> Held {
    let task = ds.task;
    let dims = task.dims();
    let (td, f) = (dims.floats(), dims.fingers);
    let demos: Vec<&DemoRecord> = ds
        .demos
        .iter()
        .filter(|d| seeds.contains(&d.seed))
        .collect();
    let total: usize = demos.iter().map(|d| d.len()).sum();
    let k = k.min(total);
    let mut h = Held {
        x: Vec::with_capacity(k * td),
        context: Vec::with_capacity(k * f),
        n: 0,
    };
    let flat: Vec<(&DemoRecord, usize)> = demos
        .iter()
        .flat_map(|d| (0..d.len()).map(move |i| (*d, i)))
        .collect();
    for j in 0..k {
        let (d, i) = flat[j * total / k];
        h.x.extend_from_slice(d.trajectory(i));
        h.context.extend_from_slice(d.context(i));
        h.n += 1;
    }
    h
}

/// Score raw trajectories with the discriminator.
fn score(disc: &mut AnyEngine, x: &[f32], context: &[f32]) -> Result<Scores, QualityError> {
    use dips_kernel::engine::DiscriminatorEngine;
    let dims = DiscriminatorEngine::dims(disc);
    let td = dims.floats_per_trajectory();
    let f = dims.fingers;
    let n = x.len() / td;
    let mut xn = x.to_vec();
    dips_kernel::diffusion::normalize_in_place(&DiscriminatorEngine::normalization(disc), &mut xn);
    let mut p = vec![0f32; n];
    let chunk = DiscriminatorEngine::max_batch(disc).clamp(1, 256);
    let mut i = 0;
    while i < n {
        let b = (n - i).min(chunk);
        disc.p_real(
            b,
            &xn[i * td..(i + b) * td],
            &context[i * f..(i + b) * f],
            &mut p[i..i + b],
        )
        .map_err(|error| QualityError::Engine {
            role: "discriminator",
            error,
        })?;
        i += b;
    }
    let logit: Vec<f64> = p
        .iter()
        .map(|&v| {
            let v = f64::from(v).clamp(1e-30, 1.0 - 1e-12);
            v.ln() - (1.0 - v).ln()
        })
        .collect();
    let ess: Vec<f64> = p
        .chunks_exact(16)
        .map(|g| {
            let s: f64 = g.iter().map(|&w| f64::from(w)).sum();
            let s2: f64 = g.iter().map(|&w| f64::from(w) * f64::from(w)).sum();
            if s2 > 0.0 { s * s / s2 } else { 0.0 }
        })
        .collect();
    Ok(Scores {
        p_real: Dist::of(p.iter().map(|&v| f64::from(v)).collect()),
        logit: Dist::of(logit),
        ess_of_16: Dist::of(ess),
    })
}

/// Sample one trajectory per (context, start row of `x`) with `config` and a fresh `seed`.
fn sample_like(
    engine: &mut AnyEngine,
    config: &SamplerConfig,
    task: Task,
    x: &[f32],
    context: &[f32],
    seed: u64,
) -> Result<Vec<f32>, SampleError> {
    let dims = task.dims();
    let (td, sd) = (dims.floats(), dims.state_dim);
    let starts: Vec<f32> = x
        .chunks_exact(td)
        .flat_map(|t| t[..sd].iter().copied())
        .collect();
    // The model as trained, at the data's own start states, nothing anchored: the quality
    // report measures the model's own rows (the planner's start anchor, `session::start_anchor`,
    // would hide the first-row jump it reports).
    sample_trajectories(
        engine,
        config,
        context,
        &starts,
        dips_kernel::adapters::StartAnchor::NONE,
        &mut KernelRng::seed_from_u64(seed),
    )
}

/// The first plan of every held-out execution of an object-moving mode: `(demo seed, mode
/// name, trajectory)` (online step 0, particle 0: the start state and CSVTO's first plan).
fn moving_starts(
    ds: &Dataset,
    seeds: &[u64],
    limit: usize,
) -> Vec<(u64, String, Vec<f32>, Vec<f32>)> {
    let task = ds.task;
    let mut out = Vec::new();
    for d in ds.demos.iter().filter(|d| seeds.contains(&d.seed)) {
        for i in 0..d.len() {
            if d.step[i] != 0 || d.particle[i] != 0 {
                continue;
            }
            let name = &d.modes[d.mode_index[i] as usize];
            let moves = task
                .mode_by_name(name)
                .ok()
                .and_then(|id| task.modes().get(id.index()))
                .is_some_and(|m| m.named.moves_object());
            if moves && out.len() < limit {
                out.push((
                    d.seed,
                    name.clone(),
                    d.trajectory(i).to_vec(),
                    d.context(i).to_vec(),
                ));
            }
        }
    }
    out
}

/// Execute the joint deltas of `traj` open loop from its row 0 state; returns (progress, valid).
fn execute(scene: SceneKind, traj: &[f32]) -> Result<(f64, bool), WorldError> {
    let task = scene.task();
    let dims = task.dims();
    let (t, d) = (dims.horizon, dims.dim());
    let l = task.layout();
    let mut world = World::new(scene);
    let start = world_state(task, &traj[..d]);
    world.set_state(&start)?;
    world.resolve_penetration();
    let before = world.state();
    let mut valid = world.valid();
    for r in 0..t - 1 {
        let row = &traj[r * d..(r + 1) * d];
        let dq: Vec<f64> = (0..dims.fingers)
            .flat_map(|i| (0..4).map(move |k| (i, k)))
            .map(|(i, k)| f64::from(row[l.dq_col(i, k)]))
            .collect();
        world.step_action(&dq)?;
        valid &= world.valid();
    }
    let after = world.state();
    let n = after.len();
    let progress = match scene {
        SceneKind::Screwdriver => {
            let dy = after[n - 1] - before[n - 1];
            dy.sin().atan2(dy.cos())
        }
        SceneKind::Card => after[n - 2] - before[n - 2],
    };
    Ok((progress, valid))
}

/// Measure the models in `models_dir` against the held-out demos of the dataset in `data_dir`.
pub fn measure(
    scene: SceneKind,
    models_dir: &Path,
    data_dir: &Path,
    held_out_seeds: &[u64],
    opts: &QualityOptions,
    mut progress: impl FnMut(&str),
) -> Result<QualityReport, QualityError> {
    let task = scene.task();
    let mut ds = dips_dataset::read_dir(data_dir, task)?;
    if opts.drop_modes_after_invalid {
        ds.drop_modes_after_invalid();
    }
    if held_out_seeds.is_empty() {
        return Err(QualityError::NoHeldOut);
    }
    let missing: Vec<u64> = held_out_seeds
        .iter()
        .copied()
        .filter(|s| !ds.demos.iter().any(|d| d.seed == *s))
        .collect();
    if !missing.is_empty() {
        return Err(QualityError::MissingDemos {
            dir: data_dir.to_path_buf(),
            seeds: missing,
        });
    }
    let Models {
        denoiser: mut engine,
        discriminator: mut disc,
        ..
    } = Models::load(opts.engine, models_dir, task)?;
    let world = World::new(scene);
    let hand = world.hand_model().clone();
    let held = held_out(&ds, held_out_seeds, opts.trajectories);
    let mut sets = vec![SetQuality {
        name: "real".into(),
        trajectories: held.n,
        sample_seconds: 0.0,
        coherence: coherence::measure(scene, &hand, &held.x, &held.context),
        scores: score(&mut disc, &held.x, &held.context)?,
        object_motion: coherence::object_motion(task, &held.x, &held.context, None),
    }];
    let steps = DenoiserEngine::dims(&engine).diffusion_steps;
    let mut configs = vec![(format!("ddpm-{steps}"), SamplerConfig::default())];
    for &s in &opts.ddim_steps {
        configs.push((format!("ddim-{s}"), SamplerConfig::ddim(s)));
    }
    for (name, config) in &configs {
        progress(&format!("sampling {} {name} trajectories", held.n));
        let t0 = Instant::now();
        let x = sample_like(&mut engine, config, task, &held.x, &held.context, opts.seed)?;
        sets.push(SetQuality {
            name: name.clone(),
            trajectories: held.n,
            sample_seconds: t0.elapsed().as_secs_f64(),
            coherence: coherence::measure(scene, &hand, &x, &held.context),
            scores: score(&mut disc, &x, &held.context)?,
            object_motion: coherence::object_motion(task, &x, &held.context, Some(&held.x)),
        });
    }
    progress("particle groups");
    let groups = 16.min(held.n);
    let (td, f) = (task.dims().floats(), task.dims().fingers);
    let mut gx = Vec::with_capacity(groups * 16 * td);
    let mut gc = Vec::with_capacity(groups * 16 * f);
    for g in 0..groups {
        let i = g * held.n / groups;
        for _ in 0..16 {
            gx.extend_from_slice(&held.x[i * td..(i + 1) * td]);
            gc.extend_from_slice(&held.context[i * f..(i + 1) * f]);
        }
    }
    let gs = sample_like(
        &mut engine,
        &SamplerConfig::default(),
        task,
        &gx,
        &gc,
        opts.seed ^ 0x9a11,
    )?;
    let particles = score(&mut disc, &gs, &gc)?;
    progress("open-loop executions");
    let starts = moving_starts(&ds, held_out_seeds, opts.open_loop_trials);
    let mut trials = Vec::new();
    let mut real_toward = 0;
    for (j, (seed, mode, real, ctx)) in starts.iter().enumerate() {
        let diffused = sample_like(
            &mut engine,
            &SamplerConfig::default(),
            task,
            real,
            ctx,
            opts.seed.wrapping_add(1000 + j as u64),
        )?;
        let (progress, valid) = execute(scene, &diffused)?;
        let (real_progress, _) = execute(scene, real)?;
        let eps = progress_threshold(scene);
        real_toward += usize::from(real_progress < -eps);
        trials.push(OpenLoopTrial {
            demo_seed: *seed,
            mode: mode.clone(),
            progress,
            toward_goal: progress < -eps,
            real_progress,
            valid,
        });
    }
    Ok(QualityReport {
        task: task.name().into(),
        models_dir: models_dir.to_path_buf(),
        data_dir: data_dir.to_path_buf(),
        held_out_seeds: held_out_seeds.to_vec(),
        open_loop: OpenLoop {
            sampler: format!("ddpm-{steps}"),
            toward_goal: trials.iter().filter(|t| t.toward_goal).count(),
            trials,
            real_toward_goal: real_toward,
        },
        sets,
        particles,
        engine: format!("{:?}", opts.engine).to_lowercase(),
        inference: {
            progress("inference times");
            inference_times(models_dir, task, 96, 20)?
        },
    })
}

/// The report as Markdown (the model card's quality section).
pub fn markdown(r: &QualityReport) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "Held-out demos (seeds {:?}), {} trajectories per set, each conditioned on a real start \
         state and contact mode; denoiser run by the {} engine.\n\n",
        r.held_out_seeds,
        r.sets.first().map_or(0, |x| x.trajectories),
        r.engine
    ));
    s.push_str(
        "| set | sample time | Δq residual mean / p90 (rad) | joints outside limits | friction excess mean / p90 (N) | forces outside cone (> 0.05 N) | lifted-finger sdf p50 (cm) | lifted rows with sdf ≥ 1.5 cm |\n|---|---|---|---|---|---|---|---|\n",
    );
    for set in &r.sets {
        let c = &set.coherence;
        s.push_str(&format!(
            "| {} | {:.1} s | {:.4} / {:.4} | {:.2} % | {:.3} / {:.3} | {:.1} % | {:.2} | {:.1} % |\n",
            set.name,
            set.sample_seconds,
            c.dq_residual_rad.mean,
            c.dq_residual_rad.p90,
            100.0 * c.joints_outside_limits,
            c.friction_excess_n.mean,
            c.friction_excess_n.p90,
            100.0 * c.friction_violations,
            100.0 * c.lifted_sdf_m.p50,
            100.0 * c.lifted_clear,
        ));
    }
    s.push_str(
        "\nThe discriminator Ψ on the same sets:\n\n| set | Ψ median | Ψ p90 | logit median | logit p90 |\n|---|---|---|---|---|\n",
    );
    for set in &r.sets {
        let c = &set.scores;
        s.push_str(&format!(
            "| {} | {:.3e} | {:.3e} | {:.1} | {:.1} |\n",
            set.name, c.p_real.p50, c.p_real.p90, c.logit.p50, c.logit.p90
        ));
    }
    let (unit, scale) = if r.task == "screwdriver" {
        ("rad of yaw", 1.0)
    } else {
        ("cm of y", 100.0)
    };
    s.push_str(&format!(
        "\nThe object's motion per segment ({unit}), which the search reads as progress: mean ± \
         std per contact mode, and for diffused sets the mean error against the real trajectory \
         from the same start:\n\n| set | mode | n | motion | mean error vs real |\n|---|---|---|---|---|\n"
    ));
    for set in &r.sets {
        for m in &set.object_motion {
            s.push_str(&format!(
                "| {} | {:?} | {} | {:.3} ± {:.3} | {} |\n",
                set.name,
                m.context,
                m.n,
                scale * m.mean,
                scale * m.std,
                m.mean_abs_error
                    .map_or("—".to_string(), |e| format!("{:.3}", scale * e))
            ));
        }
    }
    let pw = &r.particles;
    s.push_str(&format!(
        "\nA search node holds k = 16 particles weighted by Ψ. Over 16 groups of 16 DDPM samples, \
         each group from one held-out start and mode, the weights leave an effective sample size \
         of {:.1} (median; p90 {:.1}, max {:.1}) of 16 (logits: median {:.1}, p90 {:.1}).\n",
        pw.ess_of_16.p50, pw.ess_of_16.p90, pw.ess_of_16.max, pw.logit.p50, pw.logit.p90
    ));
    s.push_str("\nInference, one call at batch 96 (median of 20, this machine, single-threaded):\n\n| model | kernel interpreter | tract |\n|---|---|---|\n");
    for role in ["denoiser", "discriminator"] {
        let ms = |engine: &str| {
            r.inference
                .iter()
                .find(|i| i.role == role && i.engine == engine)
                .map_or("—".to_string(), |i| format!("{:.1} ms", i.median_ms))
        };
        s.push_str(&format!(
            "| {role} | {} | {} |\n",
            ms("kernel"),
            ms("tract")
        ));
    }
    let o = &r.open_loop;
    let (unit, eps) = if r.task == "screwdriver" {
        ("rad (Δyaw)", "0.01 rad")
    } else {
        ("m (Δy)", "1 mm")
    };
    s.push_str(&format!(
        "\nOpen loop ({}): {} of {} diffused object-moving trajectories moved the object toward \
         the goal by more than {eps} (CSVTO's own first plans from the same states: {} of {}). \
         Progress in {unit}:\n\n",
        o.sampler,
        o.toward_goal,
        o.trials.len(),
        o.real_toward_goal,
        o.trials.len()
    ));
    s.push_str(
        "| demo | mode | diffused progress | toward goal | valid | CSVTO plan's progress |\n|---|---|---|---|---|---|\n",
    );
    for t in &o.trials {
        s.push_str(&format!(
            "| {} | {} | {:+.4} | {} | {} | {:+.4} |\n",
            t.demo_seed, t.mode, t.progress, t.toward_goal, t.valid, t.real_progress
        ));
    }
    s
}
