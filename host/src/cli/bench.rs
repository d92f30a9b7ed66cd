//! `dips bench`: benchmarks that print JSON figures.

use clap::{Args, Subcommand};

/// `dips bench` arguments.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Which benchmark.
    #[command(subcommand)]
    pub command: Bench,
}

/// Benchmarks.
#[derive(Debug, Subcommand)]
pub enum Bench {
    /// Time of one 1 s action (all sub-steps) in each scene of the quasi-static world.
    Sim(super::bench_sim::BenchSimArgs),
}

/// Run `dips bench`.
pub fn main(args: BenchArgs) -> anyhow::Result<()> {
    match args.command {
        Bench::Sim(a) => super::bench_sim::main(a),
    }
}
