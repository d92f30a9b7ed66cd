//! `dips bench sim --json`: time of one action (all sub-steps) in each scene.

use clap::{Args, ValueEnum};

use dips_host::world::bench::{self, ContactModel};

/// The contact model to time.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ContactModelArg {
    /// The world's defaults.
    Default,
    /// The model before issue 10 (friction cone on every candidate, step command), for
    /// comparison.
    PlainCone,
}

/// `dips bench sim` arguments.
#[derive(Debug, Args)]
pub struct BenchSimArgs {
    /// Print JSON instead of readable `key: value` lines.
    #[arg(long)]
    pub json: bool,
    /// Actions timed per scenario.
    #[arg(long, default_value_t = 24)]
    pub actions: usize,
    /// Contact model to time.
    #[arg(long, value_enum, default_value = "default")]
    pub contact_model: ContactModelArg,
}

/// Run the benchmark and print its figures.
pub fn main(args: BenchSimArgs) -> anyhow::Result<()> {
    let model = match args.contact_model {
        ContactModelArg::Default => ContactModel::Default,
        ContactModelArg::PlainCone => ContactModel::PlainCone,
    };
    let report = bench::run(args.actions.max(1), model)?;
    crate::output::figures(args.json, &serde_json::to_value(&report)?)?;
    Ok(())
}
