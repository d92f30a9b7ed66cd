//! `dips plan`: one A* planning call from the task's start state (`CONTRACTS.md` §5).
//!
//! The models are read from `--models DIR` (`denoiser.onnx` and `discriminator.onnx`, contract
//! v1, checked against the task) and run by the kernel's interpreter (default) or tract. The
//! search is the kernel's `PaperPlanner` with the paper's settings unless flags change them,
//! the prior is the paper's ([`MarkovPrior::paper`]), and the start state is the world's.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, anyhow, bail};
use clap::{Args, ValueEnum};
use dips_kernel::adapters::{
    DiffusionSegmentSampler, DiscriminatorScorer, SamplerAdapterLayout, ScorerAdapterLayout,
};
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::engine::DenoiserEngine;
use dips_kernel::mode::Task;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{PaperPlanner, Problem, SearchConfig};
use dips_kernel::task::{CARD_GOAL_Y, Objective, ScrewdriverObjective};
use dips_onnx::{AnyEngine, EngineKind, Expectation, Role};
use serde_json::json;

use super::bench::StdClock;
use crate::problems::contract::contract_state;
use crate::scenes::SceneKind;
use crate::world::World;

/// Which engine runs the models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PlanEngine {
    /// The kernel's no_std interpreter on the lowered models.
    Kernel,
    /// tract on the ONNX files.
    Tract,
}

/// Arguments of `dips plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Task: `screwdriver` or `card`.
    #[arg(long)]
    pub task: String,
    /// Directory holding `denoiser.onnx` and `discriminator.onnx`.
    #[arg(long, default_value = "models")]
    pub models: PathBuf,
    /// Seed of the search's random stream.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Engine that runs the models.
    #[arg(long, value_enum, default_value_t = PlanEngine::Kernel)]
    pub engine: PlanEngine,
    /// Search goal: screwdriver yaw (rad; default the start yaw − π/3), card y (m; default
    /// −0.06, the paper's).
    #[arg(long, allow_hyphen_values = true)]
    pub goal: Option<f32>,
    /// Particles per node (at most 16).
    #[arg(long, default_value_t = 16)]
    pub k: u16,
    /// Search depth (default: screwdriver 7, card 5).
    #[arg(long)]
    pub depth: Option<u8>,
    /// Most node expansions (0: limited by the planner's capacity).
    #[arg(long, default_value_t = 0)]
    pub node_budget: u32,
    /// Wall-clock budget in seconds (0: none; the paper's is 300).
    #[arg(long, default_value_t = 300.0)]
    pub time_budget_s: f64,
    /// Diffusion sampler: `ddpm` (the paper's) or `ddim:STEPS`.
    #[arg(long, default_value = "ddpm")]
    pub sampler: String,
    /// Print JSON (the only output format).
    #[arg(long)]
    pub json: bool,
}

fn sampler_config(spec: &str) -> anyhow::Result<SamplerConfig> {
    if spec == "ddpm" {
        return Ok(SamplerConfig::default());
    }
    let steps = spec
        .strip_prefix("ddim:")
        .and_then(|n| n.parse::<u16>().ok())
        .filter(|&n| n > 0)
        .ok_or_else(|| anyhow!("--sampler {spec:?}: expected `ddpm` or `ddim:STEPS`"))?;
    Ok(SamplerConfig::ddim(steps))
}

fn load(kind: EngineKind, dir: &Path, role: Role, task: Task) -> anyhow::Result<AnyEngine> {
    let file = dir.join(match role {
        Role::Denoiser => "denoiser.onnx",
        Role::Discriminator => "discriminator.onnx",
    });
    if !file.is_file() {
        bail!("no {role:?} model at {}", file.display());
    }
    AnyEngine::load(kind, &file, &Expectation::new(role, task.name()))
        .with_context(|| format!("loading {}", file.display()))
}

