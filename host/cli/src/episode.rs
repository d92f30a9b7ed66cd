//! `dips episode`: one closed-loop episode of a method, executed on our quasi-static world or,
//! with `--hand mujoco`, on the MuJoCo hand (`docs/contracts.md` §5; the methods are
//! `dips_planning::online`'s; the planner always models our world).

use dips_onnx::EngineKind;
use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;

use dips_exec::ExecSettings;
use dips_exec::problems::Mode;
use dips_exec::problems::mode::parse_mode;
use dips_link::{KernelTarget, RemotePlanner};
use dips_planning::online::{Method, OnlineSettings, run_online};
use dips_planning::{Models, PlanService, models_card_goals, models_dir};
use dips_world::hand::Hands;
use dips_world::scenes::SceneKind;

use crate::search_args::{SearchArgs, named};

/// Arguments of `dips episode`.
#[derive(Debug, Args)]
pub struct EpisodeArgs {
    /// Task: `screwdriver` or `card`.
    #[arg(long, value_parser = named::<SceneKind>())]
    pub task: SceneKind,
    /// Method: dips, dips-sampled, csvto-sampled, dips-no-replan, dips-k1,
    /// dips-max-likelihood, diffusion-policy.
    #[arg(long, value_parser = named::<Method>())]
    pub method: Method,
    /// Seed of the episode (contact-sequence draw, search, samplers, CSVTO initialisation).
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
    pub seed: u64,
    /// Execute this comma-separated mode sequence instead of the prior's draw (dips-sampled,
    /// csvto-sampled). Modes: screwdriver `turn`, `index-regrasp`, `thumb-middle-regrasp`;
    /// card `both`, `index`, `middle`, `regrasp` (e.g. `--modes both,index,both`).
    #[arg(long, value_delimiter = ',')]
    pub modes: Option<Vec<String>>,
    /// Models directory (default: the shipped models, `onnx/models/<task>`).
    #[arg(long)]
    pub models: Option<PathBuf>,
    /// Engine that runs the models.
    #[arg(long, value_parser = crate::search_args::named::<EngineKind>(), default_value = "kernel")]
    pub engine: EngineKind,
    /// The search's flags.
    #[command(flatten)]
    pub search: SearchArgs,
    /// The card's goals.
    #[command(flatten)]
    pub card_goals: crate::search_args::CardGoalsArgs,
    /// The CSVTO settings that execute the modes.
    #[command(flatten)]
    pub exec_profile: crate::search_args::ExecProfileArgs,
    /// The episode's search depth flag.
    #[command(flatten)]
    pub online: crate::search_args::OnlineArgs,
    /// Stop after this many modes (default: the task's 7 / 5; the search depth stays).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::search_args::parse_positive)]
    pub max_modes: Option<usize>,
    /// Threads of each model call (default: every core). The plan does not depend on it, only
    /// how many expansions fit a time budget.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::search_args::parse_positive)]
    pub threads: Option<usize>,
    /// Output directory; `result.json`, the plots over time (`timeline.svg/png`) and
    /// `report.html` are written there.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the episode's animation (`episode.gif`), shown in `report.html`.
    #[arg(long)]
    pub render: bool,
    /// Where the planning calls are made: `in-process`, `spawn` (a `dips-firmware-sim`
    /// child), `spawn:PATH` or `tcp://HOST:PORT`. The result is the same bit for bit.
    #[arg(long, default_value = "in-process", value_parser = KernelTarget::parse)]
    pub kernel: KernelTarget,
    /// The hand that executes the actions.
    #[command(flatten)]
    pub hand: crate::hands::HandArgs,
}

