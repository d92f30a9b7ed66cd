//! `dips eval`: the paper's experiments (`dips_eval`): many episodes per method on all cores,
//! resumable and sharded, then `results.json`, `results.md` and the box plots.

use dips_onnx::EngineKind;
use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use dips_link::KernelTarget;

use dips_batch::ShardSpec;
use dips_eval::protocol::{Protocol, ProtocolFile, RegistrationStatus};
use dips_eval::{EvalSettings, run_eval_on, summarize};
use dips_planning::models_dir;
use dips_planning::online::{Method, OnlineSettings};
use dips_world::hand::Hands;
use dips_world::scenes::SceneKind;

use crate::search_args::named;

/// Arguments of `dips eval`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct EvalArgs {
    /// `merge`: the outputs of a job array's shards as one evaluation.
    #[command(subcommand)]
    pub command: Option<EvalCommand>,
    /// Task: `screwdriver` or `card` (with `--protocol`, default: the protocol's).
    #[arg(
        long,
        required_unless_present_any = ["summarize_only", "protocol"],
        value_parser = named::<SceneKind>()
    )]
    pub task: Option<SceneKind>,
    /// Comma-separated methods (default: the protocol's, else every method, in the paper's
    /// order): dips, dips-sampled, csvto-sampled, dips-no-replan, dips-k1,
    /// dips-max-likelihood, diffusion-policy.
    #[arg(long, value_delimiter = ',', value_parser = named::<Method>())]
    pub methods: Option<Vec<Method>>,
    /// Trials per method (default: the protocol's, else 10); trial `i` has seed
    /// `--first-seed + i` for every method. With `--summarize-only`, the trials expected in
    /// `--out`.
    #[arg(long, value_parser = crate::search_args::parse_positive)]
    pub trials: Option<usize>,
    /// Seed of trial 0 (default: the protocol's, else 1000, above every seed the shipped
    /// models were trained on: demos below 140). Seeds below 1000 are for tuning, and every
    /// evaluation takes a fresh registered range (`docs/results/PROTOCOL.md`).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_parser = crate::search_args::parse_seed
    )]
    pub first_seed: Option<u64>,
    /// Output directory (resumed when it holds an evaluation of the same settings).
    #[arg(long, required_unless_present = "write_protocol")]
    pub out: Option<PathBuf>,
    /// Run under the protocol FILE (`docs/results/PROTOCOL.md`): refused unless FILE is
    /// committed and this run's task, methods, seeds, settings and model hashes are its
    /// (flags not given are taken from it: task, methods, trials, first seed); the results
    /// get a `registration` block (registered, rerun, tuning or unregistered).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["summarize_only", "write_protocol"])]
    pub protocol: Option<PathBuf>,
    /// With `--protocol`: run even when FILE is not committed as it is; the results are
    /// labelled unregistered (tests and tuning only).
    #[arg(long, requires = "protocol")]
    pub protocol_uncommitted: bool,
    /// Write the protocol of these flags (settings resolved, models hashed) to FILE and run
    /// nothing; needs `--task` and `--first-seed`. Commit FILE, then run with `--protocol FILE`.
    #[arg(long, value_name = "FILE", conflicts_with = "summarize_only")]
    pub write_protocol: Option<PathBuf>,
    /// The name of the protocol `--write-protocol` writes (default: FILE's name without
    /// `.json`).
    #[arg(long, requires = "write_protocol")]
    pub protocol_name: Option<String>,
    /// Episodes run at once (default: the number of cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Threads of each model call inside an episode (default: the cores divided by
    /// `--jobs`, at least 1).
    #[arg(long)]
    pub model_threads: Option<usize>,
    /// Run only shard I of N (method × trial, in order), e.g. `--shard 0/4`; `auto` takes it
    /// from a Slurm array (`SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_COUNT`), `auto/N` the
    /// index from Slurm or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`) and N given.
    /// Shards may share `--out`; `dips eval merge` checks that every episode is there.
    #[arg(long, default_value = "0/1", value_parser = crate::batch::parse_shard)]
    pub shard: ShardSpec,
    /// Models directory (default: the shipped models, `onnx/models/<task>`).
    #[arg(long)]
    pub models: Option<PathBuf>,
    /// Engine that runs the models.
    #[arg(long, value_parser = crate::search_args::named::<EngineKind>(), default_value = "kernel")]
    pub engine: EngineKind,
    /// The search's flags.
    #[command(flatten)]
    pub search: crate::search_args::SearchArgs,
    /// The card's goals.
    #[command(flatten)]
    pub card_goals: crate::search_args::CardGoalsArgs,
    /// The CSVTO settings that execute the modes.
    #[command(flatten)]
    pub exec_profile: crate::search_args::ExecProfileArgs,
    /// Where the planning calls are made: `in-process`, `spawn` (a `dips-firmware-sim` child
    /// per episode), `spawn:PATH` or `tcp://HOST:PORT` (with `--jobs 1`). The results are the
    /// same bit for bit.
    #[arg(long, default_value = "in-process", value_parser = KernelTarget::parse)]
    pub kernel: KernelTarget,
    /// The episode's search depth flag.
    #[command(flatten)]
    pub online: crate::search_args::OnlineArgs,
    /// Stop each episode after this many modes (default: the task's 7 / 5).
    #[arg(long)]
    pub max_modes: Option<usize>,
    /// Only write the summary of the episodes already in `--out`.
    #[arg(long)]
    pub summarize_only: bool,
    /// No progress (a bar on a terminal, a line at most every 30 s in a log).
    #[arg(long)]
    pub quiet: bool,
    /// Methods whose median trial is animated in `report.html` (comma-separated; default:
    /// every method; `none`: no animation).
    #[arg(long, value_delimiter = ',')]
    pub animate: Option<Vec<String>>,
    /// Which trials get their own report beside their `result.json`: `all`, or `medians`
    /// (each method's median trial; a small report to publish).
    #[arg(long, default_value = "all", value_parser = ["all", "medians"])]
    pub episode_reports: String,
    /// The hand that executes the episodes (default: the protocol's, else our world), and
    /// its tracker noise; recorded in `eval.json`.
    #[command(flatten)]
    pub hand: crate::hands::HandArgs,
}

