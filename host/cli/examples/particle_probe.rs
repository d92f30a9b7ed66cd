//! Do k = 16 particles choose differently from k = 1? From the executed start state of every
//! planning call of the given episodes (`result.json` of a `dips` episode), plan again with
//! k = 16 (Ψ-weighted particles), k = 1 and max-likelihood over `--seeds N` search seeds each
//! (default 4), with the call's own depth, goal, the task's search settings and the shipped
//! models, and report how often two plans pick the same next mode: within k = 16 (its own
//! seed-to-seed agreement), within k = 1, and across k = 16 / k = 1 and k = 16 /
//! max-likelihood. With equal agreement within and across, the particles change nothing about
//! the choice; `docs/particles.md` reads this output.
//!
//! ```sh
//! cargo run --release -p dips-cli --example particle_probe -- [--seeds 4] [--models DIR] \
//!     target/particles/screwdriver-500/episodes/dips/seed-50*/result.json > probe.json
//! ```
//!
//! Writes one JSON object: per state the next mode each plan chose, and the agreement rates.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context, bail};
use dips_exec::problems::contract::contract_state;
use dips_kernel::budget::NoClock;
use dips_kernel::diffusion::SamplerConfig;
use dips_kernel::mode::Task;
use dips_kernel::prior::MarkovPrior;
use dips_kernel::search::{SearchConfig, SearchVariant};
use dips_kernel::session::PlanSpec;
use dips_planning::{Models, PaperSession, PlanService, models_dir};

