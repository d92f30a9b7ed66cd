//! `dips plan`: one A* planning call from the task's start state (`docs/contracts.md` §5).
//!
//! The models are read from `--models DIR` or the shipped ones (`denoiser.onnx` and
//! `discriminator.onnx`, contract v1, checked against the task) and run by the kernel's
//! interpreter (default) or tract. The search is the kernel's `PaperPlanner` with the paper's
//! settings unless flags change them, the prior is the directory's `prior.json` (fitted from
//! the training data) or else the paper's (`MarkovPrior::paper`), and the start state is the
//! world's. The
//! wiring is the shared planning session ([`dips_planning::Session`]).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{anyhow, bail};
use clap::{Args, ValueEnum};
use dips_kernel::mode::Task;
use dips_kernel::search::{SearchConfig, SearchOverrides};
use dips_kernel::session::PlanSpec;
use dips_onnx::EngineKind;
use serde_json::json;

use dips_exec::problems::contract::contract_state;
use dips_kernel::budget::NoClock;
use dips_link::{KernelTarget, RemotePlanner};
use dips_planning::{Models, PaperSession, PlanOutcome, PlanService, ProgressClock, models_dir};
use dips_world::scenes::SceneKind;
use dips_world::world::World;

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
    #[arg(long, value_parser = crate::search_args::named::<SceneKind>())]
    pub task: SceneKind,
    /// Directory holding `denoiser.onnx`, `discriminator.onnx` and optionally `prior.json`
    /// (default: the shipped models, `onnx/models/<task>`, or `$DIPS_MODELS/<task>`).
    #[arg(long)]
    pub models: Option<PathBuf>,
    /// Seed of the search's random stream.
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
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
    /// The search's flags.
    #[command(flatten)]
    pub search: crate::search_args::SearchArgs,
    /// The card's goals.
    #[command(flatten)]
    pub card_goals: crate::search_args::CardGoalsArgs,
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
    /// Threads of each model call (default: every core). The plan does not depend on it, only
    /// how many expansions fit a time budget.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::search_args::parse_positive)]
    pub threads: Option<usize>,
    /// Where the plan is made: `in-process`, `spawn` (a `dips-firmware-sim` child),
    /// `spawn:PATH` or `tcp://HOST:PORT`. The plan is the same bit for bit.
    #[arg(long, default_value = "in-process", value_parser = KernelTarget::parse)]
    pub kernel: KernelTarget,
}

/// The search settings of `dips plan`: the task's own ([`SearchConfig::for_task`]: the
/// screwdriver's α = 1e4, β = 1e3, depth 7; the card's α = 1e5, β = 0, depth 5) with the
/// flags' changes, resolved by [`SearchOverrides::resolve`].
pub fn search_config(task: Task, args: &PlanArgs) -> anyhow::Result<SearchConfig> {
    let overrides = SearchOverrides {
        k: Some(args.k),
        max_depth: args.depth,
        ..args.search.overrides()
    };
    let config = overrides.resolve(task, args.seed, args.search.time_budget_ms()?);
    config
        .validate()
        .map_err(|field| anyhow!("{field} (--k, --depth)"))?;
    if usize::from(config.k) > dips_planning::PAPER_K {
        bail!(
            "--k {}: this planner holds at most {} particles per node",
            config.k,
            dips_planning::PAPER_K
        );
    }
    Ok(config)
}