/// `dips eval` subcommands.
#[derive(Debug, Subcommand)]
pub enum EvalCommand {
    /// Merge the outputs of a job array's shards into one evaluation (`results.json`, the
    /// table, the plots, `report.html`): from SOURCES (one directory per shard) into --out, or,
    /// with no SOURCES, the shards that shared --out. The settings must agree and every
    /// episode must be there; a missing one is named with its shard.
    Merge {
        /// The merged evaluation's directory (may be one of SOURCES).
        #[arg(long)]
        out: PathBuf,
        /// The shards' evaluation directories.
        sources: Vec<PathBuf>,
        /// Summarise what is there when episodes are missing (they are listed).
        #[arg(long)]
        allow_missing: bool,
        /// Which trials get their own report: `all`, or `medians`.
        #[arg(long, default_value = "all", value_parser = ["all", "medians"])]
        episode_reports: String,
        /// Methods whose median trial is animated (comma-separated; default every method;
        /// `none`).
        #[arg(long, value_delimiter = ',')]
        animate: Option<Vec<String>>,
        /// No progress.
        #[arg(long)]
        quiet: bool,
    },
}

/// What the report of an evaluation is made with.
struct ReportArgs<'a> {
    out: &'a std::path::Path,
    animate: &'a Option<Vec<String>>,
    episode_reports: &'a str,
    quiet: bool,
}

fn merge(command: &EvalCommand) -> anyhow::Result<()> {
    let EvalCommand::Merge {
        out,
        sources,
        allow_missing,
        episode_reports,
        animate,
        quiet,
    } = command;
    let report = dips_eval::merge::merge(out, sources, *allow_missing)?;
    crate::output::note(&format!(
        "merged into {}: {} episodes copied, {} already there, {} shard records{}",
        out.display(),
        report.copied,
        report.already_there,
        report.shards,
        if report.missing.is_empty() {
            String::new()
        } else {
            format!(
                "; {} missing (--allow-missing): {}",
                report.missing.len(),
                report.missing.join(", ")
            )
        }
    ));
    let s = summarize(out)?;
    write_report(
        &ReportArgs {
            out,
            animate,
            episode_reports,
            quiet: *quiet,
        },
        &s,
    )?;
    crate::output::line(dips_eval::summary::markdown(&s).trim_end_matches('\n'))?;
    Ok(())
}

