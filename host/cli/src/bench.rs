//! `dips bench ...`: benchmarks that print JSON figures.
//!
//! `dips bench search` measures the DIPS A* (`dips_kernel::search`) with a cheap synthetic
//! sampler, so the figure is the planner's own throughput (batch bookkeeping, task costs,
//! resampling, open list), not the diffusion model's. The synthetic sampler below is a
//! benchmark workload: an analytic segment generator with noise in the task's raw layout.

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use dips_kernel::mode::{ContactMode, SegmentDims, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::rng::KernelRng;
use dips_kernel::search::{
    PaperPlanner, SearchOverrides, SearchStats, SegmentSampler, SegmentScorer,
};
use dips_kernel::session::{PlanSpec, plan_with_adapters};
use dips_kernel::task::{CardObjective, Objective, ScrewdriverObjective};

use dips_planning::StdClock;
use serde_json::json;
use std::time::{Duration, Instant};

/// `dips bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The benchmark to run.
    #[command(subcommand)]
    pub command: BenchCommand,
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Expansions per second of the A* contact search with a synthetic sampler.
    Search(SearchBenchArgs),
    /// Median seconds per call of both model engines on one model at one batch.
    Inference(super::bench_inference::InferenceArgs),
    /// Time of one 1 s action (all sub-steps) in each scene of the quasi-static world.
    Sim(super::bench_sim::BenchSimArgs),
    /// Seconds per online CSVTO step (screwdriver turn, N = 16, 25 iterations, H = 12).
    Csvto(super::bench_csvto::CsvtoBenchArgs),
    /// Wall time of real planning calls with the shipped models from the task's start.
    Plan(super::bench_plan::PlanBenchArgs),
    /// Static memory, peak stack and wire overhead of the firmware with the shipped models.
    Firmware(super::bench_firmware::FirmwareBenchArgs),
}

/// `dips bench search`.
#[derive(Debug, Args)]
pub struct SearchBenchArgs {
    /// Task whose sizes and costs are used (`screwdriver`: T=13, D=37, 3 modes; `card`:
    /// T=9, D=29, 4 modes).
    #[arg(long, default_value = "screwdriver", value_parser = crate::search_args::named::<Task>())]
    pub task: Task,
    /// Particles per node.
    #[arg(long, default_value_t = 16)]
    pub k: u16,
    /// Search depth.
    #[arg(long, default_value_t = 7)]
    pub depth: u8,
    /// Expansions per planning call (the node budget); the goal is out of reach so every
    /// call spends exactly this many.
    #[arg(long, default_value_t = 100)]
    pub expansions_per_call: u32,
    /// Seconds to measure for (after one warm-up call).
    #[arg(long, default_value_t = 3.0)]
    pub seconds: f64,
    /// First seed; call `i` uses `seed + i`.
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
    pub seed: u64,
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
}

/// Run `dips bench`.
pub fn run(args: BenchArgs, hands: &dyn dips_world::hand::Hands) -> anyhow::Result<()> {
    match args.command {
        BenchCommand::Search(a) => search(&a),
        BenchCommand::Inference(a) => super::bench_inference::run(&a),
        BenchCommand::Sim(a) => super::bench_sim::main(a, hands),
        BenchCommand::Csvto(a) => super::bench_csvto::run(a),
        BenchCommand::Plan(a) => super::bench_plan::run(&a),
        BenchCommand::Firmware(a) => super::bench_firmware::run(&a),
    }
}

/// The synthetic sampler: from each start state, contact modes move the object toward the
/// task goal (screwdriver yaw −π/6, card y −2 cm) with multiplicative noise, regrasps hold
/// it with small noise; joints take a noisy random walk; actions are noise. Layout as in
/// `docs/contracts.md` §2.
#[derive(Debug)]
struct SyntheticSampler {
    task: Task,
    noise: f32,
    time: Duration,
}

impl SegmentSampler for SyntheticSampler {
    type Error = std::convert::Infallible;

    fn max_batch(&self) -> usize {
        usize::MAX
    }

