//! `dips-mujoco`: run a commands file on the MuJoCo hand or our world (`sim run`), and time
//! one action on both (`bench`). See docs/mujoco.md.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
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
