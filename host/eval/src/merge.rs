//! `dips eval merge`: the episodes of N shards — written to one shared directory or to N
//! directories — become one evaluation. The settings of every source must agree, and every
//! episode of the evaluation must be there: a missing one is named with its shard, never
//! silently dropped. Every part must be of one registration (`registration.json`: the same
//! protocol file and status, or none), which the merged directory keeps.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use dips_batch::record::{SHARDS_DIR, record_path};
use dips_batch::{Shard, ShardRecord, first_difference, read_records, shards_without_record};
use dips_fs::write_atomic;
use serde::Serialize;

use crate::protocol::{Registration, read_registration, write_registration};
use crate::run::{WALL_FILE, finished};
use crate::settings::{EVAL_FILE, EvalFile, episode_dir, read_eval_file};

/// What a merge did.
#[derive(Debug, Clone, Serialize)]
pub struct MergeReport {
    /// Episodes copied into the output.
    pub copied: usize,
    /// Episodes already in the output (or in more than one source: the first is kept).
    pub already_there: usize,
    /// Shard records found over all sources.
    pub shards: usize,
    /// Episodes of the evaluation that no source holds (`method seed N (shard I/N)`).
    pub missing: Vec<String>,
}

/// Check that `theirs` (from `path`) describes the same evaluation as `ours`, and widen `ours`
/// to its methods and trials.
fn agree(ours: &mut EvalFile, theirs: &EvalFile, path: &Path) -> anyhow::Result<()> {
    if ours.episode != theirs.episode {
        let (field, a, b) = first_difference(
            &serde_json::to_value(&theirs.episode)?,
            &serde_json::to_value(&ours.episode)?,
            "settings",
        );
        bail!(
            "{} was run with other settings: {field} is {a} there and {b} in the evaluation \
             being merged; merge only shards of one evaluation",
            path.display()
        );
    }
    if ours.first_seed != theirs.first_seed {
        bail!(
            "{} starts at --first-seed {}, the evaluation being merged at {}",
            path.display(),
            theirs.first_seed,
            ours.first_seed
        );
    }
    for m in &theirs.methods {
        if !ours.methods.contains(m) {
            ours.methods.push(m.clone());
        }
    }
    ours.trials = ours.trials.max(theirs.trials);
    Ok(())
}

