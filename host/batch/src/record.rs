//! What a finished shard leaves behind: `DIR/shards/shard-I-of-N.json` (host, wall time, its
//! report), so that a merge can name the shards that never finished; written with
//! [`dips_fs::write_atomic`], so that shards on several hosts sharing one directory never
//! corrupt each other's files.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::shard::Shard;

/// The folder of shard records inside a batch directory.
pub const SHARDS_DIR: &str = "shards";

/// Why a batch file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// The operating system's error on a path.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// A record that does not parse.
    #[error("{path}: not a shard record ({reason}); delete it and rerun that shard")]
    BadRecord {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> BatchError + '_ {
    move |source| BatchError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// One finished shard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardRecord {
    /// Its index.
    pub index: usize,
    /// The number of shards.
    pub count: usize,
    /// The host it ran on.
    pub host: String,
    /// Wall time of its last run (s).
    pub seconds: f64,
    /// When it finished (Unix time, s).
    pub finished_unix_s: u64,
    /// What the run reported (its counts).
    pub report: serde_json::Value,
}

impl ShardRecord {
    /// The shard.
    pub fn shard(&self) -> Shard {
        Shard {
            index: self.index,
            count: self.count,
        }
    }
}

/// The record file of `shard` in `dir`.
pub fn record_path(dir: &Path, shard: Shard) -> PathBuf {
    dir.join(SHARDS_DIR)
        .join(format!("shard-{}-of-{}.json", shard.index, shard.count))
}

/// Record that `shard` finished in `dir` after `seconds`, with its `report`.
pub fn write_record(
    dir: &Path,
    shard: Shard,
    seconds: f64,
    report: &impl Serialize,
) -> Result<ShardRecord, BatchError> {
    let folder = dir.join(SHARDS_DIR);
    std::fs::create_dir_all(&folder).map_err(io(&folder))?;
    let record = ShardRecord {
        index: shard.index,
        count: shard.count,
        host: dips_fs::hostname(),
        seconds,
        finished_unix_s: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
        report: serde_json::to_value(report).unwrap_or(serde_json::Value::Null),
    };
    let path = record_path(dir, shard);
    let text = serde_json::to_string_pretty(&record).unwrap_or_default();
    dips_fs::write_atomic(&path, text.as_bytes()).map_err(io(&path))?;
    Ok(record)
}

/// Every shard record of `dir`, by count then index.
pub fn read_records(dir: &Path) -> Result<Vec<ShardRecord>, BatchError> {
    let folder = dir.join(SHARDS_DIR);
    if !folder.is_dir() {
        return Ok(Vec::new());
    }
    let mut records = Vec::new();
    for entry in std::fs::read_dir(&folder).map_err(io(&folder))? {
        let path = entry.map_err(io(&folder))?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if !(name.starts_with("shard-") && name.ends_with(".json")) {
            continue;
        }
        let text = std::fs::read_to_string(&path).map_err(io(&path))?;
        let record: ShardRecord =
            serde_json::from_str(&text).map_err(|e| BatchError::BadRecord {
                path: path.clone(),
                reason: e.to_string(),
            })?;
        records.push(record);
    }
    records.sort_by_key(|r| (r.count, r.index));
    Ok(records)
}

/// The shards of a split `count` ways that have no record in `records`.
pub fn shards_without_record(records: &[ShardRecord], count: usize) -> Vec<Shard> {
    (0..count)
        .map(|index| Shard { index, count })
        .filter(|s| !records.iter().any(|r| r.shard() == *s))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_and_missing_shards_are_named() {
        let dir = std::env::temp_dir().join(format!("dips-batch-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for index in [0, 2] {
            write_record(
                &dir,
                Shard { index, count: 3 },
                1.5,
                &serde_json::json!({ "ran": index }),
            )
            .unwrap();
        }
        let records = read_records(&dir).unwrap();
        assert_eq!(records.len(), 2);
        assert_eq!(records[1].report["ran"], 2);
        assert_eq!(
            shards_without_record(&records, 3),
            vec![Shard { index: 1, count: 3 }]
        );
        // No temporary file is left behind.
        let names: Vec<_> = std::fs::read_dir(dir.join(SHARDS_DIR))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
        std::fs::write(dir.join(SHARDS_DIR).join("shard-1-of-3.json"), "{").unwrap();
        let e = read_records(&dir).unwrap_err().to_string();
        assert!(
            e.contains("shard-1-of-3.json") && e.contains("rerun"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
