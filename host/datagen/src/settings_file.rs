//! `DIR/datagen.json`: the batches of demos a dataset directory was asked for (seed range,
//! sequence source, execution settings), so that a resumed or concurrent shard with other
//! settings is refused and a merge knows which demos must be there.

use std::path::Path;

use dips_batch::first_difference;
use serde::{Deserialize, Serialize};

use crate::run::{DatagenError, DatagenSettings, Remedy};

/// The settings file's name.
pub const DATAGEN_FILE: &str = "datagen.json";

/// The settings file's format name.
pub const DATAGEN_FORMAT: &str = "dips-datagen-settings-1";

/// One `dips datagen` batch: demos `first_seed..first_seed + demos`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Batch {
    /// Seed of the first demo.
    pub first_seed: u64,
    /// Demos in the batch (over all shards).
    pub demos: usize,
    /// Where the contact sequences come from.
    pub sequences: String,
    /// CSVTO and execution settings.
    pub exec: serde_json::Value,
}

impl Batch {
    /// The batch's seeds.
    pub fn seeds(&self) -> std::ops::Range<u64> {
        self.first_seed..self.first_seed + self.demos as u64
    }

    fn overlaps(&self, other: &Batch) -> bool {
        let (a, b) = (self.seeds(), other.seeds());
        a.start < b.end && b.start < a.end
    }
}

/// `datagen.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatagenFile {
    /// [`DATAGEN_FORMAT`].
    pub format: String,
    /// Task name.
    pub task: String,
    /// The batches, in the order they were first asked for.
    pub batches: Vec<Batch>,
}

impl DatagenFile {
    /// The batch of `settings`.
    pub fn batch_of(settings: &DatagenSettings) -> Batch {
        Batch {
            first_seed: settings.first_seed,
            demos: settings.demos,
            sequences: settings.sequences.name().to_string(),
            exec: serde_json::to_value(settings.exec).unwrap_or(serde_json::Value::Null),
        }
    }

    /// Add `batch`: the same range again must have the same settings, and a new range must not
    /// overlap one of other settings. `path` names the file in errors.
    pub fn add(&mut self, batch: Batch, path: &Path) -> Result<(), DatagenError> {
        let other = |field: String, theirs: String, ours: String, remedy| {
            Err(DatagenError::OtherSettings {
                path: path.to_path_buf(),
                field,
                theirs,
                ours,
                remedy,
            })
        };
        for old in &self.batches {
            if old == &batch {
                return Ok(());
            }
            if !old.overlaps(&batch) {
                continue;
            }
            let hint = Remedy::OtherSeedsOrDirectory;
            if (old.first_seed, old.demos) != (batch.first_seed, batch.demos) {
                return other(
                    "seeds".into(),
                    format!("{}..{}", old.seeds().start, old.seeds().end),
                    format!("{}..{}", batch.seeds().start, batch.seeds().end),
                    hint,
                );
            }
            if old.sequences != batch.sequences {
                return other(
                    "sequences".into(),
                    old.sequences.clone(),
                    batch.sequences.clone(),
                    hint,
                );
            }
            let (field, theirs, ours) = first_difference(&old.exec, &batch.exec, "exec");
            return other(field, theirs, ours, hint);
        }
        self.batches.push(batch);
        Ok(())
    }
}

/// Read `dir/datagen.json` if present.
pub fn read_datagen_file(dir: &Path) -> Result<Option<DatagenFile>, DatagenError> {
    let path = dir.join(DATAGEN_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|source| DatagenError::Io {
        path: path.clone(),
        source,
    })?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|error| DatagenError::SettingsFile { path, error })
}

/// Write `file` to `dir/datagen.json` atomically.
pub fn write_datagen_file(dir: &Path, file: &DatagenFile) -> Result<(), DatagenError> {
    let text = serde_json::to_string_pretty(file).unwrap_or_default();
    let path = dir.join(DATAGEN_FILE);
    dips_fs::write_atomic(&path, text.as_bytes())
        .map_err(|source| DatagenError::Io { path, source })
}

/// Record `settings`' batch in `dir/datagen.json`, refusing a directory of another task or a
/// seed range already asked for with other settings. Demos made before the file existed are
/// still checked one by one when they are read.
pub fn claim_dir(dir: &Path, settings: &DatagenSettings) -> Result<DatagenFile, DatagenError> {
    std::fs::create_dir_all(dir).map_err(|source| DatagenError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join(DATAGEN_FILE);
    let task = settings.task.name().to_string();
    let mut file = read_datagen_file(dir)?.unwrap_or_else(|| DatagenFile {
        format: DATAGEN_FORMAT.into(),
        task: task.clone(),
        batches: Vec::new(),
    });
    if file.task != task {
        return Err(DatagenError::OtherSettings {
            path,
            field: "task".into(),
            theirs: file.task,
            ours: task,
            remedy: Remedy::OtherDirectory,
        });
    }
    let before = file.batches.len();
    file.add(DatagenFile::batch_of(settings), &path)?;
    if file.batches.len() != before {
        write_datagen_file(dir, &file)?;
    }
    Ok(file)
}