fn main() -> std::process::ExitCode {
    match probe() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if dips_cli::output::is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            dips_cli::output::note(&format!("particle_probe: {e:#}"));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The three planners compared.
const VARIANTS: [&str; 3] = ["k16", "k1", "max-likelihood"];

fn config(variant: &str, depth: u8, task: Task, seed: u64) -> SearchConfig {
    let base = SearchConfig::for_task(task);
    let mut c = SearchConfig {
        max_depth: depth,
        seed,
        time_budget_ms: 0,
        ..base
    };
    match variant {
        "k1" => c.k = 1,
        "max-likelihood" => c.variant = SearchVariant::MaxLikelihood,
        _ => {}
    }
    c
}

/// Share of pairs (a from `xs`, b from `ys`, distinct draws when `same`) that agree.
fn agreement(xs: &[String], ys: &[String], same: bool) -> Option<f64> {
    let (mut agree, mut pairs) = (0usize, 0usize);
    for (i, a) in xs.iter().enumerate() {
        for (j, b) in ys.iter().enumerate() {
            if same && i >= j {
                continue;
            }
            pairs += 1;
            agree += usize::from(a == b);
        }
    }
    (pairs > 0).then(|| agree as f64 / pairs as f64)
}

fn probe() -> anyhow::Result<()> {
    let mut seeds = 4u64;
    let mut models_arg: Option<PathBuf> = None;
    let mut files = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seeds" => seeds = args.next().context("--seeds N")?.parse()?,
            "--models" => models_arg = Some(args.next().context("--models DIR")?.into()),
            f if f.starts_with("--") => bail!("unknown flag {f} (--seeds N, --models DIR)"),
            f => files.push(PathBuf::from(f)),
        }
    }
    if files.is_empty() || seeds == 0 {
        bail!("give at least one result.json and --seeds ≥ 1");
    }
    let mut sessions: BTreeMap<String, (PaperSession, MarkovPrior)> = BTreeMap::new();
    let mut states = Vec::new();
    let mut rates: BTreeMap<&str, (f64, usize)> = BTreeMap::new();
    for file in &files {
        let text = std::fs::read_to_string(file).with_context(|| file.display().to_string())?;
        let r: serde_json::Value = serde_json::from_str(&text)?;
        let task_name = r["task"].as_str().context("no task")?.to_string();
        let task = task_name.parse::<Task>()?;
        if !sessions.contains_key(&task_name) {
            let dir = models_dir(models_arg.as_deref(), task)?;
            let models = Models::load(dips_onnx::EngineKind::Kernel, &dir, task)?;
            models.check_sampler(&"ddpm:16".parse::<SamplerConfig>()?, task)?;
            let prior = match models.prior {
                Some(p) => p,
                None => MarkovPrior::paper(task, SearchConfig::for_task(task).p_min)
                    .map_err(|e| anyhow::anyhow!("{e}"))?,
            };
            sessions.insert(task_name.clone(), (PaperSession::new(models), prior));
        }
        let (session, prior) = sessions.get_mut(&task_name).context("session")?;
        let runs = r["mode_runs"].as_array().context("no mode_runs")?;
        let plans = r["plans"]
            .as_array()
            .context("no plans: not a searching method")?;
        let executed: Vec<String> = serde_json::from_value(r["modes"].clone())?;
        for (i, plan) in plans.iter().enumerate() {
            let Some(run) = runs.get(i) else { break };
            if plan["modes"].as_array().is_none_or(|m| m.is_empty()) {
                continue; // a finished episode's last call
            }
            let raw: Vec<f64> = serde_json::from_value(run["start_state"].clone())?;
            let start: Vec<f32> = contract_state(&raw).iter().map(|&v| v as f32).collect();
            let depth = plan["depth"].as_u64().context("no depth")? as u8;
            let goal = plan["goal"].as_f64().context("no goal")? as f32;
            let mut chosen: BTreeMap<&str, Vec<String>> = BTreeMap::new();
            for variant in VARIANTS {
                for seed in 0..seeds {
                    let mut spec = PlanSpec::with_settings(
                        task,
                        &start,
                        goal,
                        config(variant, depth, task, 1_000_003 * seed + 17),
                        *prior,
                    )
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                    spec.sampler = "ddpm:16".parse::<SamplerConfig>()?;
                    spec.executed = (i > 0)
                        .then(|| executed.get(i - 1))
                        .flatten()
                        .and_then(|m| dips_exec::problems::Mode::from_name(task, m).ok())
                        .map(|m| m.id());
                    let out = session.plan_call(&spec, &mut NoClock)?;
                    let first = out
                        .modes
                        .first()
                        .and_then(|&id| dips_exec::problems::Mode::from_id(task, id))
                        .map_or("none".to_string(), |m| m.name().to_string());
                    chosen.entry(variant).or_default().push(first);
                }
            }
            let pairs = [
                ("k16 within", "k16", "k16", true),
                ("k1 within", "k1", "k1", true),
                (
                    "max-likelihood within",
                    "max-likelihood",
                    "max-likelihood",
                    true,
                ),
                ("k16 vs k1", "k16", "k1", false),
                ("k16 vs max-likelihood", "k16", "max-likelihood", false),
                ("k1 vs max-likelihood", "k1", "max-likelihood", false),
            ];
            let mut state_rates = serde_json::Map::new();
            for (name, a, b, same) in pairs {
                if let Some(x) = agreement(&chosen[a], &chosen[b], same) {
                    let e = rates.entry(name).or_insert((0.0, 0));
                    e.0 += x;
                    e.1 += 1;
                    state_rates.insert(name.into(), x.into());
                }
            }
            states.push(serde_json::json!({
                "episode": file.display().to_string(),
                "call": i,
                "executed_next": executed.get(i),
                "chosen": chosen,
                "agreement": state_rates,
            }));
        }
    }
    let summary: serde_json::Map<String, serde_json::Value> = rates
        .iter()
        .map(|(k, (sum, n))| ((*k).to_string(), (sum / *n as f64).into()))
        .collect();
    let out = serde_json::json!({
        "seeds_per_planner": seeds,
        "states": states.len(),
        "mean_agreement": summary,
        "per_state": states,
    });
    dips_cli::output::line(&serde_json::to_string_pretty(&out)?)
}
