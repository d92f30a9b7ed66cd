//! `dips bench sim --json`: time of one action (all sub-steps) in each scene.

use clap::Args;

use crate::world::bench;

/// `dips bench sim` arguments.
#[derive(Debug, Args)]
pub struct BenchSimArgs {
    /// Print JSON (the only output format).
    #[arg(long)]
    pub json: bool,
    /// Actions timed per scenario.
    #[arg(long, default_value_t = 24)]
    pub actions: usize,
}

/// Run the benchmark and print its figures.
pub fn main(args: BenchSimArgs) -> anyhow::Result<()> {
    let report = bench::run(args.actions.max(1))?;
    let text = if args.json {
        serde_json::to_string(&report)?
    } else {
        serde_json::to_string_pretty(&report)?
    };
    println!("{text}");
    Ok(())
}
