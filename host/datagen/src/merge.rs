//! `dips datagen merge`: the demos of N shards — written to one shared directory or to N
//! directories — become one dataset with its `manifest.json`. Every demo the settings asked for
//! must be there: a missing one is named with its shard, never silently dropped.

use std::path::{Path, PathBuf};

use dips_batch::{ShardRecord, read_records, shards_without_record};
use dips_world::scenes::SceneKind;

use crate::manifest::{Manifest, index};
use crate::run::{DatagenError, Remedy, demo_path};
use crate::settings_file::{DATAGEN_FILE, DatagenFile, read_datagen_file, write_datagen_file};

/// What a merge did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MergeReport {
    /// Demo files copied into the output.
    pub copied: usize,
    /// Demo files already in the output (or in more than one source: the first is kept).
    pub already_there: usize,
    /// The shard records found, over all sources.
    pub shards: usize,
    /// The merged dataset's manifest.
    pub manifest: Manifest,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> DatagenError + '_ {
    move |source| DatagenError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Copy `from` to `to` atomically (a temporary file beside `to`, then a rename).
fn copy_atomic(from: &Path, to: &Path) -> Result<(), DatagenError> {
    let bytes = std::fs::read(from).map_err(io(from))?;
    dips_fs::write_atomic(to, &bytes).map_err(io(to))
}

/// Merge the dataset directories `sources` into `out` (which may be one of them, or hold the
/// shards itself when `sources` is empty), then check that every demo of every batch in their
/// `datagen.json` is there and index `out`. With `allow_missing`, missing demos are reported
/// on the manifest only.
pub fn merge(
    task: SceneKind,
    out: &Path,
    sources: &[PathBuf],
    allow_missing: bool,
) -> Result<MergeReport, DatagenError> {
    std::fs::create_dir_all(out.join("demos")).map_err(io(out))?;
    let out_file = out.join(DATAGEN_FILE);
    let mut settings = read_datagen_file(out)?.unwrap_or_else(|| DatagenFile {
        format: crate::settings_file::DATAGEN_FORMAT.into(),
        task: task.name().into(),
        batches: Vec::new(),
    });
    let mut records: Vec<ShardRecord> = read_records(out)?;
    let (mut copied, mut already_there) = (0, 0);
    for src in sources {
        if !src.is_dir() {
            return Err(DatagenError::NotADirectory { dir: src.clone() });
        }
        let theirs = read_datagen_file(src)?
            .ok_or_else(|| DatagenError::NoSettingsFile { dir: src.clone() })?;
        if theirs.task != settings.task {
            return Err(DatagenError::OtherSettings {
                path: src.join(DATAGEN_FILE),
                field: "task".into(),
                theirs: theirs.task,
                ours: settings.task.clone(),
                remedy: Remedy::OneTask,
            });
        }
        for batch in theirs.batches {
            settings.add(batch, &src.join(DATAGEN_FILE))?;
        }
        for r in read_records(src)? {
            if !records.contains(&r) {
                records.push(r);
            }
        }
        if same_dir(src, out) {
            continue;
        }
        let demos = src.join("demos");
        let mut files: Vec<PathBuf> = match std::fs::read_dir(&demos) {
            Ok(entries) => entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "safetensors"))
                .collect(),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(source) => {
                return Err(DatagenError::Io {
                    path: demos,
                    source,
                });
            }
        };
        files.sort();
        for f in files {
            let Some(name) = f.file_name() else { continue };
            let to = out.join("demos").join(name);
            if to.exists() {
                already_there += 1;
            } else {
                copy_atomic(&f, &to)?;
                copied += 1;
            }
        }
    }
    write_datagen_file(out, &settings)?;
    for r in &records {
        let path = dips_batch::record::record_path(out, r.shard());
        if !path.exists() {
            let text = serde_json::to_string_pretty(r).unwrap_or_default();
            std::fs::create_dir_all(out.join(dips_batch::record::SHARDS_DIR)).map_err(io(out))?;
            dips_fs::write_atomic(&path, text.as_bytes()).map_err(io(&path))?;
        }
    }
    let manifest = index(out, task)?;
    let missing: Vec<u64> = settings
        .batches
        .iter()
        .flat_map(|b| b.seeds())
        .filter(|&s| !demo_path(out, task, s).exists())
        .collect();
    if !missing.is_empty() && !allow_missing {
        let expected: usize = settings.batches.iter().map(|b| b.demos).sum();
        return Err(DatagenError::Incomplete {
            dir: out_file.parent().unwrap_or(out).to_path_buf(),
            missing: missing.len(),
            expected,
            detail: describe_missing(&settings, &records, &missing),
        });
    }
    Ok(MergeReport {
        copied,
        already_there,
        shards: records.len(),
        manifest,
    })
}

/// `seeds 3, 7 (shard 3/4: no record)`: the missing seeds, and the shards that own them where
/// the shard count is known from the records.
fn describe_missing(settings: &DatagenFile, records: &[ShardRecord], missing: &[u64]) -> String {
    let list = |v: &[u64]| {
        let mut s = v
            .iter()
            .take(12)
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(", ");
        if v.len() > 12 {
            s += &format!(", … ({} more)", v.len() - 12);
        }
        s
    };
    let mut text = format!("seeds {}", list(missing));
    if let Some(count) = records.iter().map(|r| r.count).max() {
        let mut owners: Vec<String> = Vec::new();
        for &seed in missing {
            if let Some(b) = settings.batches.iter().find(|b| b.seeds().contains(&seed)) {
                let shard = dips_batch::Shard::of_position((seed - b.first_seed) as usize, count);
                let name = format!("{shard}");
                if !owners.contains(&name) {
                    owners.push(name);
                }
            }
        }
        let unfinished: Vec<String> = shards_without_record(records, count)
            .iter()
            .map(ToString::to_string)
            .collect();
        text += &format!("; owned by shard {}", owners.join(", "));
        if !unfinished.is_empty() {
            text += &format!(
                "; shards without a finished record: {}",
                unfinished.join(", ")
            );
        }
    }
    text
}