/// Run the command.
pub fn run(args: EvalArgs, hands: &dyn Hands) -> anyhow::Result<()> {
    if let Some(command) = &args.command {
        return merge(command);
    }
    if args.summarize_only {
        let out = args.out.clone().context("--out DIR is required")?;
        let report_args = ReportArgs {
            out: &out,
            animate: &args.animate,
            episode_reports: &args.episode_reports,
            quiet: args.quiet,
        };
        let s = summarize(&out)?;
        for missing in dips_eval::summary::shortfall(&s, args.trials) {
            crate::output::note(&crate::words::shortfall(&missing));
        }
        write_report(&report_args, &s)?;
        crate::output::line(dips_eval::summary::markdown(&s).trim_end_matches('\n'))?;
        return Ok(());
    }
    let protocol = args
        .protocol
        .as_deref()
        .map(ProtocolFile::read)
        .transpose()?;
    let given = protocol.as_ref().map(|p| &p.protocol.eval);
    let task: SceneKind = match (args.task, given) {
        (Some(task), _) => task,
        (None, Some(e)) => e.episode.task,
        (None, None) => anyhow::bail!("--task is required"),
    };
    let methods = match (&args.methods, given) {
        (Some(methods), _) => methods.clone(),
        (None, Some(e)) => e.methods.clone(),
        (None, None) => Method::ALL.to_vec(),
    };
    if args.write_protocol.is_some() && args.first_seed.is_none() {
        anyhow::bail!(
            "--write-protocol needs --first-seed: a protocol names its seed range (the next \
             free one is in docs/results/PROTOCOL.md)"
        );
    }
    if let Some(list) = &args.animate {
        // Checked before the episodes run, not after.
        let names: Vec<&str> = methods.iter().map(|m| m.name()).collect();
        if let Some(bad) = list
            .iter()
            .find(|m| *m != "none" && !names.contains(&m.as_str()))
        {
            anyhow::bail!(
                "--animate {bad}: not a method of this evaluation (its methods: {}; or none)",
                names.join(", ")
            );
        }
    }
    let cores = dips_planning::default_threads();
    // One Allegro hand takes one episode at a time: a real bus has one hand on it, and an
    // emulated hand runs in real time on a core of its own.
    let one_hand = args
        .hand
        .hand
        .as_ref()
        .is_some_and(|h| h.allegro().is_some());
    if one_hand && args.jobs.is_some_and(|j| j > 1) {
        anyhow::bail!(
            "--jobs {}: an Allegro hand runs one episode at a time (--jobs 1)",
            args.jobs.unwrap_or(1)
        );
    }
    let jobs = if one_hand {
        1
    } else {
        args.jobs.unwrap_or(cores)
    };
    let model_threads = match args.model_threads {
        Some(0) => anyhow::bail!("--model-threads must be at least 1"),
        Some(n) => n,
        None => (cores / jobs.max(1)).max(1),
    };
    let mut settings = EvalSettings {
        task,
        methods,
        trials: args.trials.or(given.map(|e| e.trials)).unwrap_or(10),
        first_seed: args
            .first_seed
            .or(given.map(|e| e.first_seed))
            .unwrap_or(1000),
        shard: crate::batch::resolve_shard(args.shard)?,
        jobs,
        model_threads,
        online: OnlineSettings {
            time_budget_s: args.search.time_budget_s()?,
            search: args.search.overrides(),
            sampler: args.search.sampler,
            sequence: None,
            max_modes: args.max_modes,
            search_depth: args.online.search_depth,
            stop_rule: args.online.stop_rule,
            first_mode: args.online.first_mode,
            planner_size: args.online.planner_size,
        },
        models: models_dir(args.models.as_deref(), task.task())?,
        engine: args.engine,
        progress: crate::batch::progress_mode(args.quiet),
        stop_after: None,
        kernel: args.kernel.clone(),
        hand: args
            .hand
            .hand
            .clone()
            .or(given.map(|e| e.episode.hand.clone()))
            .unwrap_or_default(),
        tracker_noise: match (&args.hand.noise_position, &args.hand.noise_rotation, given) {
            (None, None, Some(e)) => e.episode.tracker_noise,
            _ => args.hand.noise()?,
        },
        registration: None,
        card_goals: Default::default(),
        exec_profile: args
            .exec_profile
            .exec_profile
            .or(given.map(|e| e.episode.exec_profile))
            .unwrap_or_default(),
        pose_estimate: args
            .exec_profile
            .pose_estimate
            .or(given.map(|e| e.episode.pose_estimate))
            .unwrap_or_default(),
        regrasp_guard: args
            .exec_profile
            .regrasp_guard
            .or(given.map(|e| e.episode.regrasp_guard))
            .unwrap_or_default(),
        press: args
            .exec_profile
            .press
            .or(given.map(|e| e.episode.press))
            .unwrap_or_default(),
    };
    settings.card_goals = args.card_goals.resolve(
        task.task(),
        given.map(|e| e.episode.card_goals),
        Some((
            settings.models.as_path(),
            dips_planning::models_card_goals(&settings.models)?.unwrap_or_default(),
        )),
    )?;
    if let Some(file) = &args.write_protocol {
        return write_protocol(file, args.protocol_name.as_deref(), &settings);
    }
    if let Some(p) = &protocol {
        let out = args.out.as_deref().context("--out DIR is required")?;
        let registration = p.register_in(&settings, args.protocol_uncommitted, out)?;
        crate::note!(
            "protocol {} ({}): this run is labelled {}{}",
            p.protocol.name,
            p.path.display(),
            registration.status.name(),
            match registration.status {
                RegistrationStatus::Registered => String::new(),
                RegistrationStatus::Rerun => format!(
                    " (the range is spent: {}); it never replaces the registered result",
                    registration.spent_by.join(", ")
                ),
                RegistrationStatus::Tuning => " (seeds below 1000)".into(),
                RegistrationStatus::Unregistered => " (the protocol is not committed)".into(),
            }
        );
        settings.registration = Some(registration);
    }
    let out = args.out.clone().context("--out DIR is required")?;
    let report_args = ReportArgs {
        out: &out,
        animate: &args.animate,
        episode_reports: &args.episode_reports,
        quiet: args.quiet,
    };
    let report = run_eval_on(&settings, &out, hands)?;
    let episodes = |n: usize| if n == 1 { "episode" } else { "episodes" };
    crate::output::note(&format!(
        "eval {}: {} {} run ({} with errors), {} already done, {:.0} s",
        task.name(),
        report.ran,
        episodes(report.ran),
        report.errors,
        report.skipped,
        report.seconds
    ));
    let s = summarize(&out)?;
    write_report(&report_args, &s)?;
    crate::output::line(dips_eval::summary::markdown(&s).trim_end_matches('\n'))?;
    crate::note!(
        "wrote {} and {}",
        out.join("results.json").display(),
        out.join(dips_report::REPORT_HTML).display()
    );
    Ok(())
}

