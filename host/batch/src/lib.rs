//! `dips-batch`: what the batch commands (`dips datagen`, `dips eval`) share when they run as a
//! job array on a cluster or as one process on a laptop.
//!
//! - [`shard`]: `--shard I/N` and `--shard auto` (Slurm's `SLURM_ARRAY_TASK_ID`/`_COUNT`, a
//!   Kubernetes Indexed Job's `JOB_COMPLETION_INDEX`), resolved once into a [`Shard`];
//! - [`diff`]: which setting differs between two runs, named;
//! - [`progress`]: a bar on a terminal, plain lines with done/total, rate and ETA in a log;
//! - [`record`]: `shards/shard-I-of-N.json`, what a finished shard leaves for the merge
//!   (written with `dips_fs::write_atomic`, unique across hosts sharing a directory);
//! - [`run`]: [`run_shard`], the one runner of a shard's pending items (resume note,
//!   progress, `jobs` workers on a pool, stop at the first failure, the record only when the
//!   shard is complete).
//!
//! See `docs/cluster.md`.

pub mod diff;
pub mod progress;
pub mod record;
pub mod run;
pub mod shard;

pub use diff::first_difference;
pub use progress::{Progress, ProgressMode};
pub use record::{BatchError, ShardRecord, read_records, shards_without_record, write_record};
pub use run::{RunShardError, ShardOutcome, ShardRun, run_shard};
pub use shard::{Shard, ShardEnvError, ShardError, ShardSpec};