/// Run the command.
pub fn run(args: PlanArgs) -> anyhow::Result<()> {
    let scene = SceneKind::from_name(&args.task).with_context(|| {
        format!(
            "unknown task `{}` (expected screwdriver or card)",
            args.task
        )
    })?;
    let task = match scene {
        SceneKind::Screwdriver => Task::Screwdriver,
        SceneKind::Card => Task::Card,
    };
    let sampler_config = sampler_config(&args.sampler)?;
    if !(args.time_budget_s.is_finite() && args.time_budget_s >= 0.0) {
        bail!("--time-budget-s must be a finite number of seconds ≥ 0");
    }
    let config = SearchConfig {
        k: args.k,
        max_depth: args.depth.unwrap_or(match task {
            Task::Screwdriver => 7,
            Task::Card => 5,
        }),
        node_budget: args.node_budget,
        time_budget_ms: (args.time_budget_s * 1e3).round().min(f64::from(u32::MAX)) as u32,
        seed: args.seed,
        ..SearchConfig::default()
    };
    config
        .validate()
        .map_err(|field| anyhow!("invalid search setting: {field:?}"))?;
    if usize::from(config.k) > 16 {
        bail!(
            "--k {} exceeds the planner's 16 particles per node",
            config.k
        );
    }

    let start: Vec<f32> = contract_state(&World::new(scene).state())
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let goal = match (args.goal, task) {
        (Some(goal), _) => goal,
        (None, Task::Screwdriver) => {
            ScrewdriverObjective::from_state(&start)
                .ok_or_else(|| anyhow!("the world's screwdriver state is too short"))?
                .goal_yaw
        }
        (None, Task::Card) => CARD_GOAL_Y,
    };
    let objective =
        Objective::for_goal(task, &start, goal).ok_or_else(|| anyhow!("--goal must be finite"))?;
    let prior = MarkovPrior::paper(task, config.p_min)
        .map_err(|e| anyhow!("the paper's prior with p_min {}: {e}", config.p_min))?;

    let kind = match args.engine {
        PlanEngine::Kernel => EngineKind::Kernel,
        PlanEngine::Tract => EngineKind::Tract,
    };
    let mut denoiser = load(kind, &args.models, Role::Denoiser, task)?;
    let mut discriminator = load(kind, &args.models, Role::Discriminator, task)?;
    let dims = DenoiserEngine::dims(&denoiser);
    let batch = task.mode_count() * usize::from(config.k);
    let sl = SamplerAdapterLayout::new(dims, batch, batch);
    let cl = ScorerAdapterLayout::new(dims, batch);
    let (mut sb, mut cb) = (vec![0.0f32; sl.total()], vec![0.0f32; cl.total()]);
    let mut sampler = DiffusionSegmentSampler::new(&mut denoiser, sampler_config, &mut sb, &sl)
        .map_err(|e| anyhow!("denoiser adapter: {e}"))?;
    let mut scorer = DiscriminatorScorer::new(&mut discriminator, &mut cb, &cl)
        .map_err(|e| anyhow!("discriminator adapter: {e}"))?;
    let mut planner = Box::new(PaperPlanner::new());
    let t0 = Instant::now();
    let report = planner.plan(
        &config,
        &Problem {
            task,
            dims: task.dims(),
            start: &start,
            executed: None,
            prior: &prior,
        },
        &mut sampler,
        &mut scorer,
        &objective,
        &mut StdClock(t0),
    );
    let planning_s = t0.elapsed().as_secs_f64();
    let names: Vec<&str> = report
        .modes
        .iter()
        .map(|m| task.modes().get(usize::from(m.0)).map_or("?", |s| s.name))
        .collect();
    let s = &report.stats;
    let out = json!({
        "task": task.name(),
        "seed": args.seed,
        "engine": format!("{:?}", args.engine).to_lowercase(),
        "sampler": args.sampler,
        "goal": goal,
        "status": format!("{:?}", report.status),
        "modes": names,
        "expected_progress": finite_or_null(report.expected_progress),
        "terminal_state": report.terminal_state.iter().map(|&v| finite_or_null(v)).collect::<Vec<_>>(),
        "stats": {
            "nodes_expanded": s.nodes_expanded,
            "nodes_generated": s.nodes_generated,
            "sampler_calls": s.sampler_calls,
            "scorer_calls": s.scorer_calls,
            "segments_sampled": s.segments_sampled,
        },
        "planning_s": planning_s,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// JSON has no NaN: a value that is not finite is `null`.
fn finite_or_null(v: f32) -> serde_json::Value {
    if v.is_finite() {
        json!(v)
    } else {
        serde_json::Value::Null
    }
}