/// Run the command.
pub fn run(args: PlanArgs) -> anyhow::Result<()> {
    let scene = args.task;
    let task = scene.task();
    let sampler = args.search.sampler;
    let config = search_config(task, &args)?;

    let world_state = World::new(scene).state();
    let start: Vec<f32> = contract_state(&world_state)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    // The world's raw yaw is unwrapped, so goals more than π away (a full turn) plan as given.
    let start_yaw = world_state.last().copied().unwrap_or(0.0) as f32;
    let goal = match args.goal {
        Some(goal) => goal,
        None => PlanSpec::paper_goal(task, &start)
            .ok_or_else(|| anyhow!("the world's {} state is too short", task.name()))?,
    };
    let mut spec = PlanSpec::new(task, &start, goal)
        .and_then(|spec| spec.with_start_yaw(start_yaw))
        .map_err(|e| match e {
            dips_kernel::session::SpecError::Goal => anyhow!("--goal must be finite"),
            e => anyhow!("{e}"),
        })?;
    spec.search = config;
    spec.sampler = sampler;
    spec.check().map_err(|e| anyhow!("{e}"))?;

    let kind = match args.engine {
        PlanEngine::Kernel => EngineKind::Kernel,
        PlanEngine::Tract => EngineKind::Tract,
    };
    let dir = models_dir(args.models.as_deref(), task)?;
    let mut models = Models::load(kind, &dir, task)?;
    models.set_threads(crate::model::threads(args.threads)?);
    models.check_sampler(&sampler, task)?;
    spec = spec.with_card_goals(args.card_goals.resolve(
        task,
        None,
        Some((dir.as_path(), models.trained_card_goals())),
    )?);
    let prior_source = match models.prior {
        Some(prior) => {
            spec.prior = prior;
            spec.check()
                .map_err(|e| anyhow!("{}: {e}", dir.display()))?;
            "fitted (prior.json)"
        }
        None => "paper",
    };
    let t0 = Instant::now();
    let report: PlanOutcome = match args.kernel.open()? {
        Some(link) => {
            crate::note!("planning through {}", link.name());
            let mut remote = RemotePlanner::new(link, &dir, task)?;
            remote.plan_call(&spec, &mut NoClock)?
        }
        None => {
            let mut session = PaperSession::new(models);
            // A line on stderr every second of a long call (stdout stays the result).
            let budget = args.search.time_budget_s;
            let mut tell = |s: f64, reads: u64| {
                crate::note!(
                    "planning: {s:.0} s, {} expansions started (budget {budget} s)",
                    reads.saturating_sub(1)
                );
            };
            PlanOutcome::from(&session.plan(
                &spec,
                &mut ProgressClock::start(std::time::Duration::from_secs(1), &mut tell),
            )?)
        }
    };
    let planning_s = t0.elapsed().as_secs_f64();
    let names: Vec<&str> = report
        .modes
        .iter()
        .map(|m| task.mode_name(*m).unwrap_or("?"))
        .collect();
    let out = json!({
        "task": task.name(),
        "seed": args.seed,
        "engine": format!("{:?}", args.engine).to_lowercase(),
        "sampler": sampler.method.to_string(),
        "models": dir.display().to_string(),
        "prior": prior_source,
        "goal": crate::bench::shortest(goal),
        "settings": {
            "k": config.k,
            "max_depth": config.max_depth,
            "alpha": crate::bench::shortest(config.alpha),
            "beta": crate::bench::shortest(config.beta),
            "gamma": crate::bench::shortest(config.gamma),
            "p_min": crate::bench::shortest(config.p_min),
            "node_budget": config.node_budget,
            "time_budget_ms": config.time_budget_ms,
            "cost_to_come": config.cost_to_come.name(),
        },
        "status": format!("{:?}", report.status),
        "modes": names,
        "expected_progress": finite_or_null(report.expected_progress),
        "terminal_state": report.terminal_state.iter().map(|&v| finite_or_null(v)).collect::<Vec<_>>(),
        "stats": {
            "nodes_expanded": report.nodes_expanded,
            "nodes_generated": report.nodes_generated,
            "sampler_calls": report.sampler_calls,
            "scorer_calls": report.scorer_calls,
            "segments_sampled": report.segments_sampled,
        },
        "planning_s": planning_s,
        "kernel": args.kernel.to_string(),
    });
    crate::output::figures(args.json, &out)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        plan: PlanArgs,
    }

    fn args(extra: &[&str]) -> PlanArgs {
        let mut argv = vec!["dips-plan", "--task", "card"];
        argv.extend_from_slice(extra);
        Cli::parse_from(argv).plan
    }

    #[test]
    fn each_task_plans_with_its_own_search_settings() {
        let sd = search_config(Task::Screwdriver, &args(&[])).unwrap();
        assert_eq!((sd.alpha, sd.beta, sd.max_depth), (1e4, 1e3, 7));
        let card = search_config(Task::Card, &args(&[])).unwrap();
        assert_eq!((card.alpha, card.beta, card.max_depth), (1e5, 0.0, 5));
        assert_eq!(
            card,
            SearchConfig {
                time_budget_ms: 300_000,
                ..SearchConfig::card()
            }
        );
        // Flags change only what they name.
        let c = search_config(
            Task::Card,
            &args(&["--k", "4", "--depth", "3", "--seed", "9"]),
        );
        let c = c.unwrap();
        assert_eq!((c.k, c.max_depth, c.seed), (4, 3, 9));
        assert_eq!((c.alpha, c.beta), (1e5, 0.0));
        assert!(search_config(Task::Card, &args(&["--k", "17"])).is_err());
    }
}
