//! `dips bench ...`: benchmarks that print JSON figures.

use clap::{Args, Subcommand};

use super::bench_csvto;

/// `dips bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The benchmark to run.
    #[command(subcommand)]
    pub command: BenchCommand,
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Seconds per online CSVTO step (screwdriver turn, N = 16, 25 iterations, H = 12).
    Csvto(bench_csvto::CsvtoBenchArgs),
}

/// Run the command.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    match args.command {
        BenchCommand::Csvto(a) => bench_csvto::run(a),
    }
}
