//! `prior.json`: the contact-mode prior fitted from a dataset's executed mode sequences
//! (spec §3.4: first modes and transitions counted, rows normalised, floored at `p_min`),
//! written beside the models and read by the planner.
//!
//! ```json
//! { "format": "dips-prior-1", "task": "card", "modes": ["index", ...], "p_min": 0.1,
//!   "start": [0.25, ...], "transitions": [[...], ...], "sequences": 48, "counts": {...} }
//! ```
//! `start[j]` is `p(c_0 = j)`, `transitions[i][j]` is `p(c_n = j | c_{n−1} = i)`, mode order
//! as in `modes` (the task's mode table). `counts` holds the raw counts the rows came from.

use std::path::Path;

use dips_kernel::mode::{ModeId, Task};
use dips_kernel::prior::MarkovPrior;
use serde::{Deserialize, Serialize};

use crate::{Dataset, DatasetError, Result};

/// The format tag of version 1.
pub const PRIOR_FORMAT: &str = "dips-prior-1";

/// Raw counts behind a fitted prior.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PriorCounts {
    /// How often each mode came first.
    pub start: Vec<u64>,
    /// `transitions[i][j]`: how often mode `j` followed mode `i`.
    pub transitions: Vec<Vec<u64>>,
}

/// The contents of a `prior.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PriorFile {
    /// [`PRIOR_FORMAT`].
    pub format: String,
    /// The task's name.
    pub task: String,
    /// The task's mode names, in table order (the column order of every row).
    pub modes: Vec<String>,
    /// The floor applied to every entry.
    pub p_min: f32,
    /// `p(c_0)`.
    pub start: Vec<f32>,
    /// `p(c_n | c_{n−1})`, one row per previous mode.
    pub transitions: Vec<Vec<f32>>,
    /// Number of demo sequences the prior was fitted from.
    pub sequences: usize,
    /// The raw counts.
    pub counts: PriorCounts,
}

