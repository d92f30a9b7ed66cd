//! `dips eval`: the paper's experiments. Every method of a list runs the same trials (trial
//! `i` has seed `first_seed + i` for every method, so methods are compared on the same
//! starts), two episodes at a time on two cores, each episode's `result.json` kept for replay.
//!
//! - [`settings`]: what an evaluation is, and `eval.json`, which a resumed run must agree with.
//! - [`by_name`]: how its files write the domain values (task, methods, sampler, ...): by the
//!   names their own types spell.
//! - [`run`]: the episodes of one shard, resumable (finished episodes are files and are
//!   skipped; a kill loses only the episodes in flight), with a progress bar and ETA.
//! - [`merge`]: the shards' outputs (one shared directory or N) as one evaluation, every
//!   episode accounted for (`dips eval merge`).
//! - [`protocol`]: pre-registration (`dips eval --protocol FILE`): a committed protocol file
//!   names the settings, seeds and model hashes; a run that differs is refused, and its
//!   results are labelled registered, rerun, tuning or unregistered (`registration.json`).
//! - [`summary`]: `results.json`, the Markdown table and the box plots from whatever episodes
//!   are in the directory (all shards).
//! - [`report`]: `report.html` (summary, box plots, one section per method with its median
//!   trial's animation and plots over time) and every trial's own report.
//!
//! Layout of an evaluation directory:
//!
//! ```text
//! DIR/eval.json                              the settings (checked on resume)
//! DIR/registration.json                      the registration under a protocol, if any
//! DIR/episodes/<method>/seed-<seed>/result.json   one episode (dips episode's format)
//! DIR/episodes/<method>/seed-<seed>/log.txt       its progress lines
//! DIR/episodes/<method>/seed-<seed>/wall.json     its wall time
//! DIR/episodes/<method>/seed-<seed>/report.html, timeline.{svg,png}   its report
//! DIR/episodes/<method>/seed-<seed>/episode.gif   its animation (each method's median trial)
//! DIR/shards/shard-<I>-of-<N>.json              what each finished shard ran (host, wall time)
//! DIR/results.json, DIR/results.md, DIR/outcome.{svg,png}, DIR/planning.{svg,png}
//! DIR/report.html                            the page to open in a browser
//! ```

pub mod by_name;
pub mod merge;
pub mod protocol;
pub mod report;
pub mod run;
pub mod settings;
pub mod summary;

pub use run::{EvalReport, run_eval, run_eval_on};
pub use settings::{EpisodeSettings, EvalSettings};
pub use summary::{Summary, summarize};
