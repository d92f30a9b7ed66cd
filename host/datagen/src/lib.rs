//! `dips-datagen`: the offline data of DIPS. Episodes whose contact-mode sequences come from
//! the task's prior are executed closed-loop by CSVTO in the quasi-static world, and every
//! online step's particles are recorded as training trajectories (`dips datagen`).
//!
//! - [`record`]: one demo — an episode and its trajectories ([`record::record_demo`]);
//! - [`settings_file`]: `datagen.json`, the batches a directory was asked for (checked on
//!   resume and by shards sharing the directory);
//! - [`run`]: many demos on all cores, resumable, with progress ([`run::generate`]);
//! - [`manifest`]: the dataset's `manifest.json`, rebuilt from the demo files
//!   ([`manifest::index`]);
//! - [`merge`](mod@merge): the shards' outputs (one shared directory or N) as one dataset, every demo
//!   accounted for ([`merge::merge`]).
//!
//! Shards (`--shard I/N`, `--shard auto`) and progress are `dips-batch`'s.
//!
//! The file format is `dips-dataset`'s (one safetensors file per demo). See `docs/datagen.md`.

pub mod manifest;
pub mod merge;
pub mod record;
pub mod run;
pub mod settings_file;

pub use manifest::{Manifest, index};
pub use merge::{MergeReport, merge};
pub use record::{DemoOutcome, record_demo};
pub use run::{DatagenError, DatagenReport, DatagenSettings, Remedy, generate};