    fn sample(
        &mut self,
        dims: &SegmentDims,
        starts: &[f32],
        modes: &[ContactMode],
        rng: &mut KernelRng,
        out: &mut [f32],
    ) -> Result<(), Self::Error> {
        let t0 = Instant::now();
        let (rows, d, sd) = (dims.horizon, dims.dim(), dims.state_dim);
        // Object columns (roll, pitch or x, y, then cos, sin) after the joint columns.
        let layout = self.task.layout();
        let (obj, joints) = (layout.object(), layout.joints());
        for (i, m) in modes.iter().enumerate() {
            let s0 = &starts[i * sd..(i + 1) * sd];
            let seg = &mut out[i * rows * d..(i + 1) * rows * d];
            let moving = match self.task {
                Task::Screwdriver => m.contact_count() == 3,
                Task::Card => m.contact_count() > 0,
            };
            let scale = if moving {
                1.0 + self.noise * rng.normal_f32()
            } else {
                0.1 * self.noise * rng.normal_f32()
            };
            let angle0 = s0[obj + 3].atan2(s0[obj + 2]);
            for t in 0..rows {
                let frac = t as f32 / (rows - 1).max(1) as f32;
                let row = &mut seg[t * d..(t + 1) * d];
                row[..sd].copy_from_slice(s0);
                if t > 0 {
                    for q in &mut row[..joints] {
                        *q += 0.01 * rng.normal_f32();
                    }
                }
                let mut angle = angle0;
                match self.task {
                    Task::Screwdriver => angle += frac * scale * -core::f32::consts::FRAC_PI_6,
                    Task::Card => row[obj + 1] += frac * scale * -0.02,
                }
                row[obj + 2] = angle.cos();
                row[obj + 3] = angle.sin();
                for a in &mut row[sd..] {
                    *a = if t + 1 < rows {
                        0.05 * rng.normal_f32()
                    } else {
                        0.0
                    };
                }
            }
        }
        self.time += t0.elapsed();
        Ok(())
    }
}

/// A synthetic Ψ: `exp(−0.01 · Σ x²)` over the segment (smoother segments score higher).
#[derive(Debug, Default)]
struct SyntheticScorer {
    time: Duration,
}

impl SegmentScorer for SyntheticScorer {
    type Error = std::convert::Infallible;

    fn max_batch(&self) -> usize {
        usize::MAX
    }

    fn score(
        &mut self,
        dims: &SegmentDims,
        segments: &[f32],
        modes: &[ContactMode],
        out: &mut [f32],
    ) -> Result<(), Self::Error> {
        let t0 = Instant::now();
        let n = dims.floats();
        for (i, o) in out.iter_mut().enumerate().take(modes.len()) {
            let e: f32 = segments[i * n..(i + 1) * n].iter().map(|v| v * v).sum();
            *o = (-0.01 * e).exp();
        }
        self.time += t0.elapsed();
        Ok(())
    }
}

/// A raw start state at the nominal grasp: screwdriver yaw 0, card at the origin.
fn start_state(task: Task) -> Vec<f32> {
    match task {
        Task::Screwdriver => {
            vec![
                0.1, 0.5, 0.5, 0.5, -0.1, 0.5, 0.65, 0.65, 1.2, 0.3, 0.2, 1.0, 0.0, 0.0, 1.0, 0.0,
            ]
        }
        Task::Card => vec![
            0.0, 0.35, 0.5, 0.225, 0.0, 0.35, 0.5, 0.225, 0.0, 0.0, 1.0, 0.0,
        ],
    }
}

