//! `dips-mujoco`: run a commands file on the MuJoCo hand or our world (`sim run`), and time
//! one action on both (`bench`). See docs/mujoco.md.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use dips_host::online::Method;
use dips_mujoco::run::{self, AnyHand, HandKind};
use dips_mujoco::{PoseNoise, check_version};
use dips_world::scenes::SceneKind;

#[derive(Debug, Parser)]
#[command(
    name = "dips-mujoco",
    about = "The MuJoCo hand (issue 37): run and time actions"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The hand on its own.
    Sim {
        #[command(subcommand)]
        command: SimCommand,
    },
    /// Execute CSVTO contact modes closed-loop on a hand (what `dips episode --method
    /// csvto-sampled` does per mode, the controller seeing only `Hand`); JSON on stdout.
    Modes {
        /// `screwdriver` or `card`.
        #[arg(long)]
        task: String,
        /// Comma-separated mode names, e.g. `turn` or `index,middle,both`.
        #[arg(long)]
        modes: String,
        /// Which hand executes the actions.
        #[arg(long, value_enum, default_value = "mujoco")]
        hand: HandKind,
        /// Seed of CSVTO's particles.
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
    /// One DIPS episode (`dips episode`'s planner, models and CSVTO) executed on a hand;
    /// writes DIR/result.json (with `hand`) and DIR/report.html.
    Episode {
        #[command(flatten)]
        args: EpisodeArgs,
        /// Seed of the episode.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Also write the episode's animation (`episode.gif`).
        #[arg(long)]
        render: bool,
    },
    /// Episodes of methods × seeds on a hand, one after the other, resumable
    /// (DIR/episodes/<method>/seed-<seed>/, as `dips eval`); DIR/summary.json at the end.
    Eval {
        #[command(flatten)]
        args: EpisodeArgs,
        /// Comma-separated methods, e.g. `dips,dips-sampled`.
        #[arg(long, value_delimiter = ',')]
        methods: Vec<String>,
        /// Seeds `FIRST..END` (END excluded) or a comma-separated list.
        #[arg(long)]
        seeds: String,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// Time one 1 s action on both hands (same targets, planned in our world); JSON on stdout.
    Bench {
        /// Actions timed per scene, scenario and hand (in runs of six from the start state).
        #[arg(long, default_value_t = 24)]
        actions: usize,
    },
}

#[derive(Debug, Subcommand)]
enum SimCommand {
    /// Run rows of joint deltas (the `dips sim run` commands file, `{"dq": [[...], ...]}`) and
    /// write the measured trajectory (`dips sim render --trajectory` draws it).
    Run {
        /// `screwdriver` or `card`.
        #[arg(long)]
        scene: String,
        /// The commands file.
        #[arg(long)]
        commands: PathBuf,
        /// The trajectory file to write.
        #[arg(long)]
        out: PathBuf,
        /// Which hand executes the actions.
        #[arg(long, value_enum, default_value = "mujoco")]
        hand: HandKind,
        /// Tracker noise: position σ (m) of the reported object pose (MuJoCo hand).
        #[arg(long, default_value_t = 0.0)]
        noise_position: f64,
        /// Tracker noise: rotation σ (rad per axis) of the reported object pose (MuJoCo hand).
        #[arg(long, default_value_t = 0.0)]
        noise_rotation: f64,
        /// Seed of the tracker noise.
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
}

/// The flags of `episode` and `eval`: `dips episode`'s, and the hand.
#[derive(Debug, clap::Args)]
struct EpisodeArgs {
    /// `screwdriver` or `card`.
    #[arg(long)]
    task: String,
    /// Method: dips, dips-sampled, csvto-sampled, dips-no-replan, dips-k1,
    /// dips-max-likelihood, diffusion-policy (for `episode`; `eval` takes `--methods`).
    #[arg(long, default_value = "dips")]
    method: String,
    /// Which hand executes the actions.
    #[arg(long, value_enum, default_value = "mujoco")]
    hand: HandKind,
    /// Tracker noise: position σ (m) of the reported object pose (MuJoCo hand).
    #[arg(long, default_value_t = 0.0)]
    noise_position: f64,
    /// Tracker noise: rotation σ (rad per axis) of the reported object pose (MuJoCo hand).
    #[arg(long, default_value_t = 0.0)]
    noise_rotation: f64,
    /// Models folder (default: the shipped models, `onnx/models/<task>`).
    #[arg(long)]
    models: Option<PathBuf>,
    /// Diffusion sampler (`dips episode --sampler`): `ddpm`, `ddpm:STEPS`, `ddim:STEPS[:ETA]`.
    #[arg(long, default_value = "ddpm:16")]
    sampler: String,
    /// Wall-clock budget of each planning call (s; 0: none).
    #[arg(long, default_value_t = 300.0)]
    time_budget_s: f64,
    /// Most node expansions per planning call (0: the planner's capacity; default: the task's).
    #[arg(long)]
    node_budget: Option<u32>,
    /// Stop after this many modes (default: the task's 7 / 5).
    #[arg(long)]
    max_modes: Option<usize>,
    /// Execute this comma-separated mode sequence (dips-sampled, csvto-sampled).
    #[arg(long, value_delimiter = ',')]
    modes: Option<Vec<String>>,
    /// Threads of each model call (default: every core).
    #[arg(long)]
    threads: Option<usize>,
}

impl EpisodeArgs {
    fn spec(
        &self,
        seed: u64,
    ) -> Result<dips_mujoco::episode::EpisodeSpec, Box<dyn std::error::Error>> {
        let task = SceneKind::from_name(&self.task)
            .ok_or_else(|| format!("unknown task {:?} (screwdriver or card)", self.task))?;
        if self.max_modes == Some(0) || self.threads == Some(0) {
            return Err("--max-modes and --threads must be at least 1".into());
        }
        let sequence = match &self.modes {
            Some(names) => Some(
                names
                    .iter()
                    .map(|n| dips_host::problems::mode::parse_mode(task, n.trim()))
                    .collect::<Result<Vec<_>, _>>()?,
            ),
            None => None,
        };
        let online = dips_host::online::OnlineSettings {
            time_budget_s: dips_host::online::check_time_budget_s(self.time_budget_s)?,
            node_budget: self.node_budget,
            sampler: dips_host::planning::parse_sampler(&self.sampler)?,
            sequence,
            max_modes: self.max_modes,
            cost_to_come: None,
            search_depth: None,
        };
        let noise =
            (self.noise_position != 0.0 || self.noise_rotation != 0.0).then_some(PoseNoise {
                position: self.noise_position,
                rotation: self.noise_rotation,
                seed,
            });
        Ok(dips_mujoco::episode::EpisodeSpec {
            task,
            method: Method::from_name(&self.method)?,
            seed,
            hand: self.hand,
            noise,
            models: self.models.clone(),
            threads: self
                .threads
                .unwrap_or_else(dips_host::planning::default_threads),
            online,
        })
    }
}

/// `--seeds`: `FIRST..END` or `A,B,C`.
fn parse_seeds(s: &str) -> Result<Vec<u64>, Box<dyn std::error::Error>> {
    let seeds: Vec<u64> = match s.split_once("..") {
        Some((a, b)) => (a.trim().parse()?..b.trim().parse()?).collect(),
        None => s
            .split(',')
            .map(|x| x.trim().parse())
            .collect::<Result<_, _>>()?,
    };
    if seeds.is_empty() {
        return Err(format!("--seeds {s}: no seed").into());
    }
    Ok(seeds)
}

fn episode(
    args: &EpisodeArgs,
    seed: u64,
    out: &Path,
    render: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let spec = args.spec(seed)?;
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let result = dips_mujoco::episode::run_episode(&spec, &mut |line| eprintln!("{line}"))?;
    dips_mujoco::episode::write_episode(out, &result, render)?;
    println!(
        "{}",
        serde_json::json!({
            "task": result.task,
            "method": result.method,
            "hand": result.hand,
            "seed": result.seed,
            "modes": result.modes,
            "final_yaw": result.final_yaw,
            "final_distance_m": result.final_distance_m,
            "final_dy_m": result.final_dy_m,
            "valid": result.valid,
            "success": result.success,
            "result": out.join("result.json"),
        })
    );
    Ok(())
}

fn eval(
    args: &EpisodeArgs,
    methods: &[String],
    seeds: &str,
    out: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let seeds = parse_seeds(seeds)?;
    let methods: Vec<Method> = methods
        .iter()
        .map(|m| Method::from_name(m.trim()))
        .collect::<Result<_, _>>()?;
    if methods.is_empty() {
        return Err("--methods: no method".into());
    }
    let base = args.spec(seeds[0])?;
    let noise = base.noise;
    // Each episode's tracker noise is seeded with its own seed (run_eval copies the base spec
    // and sets method and seed; the noise seed follows here).
    let summary = if noise.is_some() {
        let mut all = Vec::new();
        for &seed in &seeds {
            let spec = args.spec(seed)?;
            all.extend(dips_mujoco::episode::run_eval(
                &spec,
                &methods,
                &[seed],
                out,
                &mut |l| eprintln!("{l}"),
            )?);
        }
        all
    } else {
        dips_mujoco::episode::run_eval(&base, &methods, &seeds, out, &mut |l| eprintln!("{l}"))?
    };
    let text = serde_json::to_string_pretty(&serde_json::json!({
        "task": base.task.name(),
        "hand": base.hand.name(),
        "episodes": summary,
    }))?;
    std::fs::write(out.join("summary.json"), text + "\n")
        .map_err(|e| format!("{}: {e}", out.join("summary.json").display()))?;
    println!("{}", out.join("summary.json").display());
    Ok(())
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Commands {
    dq: Vec<Vec<f64>>,
}

fn sim_run(
    scene: &str,
    commands: &PathBuf,
    out: &PathBuf,
    hand: HandKind,
    noise: Option<PoseNoise>,
) -> Result<(), Box<dyn std::error::Error>> {
    let scene = SceneKind::from_name(scene)
        .ok_or_else(|| format!("unknown scene {scene:?} (screwdriver or card)"))?;
    let text =
        std::fs::read_to_string(commands).map_err(|e| format!("{}: {e}", commands.display()))?;
    let cmds: Commands =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", commands.display()))?;
    for (k, row) in cmds.dq.iter().enumerate() {
        if row.len() != scene.action_dim() {
            return Err(format!(
                "{}: row {k} has {} numbers but the {} task needs {}",
                commands.display(),
                row.len(),
                scene.name(),
                scene.action_dim()
            )
            .into());
        }
    }
    let mut h = AnyHand::new(hand, scene, noise)?;
    let traj = run::run_commands(&mut h, hand, &cmds.dq);
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(out, serde_json::to_string(&traj)? + "\n")
        .map_err(|e| format!("{}: {e}", out.display()))?;
    println!(
        "{}",
        serde_json::json!({
            "scene": scene.name(),
            "hand": hand.name(),
            "actions": traj.action_seconds.len(),
            "final_state": traj.states.last(),
            "valid": traj.valid.last(),
            "metric": traj.metric.last(),
            "mean_action_s": traj.action_seconds.iter().sum::<f64>() / traj.action_seconds.len().max(1) as f64,
        })
    );
    match traj.error {
        Some(e) => Err(e.into()),
        None => Ok(()),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Every path below builds a MuJoCo model; say what is wrong before mujoco-rs would panic.
    if let Err(e) = check_version() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Sim {
            command:
                SimCommand::Run {
                    scene,
                    commands,
                    out,
                    hand,
                    noise_position,
                    noise_rotation,
                    seed,
                },
        } => {
            let noise = (noise_position != 0.0 || noise_rotation != 0.0).then_some(PoseNoise {
                position: noise_position,
                rotation: noise_rotation,
                seed,
            });
            sim_run(&scene, &commands, &out, hand, noise)
        }
        Command::Modes {
            task,
            modes,
            hand,
            seed,
        } => SceneKind::from_name(&task)
            .ok_or_else(|| format!("unknown task {task:?} (screwdriver or card)").into())
            .and_then(|scene| {
                let names: Vec<String> = modes.split(',').map(|m| m.trim().to_string()).collect();
                let figures = run::run_csvto_modes(hand, scene, &names, seed, &mut |line| {
                    eprintln!("{line}")
                })?;
                println!(
                    "{}",
                    serde_json::to_string_pretty(&serde_json::json!({
                        "task": scene.name(),
                        "hand": hand.name(),
                        "seed": seed,
                        "modes": figures,
                    }))?
                );
                Ok(())
            }),
        Command::Episode {
            args,
            seed,
            out,
            render,
        } => episode(&args, seed, &out, render),
        Command::Eval {
            args,
            methods,
            seeds,
            out,
        } => eval(&args, &methods, &seeds, &out),
        Command::Bench { actions } => run::bench(actions).and_then(|t| {
            println!(
                "{}",
                serde_json::to_string_pretty(&serde_json::json!({
                    "bench": "mujoco-vs-world",
                    "actions": actions,
                    "scenarios": t,
                }))?
            );
            Ok(())
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