fn bad(path: &Path, reason: impl Into<String>) -> DatasetError {
    DatasetError::Format {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

impl PriorFile {
    /// Fit from every demo's executed mode sequence and floor at `p_min`.
    pub fn fit(ds: &Dataset, p_min: f32) -> Result<Self> {
        Self::fit_where(ds, p_min, |_| true)
    }

    /// Fit from the executed mode sequences of the demos `keep` accepts (e.g. those of some
    /// sequence sources only) and floor at `p_min`; an error when it accepts none.
    pub fn fit_where(
        ds: &Dataset,
        p_min: f32,
        keep: impl Fn(&crate::DemoRecord) -> bool,
    ) -> Result<Self> {
        let task = ds.task;
        let n = task.mode_count();
        let mut sequences = Vec::with_capacity(ds.demos.len());
        let mut counts = PriorCounts {
            start: vec![0; n],
            transitions: vec![vec![0; n]; n],
        };
        for demo in ds.demos.iter().filter(|d| keep(d)) {
            let mut seq = Vec::with_capacity(demo.modes.len());
            for name in &demo.modes {
                let id = task.mode_by_name(name).map_err(|_| {
                    bad(
                        Path::new(&format!("demo seed {}", demo.seed)),
                        format!("mode {name:?} is not a {} mode", task.name()),
                    )
                })?;
                match seq.last() {
                    None => counts.start[id.index()] += 1,
                    Some(&ModeId(prev)) => {
                        counts.transitions[usize::from(prev)][id.index()] += 1;
                    }
                }
                seq.push(id);
            }
            sequences.push(seq);
        }
        if sequences.is_empty() {
            return Err(bad(
                Path::new("prior"),
                format!(
                    "no demo of the {} demos was chosen to fit the prior from",
                    ds.demos.len()
                ),
            ));
        }
        let prior = MarkovPrior::fit_with_floor(n, &sequences, p_min)
            .map_err(|e| bad(Path::new("prior"), format!("cannot fit the prior: {e}")))?;
        Ok(Self::from_prior(
            task,
            &prior,
            p_min,
            sequences.len(),
            counts,
        ))
    }

    fn from_prior(
        task: Task,
        prior: &MarkovPrior,
        p_min: f32,
        sequences: usize,
        counts: PriorCounts,
    ) -> Self {
        let n = task.mode_count();
        let ids: Vec<ModeId> = (0..n).map(|i| ModeId(i as u8)).collect();
        Self {
            format: PRIOR_FORMAT.to_string(),
            task: task.name().to_string(),
            modes: ids
                .iter()
                .map(|&m| task.mode_name(m).unwrap_or("?").to_string())
                .collect(),
            p_min,
            start: ids.iter().map(|&j| prior.probability(None, j)).collect(),
            transitions: ids
                .iter()
                .map(|&i| ids.iter().map(|&j| prior.probability(Some(i), j)).collect())
                .collect(),
            sequences,
            counts,
        }
    }

    /// The kernel prior (rows renormalised to one).
    pub fn prior(&self) -> std::result::Result<MarkovPrior, dips_kernel::prior::PriorError> {
        let rows: Vec<&[f32]> = self.transitions.iter().map(Vec::as_slice).collect();
        MarkovPrior::from_rows(&self.start, &rows)
    }

    /// Write `path` atomically (pretty JSON).
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(|e| bad(path, e.to_string()))?;
        dips_fs::write_atomic(path, text.as_bytes()).map_err(|source| DatasetError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Read `path` and check it is a prior over `task`'s modes; the error names the file and
    /// what is wrong.
    pub fn load(path: &Path, task: Task) -> Result<(Self, MarkovPrior)> {
        let text = std::fs::read_to_string(path).map_err(|source| DatasetError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let file: Self =
            serde_json::from_str(&text).map_err(|e| bad(path, format!("not a prior file: {e}")))?;
        if file.format != PRIOR_FORMAT {
            return Err(bad(
                path,
                format!("format {:?}, expected {PRIOR_FORMAT:?}", file.format),
            ));
        }
        if file.task != task.name() {
            return Err(bad(
                path,
                format!("a {} prior, expected {}", file.task, task.name()),
            ));
        }
        let n = task.mode_count();
        let expected: Vec<&str> = (0..n)
            .map(|i| task.mode_name(ModeId(i as u8)).unwrap_or("?"))
            .collect();
        if file.modes != expected {
            return Err(bad(
                path,
                format!("modes {:?}, expected {expected:?}", file.modes),
            ));
        }
        if file.transitions.len() != n {
            return Err(bad(
                path,
                format!("{} transition rows, expected {n}", file.transitions.len()),
            ));
        }
        let prior = file.prior().map_err(|e| bad(path, e.to_string()))?;
        Ok((file, prior))
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::DemoRecord;

    fn demo(seed: u64, modes: &[&str]) -> DemoRecord {
        let task = Task::Card;
        let dims = task.dims();
        let mut contexts = Vec::new();
        for name in modes {
            let id = task.mode_by_name(name).unwrap();
            let mut c = [0.0f32; 2];
            task.modes()[id.index()].mode.write_signs(&mut c);
            contexts.extend_from_slice(&c);
        }
        DemoRecord {
            task,
            seed,
            modes: modes.iter().map(|s| s.to_string()).collect(),
            trajectories: vec![0.0; modes.len() * dims.floats()],
            contexts,
            mode_index: (0..modes.len() as i64).collect(),
            step: vec![0; modes.len()],
            particle: vec![0; modes.len()],
            metadata: BTreeMap::new(),
        }
    }

    #[test]
    fn fits_counts_floors_and_round_trips() {
        let ds = Dataset::from_demos(
            Task::Card,
            vec![
                demo(1, &["index", "regrasp"]),
                demo(2, &["index", "both"]),
                demo(3, &["middle", "regrasp"]),
            ],
        )
        .unwrap();
        let f = PriorFile::fit(&ds, 0.1).unwrap();
        assert_eq!(f.modes, ["index", "middle", "both", "regrasp"]);
        assert_eq!(f.counts.start, [2, 1, 0, 0]);
        assert_eq!(f.counts.transitions[0], [0, 0, 1, 1]);
        assert_eq!(f.counts.transitions[1], [0, 0, 0, 1]);
        assert_eq!(f.sequences, 3);
        for row in std::iter::once(&f.start).chain(&f.transitions) {
            let sum: f32 = row.iter().sum();
            assert!((sum - 1.0).abs() < 1e-5, "{row:?}");
            assert!(row.iter().all(|&p| p >= 0.1 - 1e-6), "{row:?}");
        }
        assert!(
            f.start[0] > f.start[1] && f.start[1] > f.start[2],
            "{:?}",
            f.start
        );
        // A mode never left (both) has a uniform row.
        assert!(f.transitions[2].iter().all(|&p| (p - 0.25).abs() < 1e-6));

        // Fitting from some demos only counts only theirs; choosing none is an error.
        let odd = PriorFile::fit_where(&ds, 0.1, |d| d.seed % 2 == 1).unwrap();
        assert_eq!(odd.sequences, 2);
        assert_eq!(odd.counts.start, [1, 1, 0, 0]);
        assert_eq!(odd.counts.transitions[0], [0, 0, 0, 1]);
        let e = PriorFile::fit_where(&ds, 0.1, |_| false).unwrap_err();
        assert!(e.to_string().contains("no demo of the 3 demos"), "{e}");

        let dir = std::env::temp_dir().join(format!("dips-prior-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("prior.json");
        f.save(&path).unwrap();
        let (back, prior) = PriorFile::load(&path, Task::Card).unwrap();
        assert_eq!(back, f);
        assert!((prior.probability(None, ModeId(0)) - f.start[0]).abs() < 1e-6);
        let e = PriorFile::load(&path, Task::Screwdriver).unwrap_err();
        assert!(
            e.to_string().contains("prior.json") && e.to_string().contains("card"),
            "{e}"
        );
        std::fs::write(&path, "{\"format\": 3}").unwrap();
        let e = PriorFile::load(&path, Task::Card).unwrap_err();
        assert!(e.to_string().contains("not a prior file"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
