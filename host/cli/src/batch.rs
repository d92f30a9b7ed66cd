//! What `dips eval` and `dips datagen` share as batch jobs: the shard resolved from `--shard`
//! (or the scheduler's environment) and the progress mode.

use dips_batch::{ProgressMode, Shard, ShardSpec};

use crate::output::note;

/// `--shard`'s parser: `I/N`, `auto` or `auto/N`, or the command line's words for what is
/// not ([`crate::words::shard`]).
pub fn parse_shard(s: &str) -> Result<ShardSpec, String> {
    s.parse().map_err(|e| crate::words::shard(&e))
}

/// The shard this process runs: `--shard I/N` as given, `auto` from the environment (the
/// variables read are named on stderr, so a job's log says which shard it was).
pub fn resolve_shard(spec: ShardSpec) -> anyhow::Result<Shard> {
    let resolved = spec.resolve_from_env()?;
    if matches!(spec, ShardSpec::Auto { .. }) {
        note(&format!(
            "shard {} (from {})",
            resolved.shard, resolved.source
        ));
    }
    Ok(resolved.shard)
}

/// `--quiet` hides progress; otherwise a bar on a terminal and log lines elsewhere.
pub fn progress_mode(quiet: bool) -> ProgressMode {
    if quiet {
        ProgressMode::Hidden
    } else {
        ProgressMode::Auto
    }
}
