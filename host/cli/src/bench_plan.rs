//! `dips bench plan`: the wall time of real planning calls (the shipped or given models, the
//! task's default search settings) from the task's start state, one call per seed.
//!
//! This is the figure the paper reports as A* time (46.8 s screwdriver, 64.9 s card on a
//! GPU). The calls of whole episodes, from every state an episode visits, are in
//! `dips eval`'s table (planning median / p90).

use dips_onnx::EngineKind;
use std::time::Instant;

use anyhow::anyhow;
use clap::Args;
use dips_eval::summary::Stats;
use dips_exec::problems::contract::contract_state;
use dips_kernel::session::PlanSpec;
use dips_planning::{Models, PaperSession, StdClock, models_dir};
use dips_world::scenes::SceneKind;
use dips_world::world::World;
use serde_json::json;

use crate::model::SimdArg;
use crate::search_args::named;

/// `dips bench plan`.
#[derive(Debug, Args)]
pub struct PlanBenchArgs {
    /// Task: `screwdriver` or `card`.
    #[arg(long, default_value = "screwdriver", value_parser = named::<SceneKind>())]
    pub task: SceneKind,
    /// Planning calls; call `i` uses seed `--seed + i`.
    #[arg(long, default_value_t = 10)]
    pub calls: u32,
    /// First seed.
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
    pub seed: u64,
    /// The search's flags.
    #[command(flatten)]
    pub search: crate::search_args::SearchArgs,
    /// Models directory (default: the shipped models).
    #[arg(long)]
    pub models: Option<std::path::PathBuf>,
    /// Engine that runs the models.
    #[arg(long, value_parser = crate::search_args::named::<EngineKind>(), default_value = "kernel")]
    pub engine: EngineKind,
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
    /// Threads of each model call (default: every core). The plan does not depend on it, only
    /// how many expansions fit a time budget.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::search_args::parse_positive)]
    pub threads: Option<usize>,
    /// Which copies of the kernel interpreter's op kernels run (the plans are the same).
    #[arg(long, value_enum, default_value_t = SimdArg::Auto)]
    pub simd: SimdArg,
}

/// Run the benchmark.
pub fn run(args: &PlanBenchArgs) -> anyhow::Result<()> {
    let scene = args.task;
    if args.calls == 0 {
        anyhow::bail!("--calls must be at least 1");
    }
    let time_budget_ms = args.search.time_budget_ms()?;
    let task = scene.task();
    let simd = args.simd.apply();
    let sampler = args.search.sampler;
    let dir = models_dir(args.models.as_deref(), task)?;
    let mut models = Models::load(args.engine, &dir, task)?;
    let threads = crate::model::threads(args.threads)?;
    models.set_threads(threads);
    models.check_sampler(&sampler, task)?;
    let prior = models.prior;
    let mut session = PaperSession::new(models);
    let start: Vec<f32> = contract_state(&World::new(scene).state())
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let goal = PlanSpec::paper_goal(task, &start).ok_or_else(|| anyhow!("state too short"))?;
    let overrides = args.search.overrides();
    let mut calls = Vec::new();
    let mut seconds = Vec::new();
    // The form every call searches with (the calls differ only in their seeds).
    let cost_to_come = overrides
        .resolve(task, args.seed, time_budget_ms)
        .cost_to_come;
    for i in 0..args.calls {
        let config = overrides.resolve(task, args.seed + u64::from(i), time_budget_ms);
        let mut spec = PlanSpec::new(task, &start, goal).map_err(|e| anyhow!("{e}"))?;
        spec.search = config;
        spec.sampler = sampler;
        if let Some(p) = prior {
            spec.prior = p;
        }
        spec.check().map_err(|e| anyhow!("{e}"))?;
        let t0 = Instant::now();
        let report = session.plan(&spec, &mut StdClock(t0))?;
        let s = t0.elapsed().as_secs_f64();
        crate::note!(
            "call {}/{}: {s:.2} s, {} expansions, {:?}",
            i + 1,
            args.calls,
            report.stats.nodes_expanded,
            report.status
        );
        seconds.push(s);
        calls.push(json!({
            "seed": config.seed,
            "seconds": s,
            "nodes_expanded": report.stats.nodes_expanded,
            "status": format!("{:?}", report.status),
            "modes": report.modes.iter().map(|m| task.mode_name(*m).unwrap_or("?")).collect::<Vec<_>>(),
        }));
    }
    let stats = Stats::of(&seconds).ok_or_else(|| anyhow!("no finite call time"))?;
    let out = json!({
        "bench": "plan",
        "task": task.name(),
        "models": dir.display().to_string(),
        "engine": format!("{:?}", args.engine).to_lowercase(),
        "sampler": args.search.sampler.method.to_string(),
        "cost_to_come": cost_to_come.name(),
        "start": "the task's start state",
        "threads": threads,
        "simd": simd,
        "calls": calls,
        "seconds": {
            "median": stats.median,
            "p90": stats.p90,
            "max": stats.max,
            "mean": stats.mean,
        },
    });
    crate::output::figures(args.json, &out)?;
    Ok(())
}
