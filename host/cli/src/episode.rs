//! `dips episode`: one closed-loop episode in the quasi-static world (`CONTRACTS.md` §5).

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;

use dips_host::execute::{ExecSettings, prior_sequence_for_seed, run_episode};
use dips_host::problems::Mode;
use dips_host::problems::mode::parse_mode;
use dips_host::scenes::SceneKind;

/// Arguments of `dips episode`.
#[derive(Debug, Args)]
pub struct EpisodeArgs {
    /// Task: `screwdriver` or `card`.
    #[arg(long)]
    pub task: String,
    /// Method: `csvto-sampled` (the others come with the search).
    #[arg(long)]
    pub method: String,
    /// Seed of the contact-sequence draw and the CSVTO initialisation.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Execute this comma-separated mode sequence instead of the method's own.
    #[arg(long, value_delimiter = ',')]
    pub modes: Option<Vec<String>>,
    /// Output directory; `result.json` is written there.
    #[arg(long)]
    pub out: PathBuf,
}

/// Methods of CONTRACTS §5 that need the diffusion search, not available in this command yet.
const SEARCH_METHODS: [&str; 6] = [
    "dips",
    "dips-sampled",
    "dips-no-replan",
    "dips-k1",
    "dips-max-likelihood",
    "diffusion-policy",
];

/// Run the command.
pub fn run(args: EpisodeArgs) -> anyhow::Result<()> {
    let task = SceneKind::from_name(&args.task).with_context(|| {
        format!(
            "unknown task `{}` (expected screwdriver or card)",
            args.task
        )
    })?;
    if args.method != "csvto-sampled" {
        if SEARCH_METHODS.contains(&args.method.as_str()) {
            bail!(
                "method `{}` needs the diffusion models and the contact search, which `dips \
                 episode` does not run yet; available: csvto-sampled",
                args.method
            );
        }
        bail!("unknown method `{}`; available: csvto-sampled", args.method);
    }
    let modes: Vec<Mode> = match &args.modes {
        Some(names) => names
            .iter()
            .map(|n| parse_mode(task, n.trim()))
            .collect::<Result<_, _>>()?,
        None => prior_sequence_for_seed(task, args.seed),
    };
    let settings = ExecSettings::for_task(task);
    let mut progress = |line: &str| eprintln!("{line}");
    let result = run_episode(
        task,
        &args.method,
        args.seed,
        &modes,
        &settings,
        &mut progress,
    )?;
    result
        .write(&args.out)
        .with_context(|| format!("writing {}", args.out.join("result.json").display()))?;
    eprintln!(
        "done: valid {}, {}",
        result.valid,
        match (result.final_yaw, result.final_distance_m) {
            (Some(y), _) => format!("final yaw {y:.3} rad"),
            (_, Some(d)) => format!("final distance {:.3} m", d),
            _ => String::new(),
        }
    );
    Ok(())
}