fn search(a: &SearchBenchArgs) -> anyhow::Result<()> {
    let task = a.task;
    if !(a.seconds.is_finite() && a.seconds > 0.0) {
        bail!("--seconds must be a positive number, got {}", a.seconds);
    }
    let config = SearchOverrides {
        k: Some(a.k),
        max_depth: Some(a.depth),
        node_budget: Some(a.expansions_per_call),
        ..SearchOverrides::default()
    }
    .resolve(task, 0, 0);
    config
        .validate()
        .with_context(|| "invalid search settings")?;
    let capacity = dips_planning::PAPER_K;
    if a.k == 0 || usize::from(a.k) > capacity {
        bail!(
            "--k {}: the benchmarked planner holds 1 to {capacity} particles per node (its \
             capacity, the paper's k)",
            a.k
        );
    }
    let prior = match task {
        Task::Screwdriver => MarkovPrior::from_rows(
            &[0.8, 0.1, 0.1],
            &[&[0.1, 0.45, 0.45], &[0.45, 0.1, 0.45], &[0.45, 0.45, 0.1]],
        ),
        Task::Card => MarkovPrior::uniform(4),
    }
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let start = start_state(task);
    let mut spec = PlanSpec::with_settings(task, &start, -100.0, config, prior)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // Goals out of reach, so every call spends its node budget (the yaw unwrapped around 0).
    spec.objective = match task {
        Task::Screwdriver => Objective::Screwdriver(ScrewdriverObjective {
            reference_yaw: 0.0,
            goal_yaw: -100.0,
        }),
        Task::Card => Objective::Card(CardObjective::new(-100.0)),
    };
    measure(a, &spec)
}

/// Plan repeatedly for `a.seconds` and print the figures.
fn measure(a: &SearchBenchArgs, spec: &PlanSpec) -> anyhow::Result<()> {
    let task = spec.task;
    let config = &spec.search;
    let mut planner: Box<PaperPlanner> = Box::new(PaperPlanner::new());
    let mut sampler = SyntheticSampler {
        task,
        noise: 0.2,
        time: Duration::ZERO,
    };
    let mut scorer = SyntheticScorer::default();
    let mut clock = StdClock(Instant::now());

    // Warm-up call (not measured).
    let warm = plan_with_adapters(&mut planner, spec, &mut sampler, &mut scorer, &mut clock);
    if !warm.status.has_plan() {
        bail!("planning failed: {:?}", warm.status);
    }
    sampler.time = Duration::ZERO;
    scorer.time = Duration::ZERO;

    let mut total = SearchStats::default();
    let mut calls = 0u64;
    let mut last_status = warm.status;
    let t0 = Instant::now();
    while t0.elapsed().as_secs_f64() < a.seconds {
        let call = spec.clone().with_seed(a.seed.wrapping_add(calls));
        let r = plan_with_adapters(&mut planner, &call, &mut sampler, &mut scorer, &mut clock);
        last_status = r.status;
        total.nodes_expanded += r.stats.nodes_expanded;
        total.nodes_generated += r.stats.nodes_generated;
        total.segments_sampled += r.stats.segments_sampled;
        total.sampler_calls += r.stats.sampler_calls;
        calls += 1;
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let expansions = f64::from(total.nodes_expanded);
    let workload = (sampler.time + scorer.time).as_secs_f64();
    let dims = task.dims();
    let out = json!({
        "bench": "search",
        "task": task.name(),
        "sampler": "synthetic analytic segments with noise (host bench workload)",
        "settings": {
            "k": config.k,
            "max_depth": config.max_depth,
            "modes": task.mode_count(),
            "horizon_T": dims.horizon,
            "dim_D": dims.dim(),
            "gamma": shortest(config.gamma),
            "alpha": shortest(config.alpha),
            "beta": shortest(config.beta),
            "expansions_per_call": config.node_budget,
        },
        "calls": calls,
        "status_of_last_call": format!("{last_status:?}"),
        "elapsed_s": elapsed,
        "expansions": total.nodes_expanded,
        "expansions_per_s": expansions / elapsed,
        "segments_per_s": f64::from(total.segments_sampled) / elapsed,
        "nodes_generated": total.nodes_generated,
        "sampler_calls": total.sampler_calls,
        "synthetic_sampler_and_scorer_s": workload,
        "planner_us_per_expansion_excluding_sampler_and_scorer":
            (elapsed - workload) / expansions * 1e6,
        "planner": {
            "type": "PaperPlanner = Planner<K=16, N=512, O=256, S=481>",
            "size_of_bytes": std::mem::size_of::<PaperPlanner>(),
        },
    });
    crate::output::figures(a.json, &out)?;
    Ok(())
}

/// An `f32` as the `f64` with the same shortest decimal form (0.9, not 0.8999999761581421).
pub(crate) fn shortest(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}
