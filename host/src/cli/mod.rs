//! The `dips` command line (`CONTRACTS.md` §5). Each command group lives in its own module.

use clap::{Parser, Subcommand};

pub mod bench;
pub mod bench_inference;
pub mod model;

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
}

/// Parse the process arguments and run the command.
pub fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Model(args) => model::run(args),
        Command::Bench(args) => bench::run(args),
    }
}
