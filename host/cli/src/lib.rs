//! The `dips` command line (`docs/contracts.md` §5). Each command group lives in its own module.

use clap::{Parser, Subcommand};
use dips_world::hand::HandKind;

use crate::hands::CliHands;

pub mod batch;
pub mod bench;
pub mod bench_csvto;
pub mod bench_firmware;
pub mod bench_inference;
pub mod bench_plan;
pub mod bench_sim;
pub mod datagen;
pub mod episode;
pub mod eval;
pub mod hand_cmd;
pub mod hands;
pub mod model;
pub mod model_quality;
pub mod output;
pub mod plan;
pub mod render;
pub mod search_args;
pub mod sim;
pub mod train;
pub mod words;

/// DIPS: diffusion-informed probabilistic contact search for multi-finger manipulation.
#[derive(Debug, Parser)]
#[command(name = "dips", version, about)]
pub struct Cli {
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// Top-level commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Validate, run and lower contract-v1 models.
    Model(model::ModelArgs),
    /// Benchmarks that print JSON figures.
    Bench(bench::BenchArgs),
    /// Quasi-static test world (or `--hand mujoco`): run actions, draw scenes and trajectories.
    Sim(sim::SimArgs),
    /// One closed-loop episode, executed on the quasi-static world or (`--hand mujoco`) the
    /// MuJoCo hand; writes DIR/result.json.
    Episode(episode::EpisodeArgs),
    /// Bring-up of the Allegro hand: info, live joints, a slow move home (a real bus or the
    /// emulated hand).
    Hand(hand_cmd::HandArgs),
    /// The paper's experiments: many episodes per method (resumable, sharded), then
    /// results.json, results.md and box plots.
    Eval(Box<eval::EvalArgs>),
    /// Pictures of an episode (`result.json`) or a `dips sim run` trajectory: a GIF
    /// animation, or one state as SVG/PNG.
    Render(render::RenderArgs),
    /// One A* planning call from the task's start state with the diffusion models.
    Plan(plan::PlanArgs),
    /// Generate a dataset: CSVTO demos driven by the task's prior (resumable, sharded).
    Datagen(datagen::DatagenArgs),
    /// Train the denoiser and the discriminator on a dataset; export them as ONNX.
    Train(train::TrainArgs),
}

impl Command {
    /// The hand the command executes on (`--hand`), for the commands that take one.
    pub fn hand(&self) -> Option<HandKind> {
        match self {
            Command::Episode(a) => Some(a.hand.kind()),
            Command::Hand(a) => Some(HandKind::Allegro(Box::new(a.options().ok()?))),
            // Without `--hand`, a protocol's hand (an unreadable protocol fails later, with
            // its own message).
            Command::Eval(a) => a.hand.hand.clone().or_else(|| {
                let file = a.protocol.as_deref()?;
                let p = dips_eval::protocol::ProtocolFile::read(file).ok()?;
                Some(p.protocol.eval.episode.hand)
            }),
            Command::Sim(a) => match &a.command {
                sim::SimCommand::Run(r) => Some(r.hand.clone()),
                sim::SimCommand::Render(_) => None,
            },
            Command::Bench(a) => match &a.command {
                bench::BenchCommand::Sim(b) => Some(b.hand.clone()),
                _ => None,
            },
            _ => None,
        }
    }
}

/// Parse the process arguments and run the command with our world and the Allegro driver
/// (its emulated hand on the joint model, [`hands::DipsHands`]); a command for another hand
/// (`--hand mujoco`) runs in the `dips-mujoco` binary instead ([`hands::delegate`]).
pub fn main() -> anyhow::Result<()> {
    main_with(&hands::DipsHands)
}

/// Parse the process arguments and run the command, opening the hands that execute actions
/// with `hands` (`dips-mujoco` registers the MuJoCo hand here). A hand `hands` lacks is
/// delegated to the binary that has it.
pub fn main_with(hands: &dyn CliHands) -> anyhow::Result<()> {
    let cli = Cli::parse();
    if let Some(kind) = cli.command.hand().filter(|k| !hands.has(k)) {
        return hands::delegate(kind);
    }
    match cli.command {
        Command::Model(args) => model::run(args),
        Command::Bench(args) => bench::run(args, hands),
        Command::Sim(args) => sim::main(args, hands),
        Command::Episode(args) => episode::run(args, hands),
        Command::Eval(args) => eval::run(*args, hands),
        Command::Hand(args) => hand_cmd::run(args, hands),
        Command::Plan(args) => plan::run(args),
        Command::Render(args) => render::run(args),
        Command::Datagen(args) => datagen::run(args),
        Command::Train(args) => train::run(args),
    }
}
