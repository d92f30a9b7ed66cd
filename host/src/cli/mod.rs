//! The `dips` command line (`CONTRACTS.md` §5). Each command group lives in its own module.

use clap::{Parser, Subcommand};

pub mod bench;
pub mod bench_csvto;
pub mod episode;

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
    /// One closed-loop episode in the quasi-static world; writes DIR/result.json.
    Episode(episode::EpisodeArgs),
    /// Benchmarks that print JSON figures.
    Bench(bench::BenchArgs),
}

/// Parse the process arguments and run the command.
pub fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Episode(args) => episode::run(args),
        Command::Bench(args) => bench::run(args),
    }
}