/// `--write-protocol FILE`: the protocol of `settings`, written and named; nothing runs.
fn write_protocol(
    file: &std::path::Path,
    name: Option<&str>,
    settings: &EvalSettings,
) -> anyhow::Result<()> {
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    settings.validate()?;
    let protocol = Protocol::new(name.unwrap_or(&stem), settings)?;
    protocol.write(file)?;
    if protocol.tuning() {
        crate::note!(
            "seeds {}…: below 1000, so runs of this protocol are tuning, never registered",
            settings.first_seed
        );
    }
    crate::note!(
        "wrote the protocol {} to {} ({} model files hashed); commit it, then run \
         `dips eval --protocol {} --out DIR`",
        protocol.name,
        file.display(),
        protocol.models.len(),
        file.display()
    );
    Ok(())
}

fn write_report(args: &ReportArgs<'_>, s: &dips_eval::Summary) -> anyhow::Result<()> {
    use dips_eval::report::{EpisodeReports, ReportOptions};
    let methods: Vec<Method> = s.methods.iter().map(|m| m.method).collect();
    let animate = match &args.animate {
        None => methods.clone(),
        Some(list) if list.len() == 1 && list[0] == "none" => Vec::new(),
        Some(list) => list
            .iter()
            .map(|m| match methods.iter().find(|ours| ours.name() == m) {
                Some(&ours) => Ok(ours),
                None => Err(anyhow::anyhow!(
                    "--animate {m}: not a method of this evaluation (its methods: {}; or none)",
                    methods
                        .iter()
                        .map(|m| m.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                )),
            })
            .collect::<anyhow::Result<_>>()?,
    };
    let options = ReportOptions {
        episodes: if args.episode_reports == "medians" {
            EpisodeReports::Medians
        } else {
            EpisodeReports::All
        },
        animate,
    };
    let finished = s.trials.iter().filter(|t| t.error.is_none()).count();
    let bar = crate::render::progress_bar(finished, "report", "episodes");
    if args.quiet {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    dips_eval::report::write_report(args.out, s, &options, &mut |done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
    Ok(())
}
