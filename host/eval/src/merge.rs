//! `dips eval merge`: the episodes of N shards — written to one shared directory or to N
//! directories — become one evaluation. The settings of every source must agree, and every
//! episode of the evaluation must be there: a missing one is named with its shard, never
//! silently dropped. Every part must be of one registration (`registration.json`: the same
//! protocol file and status, or none), which the merged directory keeps.

use std::path::{Path, PathBuf};

use dips_batch::record::{SHARDS_DIR, record_path};
use dips_batch::{
    BatchError, Shard, ShardRecord, first_difference, read_records, shards_without_record,
};
use dips_fs::write_atomic;
use serde::Serialize;

use crate::protocol::{ProtocolError, Registration, read_registration, write_registration};
use crate::run::{WALL_FILE, finished};
use crate::settings::{EVAL_FILE, EvalFile, EvalFileError, episode_dir, read_eval_file};

/// Why shards cannot be merged. Each message names the directory and what differs or lacks.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// A source is not a directory.
    #[error("{} is not a directory (give the shards' evaluation directories)", dir.display())]
    NotADirectory {
        /// The source.
        dir: PathBuf,
    },
    /// A source holds no evaluation.
    #[error("{} has no {EVAL_FILE}: not a dips eval output directory", dir.display())]
    NoEvalFile {
        /// The source.
        dir: PathBuf,
    },
    /// Nothing to merge.
    #[error("{} holds no {EVAL_FILE} and no source was given: nothing to merge", out.display())]
    Nothing {
        /// The output directory.
        out: PathBuf,
    },
    /// A source ran other settings.
    #[error(
        "{} was run with other settings: {field} is {there} there and {here} in the evaluation \
         being merged; merge only shards of one evaluation",
        file.display()
    )]
    OtherSettings {
        /// The source's `eval.json`.
        file: PathBuf,
        /// The first setting that differs.
        field: String,
        /// Its value in the source, as JSON.
        there: String,
        /// Its value in the evaluation being merged, as JSON.
        here: String,
    },
    /// A source starts at another seed.
    #[error(
        "{} starts at first seed {there}, the evaluation being merged at {here}",
        file.display()
    )]
    OtherFirstSeed {
        /// The source's `eval.json`.
        file: PathBuf,
        /// Its first seed.
        there: u64,
        /// The evaluation's.
        here: u64,
    },
    /// A source is of another registration.
    #[error(
        "{} was {theirs}, {} {ours}; merge only shards of one registration",
        dir.display(),
        from.display()
    )]
    OtherRegistration {
        /// The source.
        dir: PathBuf,
        /// Its registration, described.
        theirs: String,
        /// The directory whose registration the others have.
        from: PathBuf,
        /// That registration, described.
        ours: String,
    },
    /// Episodes of the evaluation are in no source.
    #[error(
        "{}: {} of {total} episodes are missing: {}{}{}; rerun those shards (they resume), or \
         merge allowing missing episodes to summarise what is there",
        out.display(),
        missing.len(),
        missing.iter().take(12).map(String::as_str).collect::<Vec<_>>().join(", "),
        if missing.len() > 12 { ", …" } else { "" },
        if unfinished.is_empty() {
            String::new()
        } else {
            format!("; shards without a finished record: {}", unfinished.join(", "))
        }
    )]
    Missing {
        /// The output directory.
        out: PathBuf,
        /// The missing episodes (`method seed N (shard I/N)`).
        missing: Vec<String>,
        /// The episodes of the evaluation.
        total: usize,
        /// The shards without a finished record.
        unfinished: Vec<String>,
    },
    /// An `eval.json` cannot be read.
    #[error(transparent)]
    EvalFile(#[from] EvalFileError),
    /// A `registration.json` cannot be read or written.
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// A shard record cannot be read.
    #[error(transparent)]
    Batch(#[from] BatchError),
    /// A file cannot be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file or directory.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A directory cannot be made.
    #[error("creating {}", dir.display())]
    Create {
        /// The directory.
        dir: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A file cannot be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A file cannot be written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

fn create(dir: &Path) -> Result<(), MergeError> {
    std::fs::create_dir_all(dir).map_err(|source| MergeError::Create {
        dir: dir.to_path_buf(),
        source,
    })
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), MergeError> {
    write_atomic(path, bytes).map_err(|source| MergeError::Write {
        path: path.to_path_buf(),
        source,
    })
}

fn read_error(path: &Path) -> impl FnOnce(std::io::Error) -> MergeError + '_ {
    move |source| MergeError::Read {
        path: path.to_path_buf(),
        source,
    }
}

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
fn agree(ours: &mut EvalFile, theirs: &EvalFile, path: &Path) -> Result<(), MergeError> {
    if ours.episode != theirs.episode {
        let (field, there, here) = first_difference(
            &serde_json::to_value(&theirs.episode)?,
            &serde_json::to_value(&ours.episode)?,
            "settings",
        );
        return Err(MergeError::OtherSettings {
            file: path.to_path_buf(),
            field,
            there,
            here,
        });
    }
    if ours.first_seed != theirs.first_seed {
        return Err(MergeError::OtherFirstSeed {
            file: path.to_path_buf(),
            there: theirs.first_seed,
            here: ours.first_seed,
        });
    }
    for m in &theirs.methods {
        if !ours.methods.contains(m) {
            ours.methods.push(*m);
        }
    }
    ours.trials = ours.trials.max(theirs.trials);
    Ok(())
}

/// Copy the files of one finished episode, `wall.json` last (it is what marks an episode
/// finished), each atomically.
fn copy_episode(from: &Path, to: &Path) -> Result<(), MergeError> {
    create(to)?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(from)
        .map_err(read_error(from))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort_by_key(|p| (p.file_name().is_some_and(|n| n == WALL_FILE), p.clone()));
    for f in files {
        let Some(name) = f.file_name() else { continue };
        let bytes = std::fs::read(&f).map_err(read_error(&f))?;
        write(&to.join(name), &bytes)?;
    }
    Ok(())
}

/// Merge the evaluation directories `sources` into `out` (which may be one of them, or hold
/// every shard itself when `sources` is empty). Errors when a source's settings differ, or when
/// an episode of the evaluation is in no source (unless `allow_missing`: then it is listed).
pub fn merge(
    out: &Path,
    sources: &[PathBuf],
    allow_missing: bool,
) -> Result<MergeReport, MergeError> {
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
            return Err(MergeError::NotADirectory { dir: src.clone() });
        }
        let theirs =
            read_eval_file(src)?.ok_or_else(|| MergeError::NoEvalFile { dir: src.clone() })?;
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
                    return Err(MergeError::OtherRegistration {
                        dir: src.clone(),
                        theirs: name(&their_registration),
                        from: from.clone(),
                        ours: name(ours),
                    });
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
                let from = episode_dir(src, *method, seed);
                if !finished(&from) {
                    continue;
                }
                let to = episode_dir(out, *method, seed);
                if finished(&to) {
                    already_there += 1;
                } else {
                    copy_episode(&from, &to)?;
                    copied += 1;
                }
            }
        }
    }
    let file = file.ok_or_else(|| MergeError::Nothing {
        out: out.to_path_buf(),
    })?;
    create(out)?;
    if let Some((Some(r), _)) = &registration
        && read_registration(out)?.is_none()
    {
        write_registration(out, r)?;
    }
    write(
        &out.join(EVAL_FILE),
        serde_json::to_string_pretty(&file)?.as_bytes(),
    )?;
    for r in &records {
        let path = record_path(out, r.shard());
        if !path.exists() {
            create(&out.join(SHARDS_DIR))?;
            write(&path, serde_json::to_string_pretty(r)?.as_bytes())?;
        }
    }
    let count = records.iter().map(|r| r.count).max();
    let mut missing = Vec::new();
    let mut position = 0;
    for method in &file.methods {
        for trial in 0..file.trials {
            let seed = file.first_seed + trial as u64;
            if !finished(&episode_dir(out, *method, seed)) {
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
        let unfinished = count.map_or(Vec::new(), |n| {
            shards_without_record(&records, n)
                .iter()
                .map(ToString::to_string)
                .collect()
        });
        return Err(MergeError::Missing {
            out: out.to_path_buf(),
            missing,
            total: file.methods.len() * file.trials,
            unfinished,
        });
    }
    Ok(MergeReport {
        copied,
        already_there,
        shards: records.len(),
        missing,
    })
}