/// Run the command.
pub fn run(args: EpisodeArgs, hands: &dyn Hands) -> anyhow::Result<()> {
    let (task, method) = (args.task, args.method);
    if args.max_modes == Some(0) {
        bail!("--max-modes must be at least 1");
    }
    let time_budget_s = args.search.time_budget_s()?;
    let sampler = args.search.sampler;
    let sequence: Option<Vec<Mode>> = match &args.modes {
        Some(names) => Some(
            names
                .iter()
                .map(|n| parse_mode(task, n.trim()))
                .collect::<Result<_, _>>()?,
        ),
        None => None,
    };
    let hand_options = args.hand.options(args.seed)?;
    // Fail on the output path before the episode, not after it.
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create the output directory {}", args.out.display()))?;
    let models = if method.needs_models() {
        let dir = models_dir(args.models.as_deref(), task.task())?;
        let mut models = Models::load(args.engine, &dir, task.task())?;
        models.set_threads(crate::model::threads(args.threads)?);
        models.check_sampler(&sampler, task.task())?;
        Some(models)
    } else {
        None
    };
    let settings = OnlineSettings {
        time_budget_s,
        search: args.search.overrides(),
        sampler,
        sequence,
        max_modes: args.max_modes,
        search_depth: args.online.search_depth,
        stop_rule: args.online.stop_rule,
        first_mode: args.online.first_mode,
        planner_size: args.online.planner_size,
    };
    let mut exec =
        ExecSettings::for_profile(task, args.exec_profile.exec_profile.unwrap_or_default())?;
    exec.pose_estimate = args.exec_profile.pose_estimate.unwrap_or_default();
    exec.regrasp_guard = args.exec_profile.regrasp_guard.unwrap_or_default();
    exec.press = args.exec_profile.press.unwrap_or_default();
    let trained = match (&models, &args.models) {
        (Some(m), _) => Some((m.dir.clone(), m.trained_card_goals())),
        // A method without models (csvto-sampled) still executes the goals of models given.
        (None, Some(dir)) => Some((dir.clone(), models_card_goals(dir)?.unwrap_or_default())),
        (None, None) => None,
    };
    exec.card_goals = args.card_goals.resolve(
        task.task(),
        None,
        trained.as_ref().map(|(d, g)| (d.as_path(), *g)),
    )?;
    let kind = args.hand.kind();
    let mut hand = hands
        .open(&kind, task, &hand_options)
        .with_context(|| format!("--hand {kind}"))?;
    let mut progress = |line: &str| crate::output::note(line);
    let link = if method.searches() {
        args.kernel.open()?
    } else {
        None
    };
    let mut remote = match (link, &models) {
        (Some(link), Some(m)) => {
            crate::note!("planning through {}", link.name());
            Some(RemotePlanner::new(link, &m.dir, task.task())?)
        }
        _ => None,
    };
    let result = run_online(
        &mut *hand,
        method,
        args.seed,
        models,
        remote.as_mut().map(|r| r as &mut dyn PlanService),
        &exec,
        &settings,
        &mut progress,
    )?;
    dips_eval::run::write_result(&result, &args.out, hand_options.noise)?;
    write_report(&args.out, args.render)?;
    crate::note!(
        "done on {}: {} modes executed, valid {}, {}",
        result.hand,
        result.modes.len(),
        result.valid,
        match (result.final_yaw, result.final_distance_m) {
            (Some(y), _) => format!("final yaw {y:.3} rad"),
            (_, Some(d)) => format!("final distance to the goal {:.2} cm", 100.0 * d),
            _ => String::new(),
        }
    );
    Ok(())
}

/// Write the report of the episode in `dir` (its `result.json`): plots over time,
/// `report.html` and, when `animate`, the animation.
pub fn write_report(dir: &std::path::Path, animate: bool) -> anyhow::Result<()> {
    let rec = dips_report::Recording::read(&dir.join("result.json"))?;
    let bar = if animate {
        crate::render::progress_bar(rec.frames.len(), "animation", "frames")
    } else {
        indicatif::ProgressBar::hidden()
    };
    dips_report::write_episode_report(dir, &rec, animate, &mut |done, _| {
        bar.set_position(done as u64)
    })
    .with_context(|| format!("writing the report in {}", dir.display()))?;
    bar.finish_and_clear();
    crate::note!("report: {}", dir.join(dips_report::REPORT_HTML).display());
    Ok(())
}
