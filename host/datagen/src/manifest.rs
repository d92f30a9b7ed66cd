//! `manifest.json`: what a dataset directory holds, rebuilt from its demo files. Rebuilding
//! from the files (rather than appending as demos finish) is what makes shards mergeable:
//! copy the `demos/` of every shard into one directory and index it.

use std::path::Path;

use dips_dataset::{DatasetError, demo_files, read_demo};
use dips_world::scenes::SceneKind;
use serde::{Deserialize, Serialize};

use crate::run::{DatagenError, GIT_REVISION};

/// The manifest format's name and version.
pub const MANIFEST_FORMAT: &str = "dips-datagen-manifest-1";

/// A dataset directory's summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`MANIFEST_FORMAT`].
    pub format: String,
    /// Task name.
    pub task: String,
    /// Demos in `demos/`.
    pub demos: usize,
    /// Their seeds, ascending.
    pub seeds: Vec<u64>,
    /// Trajectories over all demos.
    pub trajectories: usize,
    /// Rows and columns of each trajectory (`T`, `D`).
    pub shape: [usize; 2],
    /// Executed modes over all demos.
    pub modes: usize,
    /// Demos whose object stayed valid throughout.
    pub valid_demos: usize,
    /// Median final yaw (screwdriver, rad) or distance to the goal (card, m) over the demos.
    pub median_final_metric: Option<f64>,
    /// Median wall time per demo as recorded by the generator (s).
    pub median_seconds_per_demo: Option<f64>,
    /// Git revisions the demos were generated at.
    pub git_revisions: Vec<String>,
    /// Execution settings of the first demo (JSON, as recorded).
    pub exec_settings: Option<serde_json::Value>,
    /// The revision of the program that wrote this manifest.
    pub indexed_by: String,
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// Read every demo of `dir` (checking each), write `dir/manifest.json` atomically and return
/// it. Two demos with one seed (two shards that overlapped) are an error naming both files.
pub fn index(dir: &Path, task: SceneKind) -> Result<Manifest, DatagenError> {
    let kernel_task = task.task();
    let files = demo_files(dir)?;
    let dims = kernel_task.dims();
    let mut seeds = Vec::with_capacity(files.len());
    let mut seen: Vec<(u64, std::path::PathBuf)> = Vec::new();
    let (mut trajectories, mut modes, mut valid) = (0, 0, 0);
    let (mut metric, mut seconds) = (Vec::new(), Vec::new());
    let mut revisions: Vec<String> = Vec::new();
    let mut exec_settings = None;
    for f in files {
        let d = read_demo(&f, kernel_task)?;
        if let Some((_, first)) = seen.iter().find(|(s, _)| *s == d.seed) {
            return Err(DatasetError::DuplicateSeed {
                seed: d.seed,
                first: first.clone(),
                second: f,
            }
            .into());
        }
        seen.push((d.seed, f.clone()));
        seeds.push(d.seed);
        trajectories += d.len();
        modes += d.modes.len();
        if let Some(o) = d.outcome() {
            valid += usize::from(o["valid"].as_bool().unwrap_or(false));
            if let Some(m) = o["final_yaw"]
                .as_f64()
                .or_else(|| o["final_distance_m"].as_f64())
            {
                metric.push(m);
            }
        }
        if let Some(s) = d.metadata.get("seconds").and_then(|s| s.parse().ok()) {
            seconds.push(s);
        }
        if let Some(r) = d.metadata.get("git_revision")
            && !revisions.contains(r)
        {
            revisions.push(r.clone());
        }
        if exec_settings.is_none() {
            exec_settings = d
                .metadata
                .get("exec_settings")
                .and_then(|s| serde_json::from_str(s).ok());
        }
    }
    seeds.sort_unstable();
    let manifest = Manifest {
        format: MANIFEST_FORMAT.into(),
        task: task.name().into(),
        demos: seeds.len(),
        seeds,
        trajectories,
        shape: [dims.horizon, dims.dim()],
        modes,
        valid_demos: valid,
        median_final_metric: median(metric),
        median_seconds_per_demo: median(seconds),
        git_revisions: revisions,
        exec_settings,
        indexed_by: GIT_REVISION.into(),
    };
    let path = dir.join("manifest.json");
    let text = serde_json::to_string_pretty(&manifest).unwrap_or_default();
    // Every shard of a shared directory rewrites it when it finishes: the atomic writer names
    // its temporary file after the host too, so two shards never write one.
    dips_fs::write_atomic(&path, text.as_bytes())
        .map_err(|source| DatagenError::Io { path, source })?;
    Ok(manifest)
}
