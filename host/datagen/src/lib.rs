//! `dips-datagen`: the offline data of DIPS. Episodes whose contact-mode sequences come from
//! the task's prior are executed closed-loop by CSVTO in the quasi-static world, and every
//! online step's particles are recorded as training trajectories (`dips datagen`).
//!
//! - [`record`]: one demo — an episode and its trajectories ([`record::record_demo`]);
//! - [`shard`]: `--shard I/N`, the split of demo seeds over the machines of a job array;
//! - [`run`]: many demos on all cores, resumable, with progress ([`run::generate`]);
//! - [`manifest`]: the dataset's `manifest.json`, rebuilt from the demo files
//!   ([`manifest::index`]), which is also how shards are merged.
//!
//! The file format is `dips-dataset`'s (one safetensors file per demo). See `docs/datagen.md`.

pub mod manifest;
pub mod record;
pub mod run;
pub mod shard;

pub use manifest::{Manifest, index};
pub use record::{DemoOutcome, record_demo};
pub use run::{DatagenError, DatagenReport, DatagenSettings, generate};
pub use shard::Shard;