/// Copy the files of one finished episode, `wall.json` last (it is what marks an episode
/// finished), each atomically.
fn copy_episode(from: &Path, to: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(to).with_context(|| format!("creating {}", to.display()))?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(from)
        .with_context(|| format!("reading {}", from.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort_by_key(|p| (p.file_name().is_some_and(|n| n == WALL_FILE), p.clone()));
    for f in files {
        let Some(name) = f.file_name() else { continue };
        let bytes = std::fs::read(&f).with_context(|| format!("reading {}", f.display()))?;
        let path = to.join(name);
        write_atomic(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// Merge the evaluation directories `sources` into `out` (which may be one of them, or hold
/// every shard itself when `sources` is empty). Errors when a source's settings differ, or when
/// an episode of the evaluation is in no source (unless `allow_missing`: then it is listed).
pub fn merge(out: &Path, sources: &[PathBuf], allow_missing: bool) -> anyhow::Result<MergeReport> {
    let mut file = read_eval_file(out)?;
    // The registration every part must share (`None` inside: run without a protocol); unknown
    // until a directory with an evaluation is seen.
    let mut registration: Option<(Option<Registration>, PathBuf)> = file
        .as_ref()
        .map(|_| read_registration(out).map(|r| (r, out.to_path_buf())))
        .transpose()?;
    let mut records: Vec<ShardRecord> = read_records(out)?;
    let (mut copied, mut already_there) = (0, 0);
    for src in sources {
        if !src.is_dir() {
            bail!(
                "{} is not a directory (give the shards' evaluation directories)",
                src.display()
            );
        }
        let theirs = read_eval_file(src)?.with_context(|| {
            format!(
                "{} has no {EVAL_FILE}: not a dips eval output directory",
                src.display()
            )
        })?;
        match &mut file {
            None => file = Some(theirs.clone()),
            Some(ours) => agree(ours, &theirs, &src.join(EVAL_FILE))?,
        }
        let their_registration = read_registration(src)?;
        match &registration {
            None => registration = Some((their_registration, src.clone())),
            Some((ours, from)) => {
                let key = |r: &Option<Registration>| {
                    r.as_ref().map(|r| (r.protocol_sha256.clone(), r.status))
                };
                if key(ours) != key(&their_registration) {
                    let name = |r: &Option<Registration>| match r {
                        Some(r) => format!("{} under protocol {}", r.status.name(), r.name),
                        None => "run without a protocol".to_string(),
                    };
                    bail!(
                        "{} was {}, {} {}; merge only shards of one registration",
                        src.display(),
                        name(&their_registration),
                        from.display(),
                        name(ours)
                    );
                }
            }
        }
        for r in read_records(src)? {
            if !records.contains(&r) {
                records.push(r);
            }
        }
        let same = matches!(
            (src.canonicalize(), out.canonicalize()),
            (Ok(a), Ok(b)) if a == b
        );
        if same {
            continue;
        }
        for method in &theirs.methods {
            for trial in 0..theirs.trials {
                let seed = theirs.first_seed + trial as u64;
                let from = episode_dir(src, method, seed);
                if !finished(&from) {
                    continue;
                }
                let to = episode_dir(out, method, seed);
                if finished(&to) {
                    already_there += 1;
                } else {
                    copy_episode(&from, &to)?;
                    copied += 1;
                }
            }
        }
    }
    let file = file.with_context(|| {
        format!(
            "{} holds no {EVAL_FILE} and no source was given: nothing to merge",
            out.display()
        )
    })?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    if let Some((Some(r), _)) = &registration
        && read_registration(out)?.is_none()
    {
        write_registration(out, r)?;
    }
    let path = out.join(EVAL_FILE);
    write_atomic(&path, serde_json::to_string_pretty(&file)?.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    for r in &records {
        let path = record_path(out, r.shard());
        if !path.exists() {
            std::fs::create_dir_all(out.join(SHARDS_DIR))?;
            write_atomic(&path, serde_json::to_string_pretty(r)?.as_bytes())
                .with_context(|| format!("writing {}", path.display()))?;
        }
    }
    let count = records.iter().map(|r| r.count).max();
    let mut missing = Vec::new();
    let mut position = 0;
    for method in &file.methods {
        for trial in 0..file.trials {
            let seed = file.first_seed + trial as u64;
            if !finished(&episode_dir(out, method, seed)) {
                missing.push(match count {
                    Some(n) => format!(
                        "{method} seed {seed} (shard {})",
                        Shard::of_position(position, n)
                    ),
                    None => format!("{method} seed {seed}"),
                });
            }
            position += 1;
        }
    }
    if !missing.is_empty() && !allow_missing {
        let unfinished = count.map_or(String::new(), |n| {
            let s: Vec<String> = shards_without_record(&records, n)
                .iter()
                .map(ToString::to_string)
                .collect();
            if s.is_empty() {
                String::new()
            } else {
                format!("; shards without a finished record: {}", s.join(", "))
            }
        });
        let total = file.methods.len() * file.trials;
        let shown: Vec<&str> = missing.iter().take(12).map(String::as_str).collect();
        bail!(
            "{}: {} of {total} episodes are missing: {}{}{unfinished}; rerun those shards (they \
             resume), or merge with --allow-missing to summarise what is there",
            out.display(),
            missing.len(),
            shown.join(", "),
            if missing.len() > shown.len() {
                ", …"
            } else {
                ""
            },
        );
    }
    Ok(MergeReport {
        copied,
        already_there,
        shards: records.len(),
        missing,
    })
}
