//! `dips-dataset`: the on-disk format of DIPS training data, its reader and its atomic writer.
//!
//! # Format, version 1
//! A dataset is a directory `DIR/demos/` holding one [safetensors] file per demo
//! (`*.safetensors`; a PyTorch user reads it with `safetensors.torch.load_file`). Tensors:
//!
//! | name | dtype | shape | holds |
//! |---|---|---|---|
//! | `trajectories` | F32 | `[N, T, D]` | raw `docs/contracts.md` §2 rows (yaw/θ as cos/sin, not normalised) |
//! | `contexts` | F32 | `[N, F]` | the contact mode of each trajectory, ±1 per finger |
//! | `mode_index` | I64 | `[N]` | which executed mode (index into `modes`) the sample belongs to |
//! | `step` | I64 | `[N]` | the online (replanning) step within that mode |
//! | `particle` | I64 | `[N]` | the CSVTO particle |
//!
//! `__metadata__` (all strings): `dips.dataset` = `"1"`, `task` (`screwdriver` | `card`),
//! `seed` (the demo's seed, decimal), `modes` (JSON array of the executed mode names, in
//! order). Other keys are kept verbatim in [`DemoRecord::metadata`] (e.g. the executed outcome
//! or the git revision the data generator ran at).
//!
//! Every sample's context must equal the contact vector of `modes[mode_index]`.
//!
//! [safetensors]: https://huggingface.co/docs/safetensors

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use dips_kernel::mode::{SegmentDims, Task};
use dips_kernel::task::CardGoals;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};

/// The format version this crate reads and writes (`dips.dataset`).
pub const FORMAT_VERSION: &str = "1";

/// Metadata keys the format defines; other keys travel in [`DemoRecord::metadata`].
pub const RESERVED_KEYS: [&str; 4] = ["dips.dataset", "task", "seed", "modes"];

/// Why a dataset could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A file or directory could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A demo file is not a valid dataset file; `reason` says what is wrong.
    #[error("{path}: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A record handed to [`write_demo`] is inconsistent.
    #[error("demo record for {path}: {reason}")]
    BadRecord {
        /// The file it was to be written to.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The directory holds no demo file.
    #[error("{dir}: no demos/*.safetensors files")]
    Empty {
        /// The dataset directory.
        dir: PathBuf,
    },
    /// Two files carry the same demo seed (the train/held-out split is by seed).
    #[error("{first} and {second} both hold demo seed {seed}")]
    DuplicateSeed {
        /// The seed.
        seed: u64,
        /// The first file.
        first: PathBuf,
        /// The second file.
        second: PathBuf,
    },
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, DatasetError>;

pub mod prior_file;
pub use prior_file::{PRIOR_FORMAT, PriorFile};

/// One demo: every recorded trajectory of one episode.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoRecord {
    /// The task.
    pub task: Task,
    /// The demo's seed.
    pub seed: u64,
    /// Names of the executed modes, in order (`Task::modes` names).
    pub modes: Vec<String>,
    /// `[N, T, D]` raw trajectories, row-major.
    pub trajectories: Vec<f32>,
    /// `[N, F]` contact modes (±1).
    pub contexts: Vec<f32>,
    /// `[N]` index into `modes`.
    pub mode_index: Vec<i64>,
    /// `[N]` online step within the mode.
    pub step: Vec<i64>,
    /// `[N]` CSVTO particle.
    pub particle: Vec<i64>,
    /// Other metadata (not the reserved keys).
    pub metadata: BTreeMap<String, String>,
}

/// The metadata key naming the source of a demo's contact sequence (`dips datagen
/// --sequences`); a demo without it was made from [`SEQUENCE_SOURCES`]`[0]`, the paper's
/// pattern.
pub const SEQUENCES_KEY: &str = "sequences";

/// The metadata key of the outcome `dips datagen` records for a demo (JSON: `valid`, the final
/// metric, and per mode `mode`, `start_state`, `end_state`, `valid`).
pub const OUTCOME_KEY: &str = "outcome";

/// The metadata key of the execution settings `dips datagen` ran a demo with (JSON; its
/// `card_goals`, absent for ours, says where the card's pushes aimed).
pub const EXEC_SETTINGS_KEY: &str = "exec_settings";

/// The sequence sources `dips datagen --sequences` knows, the default first.
pub const SEQUENCE_SOURCES: [&str; 3] = ["pattern", "markov", "turn-runs"];

impl DemoRecord {
    /// The source of the demo's contact sequence ([`SEQUENCES_KEY`]; the paper's pattern
    /// when absent).
    pub fn sequence_source(&self) -> &str {
        self.metadata
            .get(SEQUENCES_KEY)
            .map_or(SEQUENCE_SOURCES[0], String::as_str)
    }

    /// Where the demo's card pushes aimed: the `card_goals` of its execution settings
    /// ([`EXEC_SETTINGS_KEY`]); ours ([`CardGoals::Capped`]) when the settings do not name
    /// them (every demo made before they could differ). `None` when the settings name
    /// something that is not a card-goals name.
    pub fn card_goals(&self) -> Option<CardGoals> {
        let Some(text) = self.metadata.get(EXEC_SETTINGS_KEY) else {
            return Some(CardGoals::default());
        };
        let exec: serde_json::Value = serde_json::from_str(text).ok()?;
        match exec.get("card_goals") {
            None => Some(CardGoals::default()),
            Some(v) => v.as_str()?.parse().ok(),
        }
    }

    /// Number of trajectories `N`.
    pub fn len(&self) -> usize {
        self.mode_index.len()
    }

    /// The demo's recorded outcome ([`OUTCOME_KEY`]), `None` when absent or not JSON.
    pub fn outcome(&self) -> Option<serde_json::Value> {
        serde_json::from_str(self.metadata.get(OUTCOME_KEY)?).ok()
    }

    /// The index of a demo's first mode that did not stay valid (the object fell or left the
    /// task's bounds in it), from its [`Self::outcome`] (each mode's `valid`); `None` when
    /// every mode stayed valid or the demo carries no such record.
    pub fn first_invalid_mode(&self) -> Option<usize> {
        self.outcome()?
            .get("modes")?
            .as_array()?
            .iter()
            .position(|m| m.get("valid").and_then(serde_json::Value::as_bool) == Some(false))
    }

    /// Drop the trajectories of the modes after a demo's first invalid mode
    /// ([`Self::first_invalid_mode`]; the mode in which the object fell is kept): they start from an
    /// object already fallen, a state the planner never plans from, and would widen the
    /// normalisation of the object's columns (a fallen screwdriver's roll reaches π). Returns the
    /// number of trajectories dropped.
    pub fn drop_modes_after_invalid(&mut self) -> usize {
        let Some(last) = self.first_invalid_mode() else {
            return 0;
        };
        let keep: Vec<bool> = self.mode_index.iter().map(|&m| m <= last as i64).collect();
        let dropped = self.retain(&keep);
        if dropped > 0 {
            self.modes.truncate(last + 1);
        }
        dropped
    }

    /// Keep only the trajectories recorded at online step `k ≥ min_step` of their mode: the
    /// first `k` rows of such a trajectory are what the world executed (`docs/datagen.md`),
    /// the rest the particle's plan from there. Returns the number of trajectories dropped.
    pub fn keep_steps_from(&mut self, min_step: usize) -> usize {
        let min = i64::try_from(min_step).unwrap_or(i64::MAX);
        let keep: Vec<bool> = self.step.iter().map(|&k| k >= min).collect();
        self.retain(&keep)
    }

    /// Keep trajectory `i` where `keep[i]`; the number dropped.
    fn retain(&mut self, keep: &[bool]) -> usize {
        let dropped = keep.iter().filter(|k| !**k).count();
        if dropped == 0 {
            return 0;
        }
        let (floats, fingers) = (self.task.dims().floats(), self.task.dims().fingers);
        fn retain<T: Copy>(v: &mut Vec<T>, keep: &[bool], width: usize) {
            let old = std::mem::take(v);
            v.extend(
                old.chunks(width)
                    .zip(keep)
                    .filter(|(_, k)| **k)
                    .flat_map(|(c, _)| c.iter().copied()),
            );
        }
        retain(&mut self.trajectories, keep, floats);
        retain(&mut self.contexts, keep, fingers);
        retain(&mut self.mode_index, keep, 1);
        retain(&mut self.step, keep, 1);
        retain(&mut self.particle, keep, 1);
        dropped
    }

    /// Whether the demo holds no trajectory.
    pub fn is_empty(&self) -> bool {
        self.mode_index.is_empty()
    }

    /// The task's segment sizes.
    pub fn dims(&self) -> SegmentDims {
        self.task.dims()
    }

    /// Trajectory `i` (`T·D` floats).
    pub fn trajectory(&self, i: usize) -> &[f32] {
        let n = self.dims().floats();
        &self.trajectories[i * n..(i + 1) * n]
    }

    /// Context of trajectory `i` (`F` floats).
    pub fn context(&self, i: usize) -> &[f32] {
        let f = self.dims().fingers;
        &self.contexts[i * f..(i + 1) * f]
    }

    /// Check the record's internal consistency; `Err(reason)` says what is wrong.
    pub fn check(&self) -> std::result::Result<(), String> {
        let dims = self.dims();
        let n = self.len();
        if self.step.len() != n || self.particle.len() != n {
            return Err(format!(
                "mode_index, step and particle have {n}, {} and {} entries",
                self.step.len(),
                self.particle.len()
            ));
        }
        if self.trajectories.len() != n * dims.floats() {
            return Err(format!(
                "trajectories has {} floats, expected N·T·D = {n}·{}·{} = {}",
                self.trajectories.len(),
                dims.horizon,
                dims.dim(),
                n * dims.floats()
            ));
        }
        if self.contexts.len() != n * dims.fingers {
            return Err(format!(
                "contexts has {} floats, expected N·F = {n}·{} = {}",
                self.contexts.len(),
                dims.fingers,
                n * dims.fingers
            ));
        }
        if let Some(i) = self.trajectories.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "trajectories[{}] row {} column {} is not finite",
                i / dims.floats(),
                (i % dims.floats()) / dims.dim(),
                i % dims.dim()
            ));
        }
        let mut vectors = Vec::with_capacity(self.modes.len());
        for name in &self.modes {
            let id = self
                .task
                .mode_by_name(name)
                .map_err(|_| format!("mode {name:?} is not a {} mode", self.task.name()))?;
            let mode = self
                .task
                .contact_mode(id)
                .ok_or_else(|| format!("mode {name:?} has no contact vector"))?;
            let mut v = vec![0.0f32; dims.fingers];
            mode.write_signs(&mut v);
            vectors.push(v);
        }
        for i in 0..n {
            let m = self.mode_index[i];
            let v = usize::try_from(m)
                .ok()
                .and_then(|m| vectors.get(m))
                .ok_or_else(|| {
                    format!(
                        "mode_index[{i}] = {m} but {} modes were executed",
                        self.modes.len()
                    )
                })?;
            let c = self.context(i);
            if c != v.as_slice() {
                return Err(format!(
                    "contexts[{i}] = {c:?} is not the contact vector {v:?} of mode {:?}",
                    self.modes[m as usize]
                ));
            }
        }
        Ok(())
    }
}

/// Little-endian bytes of `f32`s (the safetensors byte order).
pub fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Little-endian bytes of `i64`s.
pub fn i64_bytes(v: &[i64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Encode a demo as safetensors bytes (see the crate docs for the layout).
pub fn encode_demo(path: &Path, demo: &DemoRecord) -> Result<Vec<u8>> {
    let bad = |reason: String| DatasetError::BadRecord {
        path: path.to_path_buf(),
        reason,
    };
    demo.check().map_err(bad)?;
    if let Some(k) = demo
        .metadata
        .keys()
        .find(|k| RESERVED_KEYS.contains(&k.as_str()))
    {
        return Err(bad(format!("metadata key {k:?} is reserved")));
    }
    let dims = demo.dims();
    let n = demo.len();
    let buffers = [
        (
            "trajectories",
            Dtype::F32,
            vec![n, dims.horizon, dims.dim()],
            f32_bytes(&demo.trajectories),
        ),
        (
            "contexts",
            Dtype::F32,
            vec![n, dims.fingers],
            f32_bytes(&demo.contexts),
        ),
        (
            "mode_index",
            Dtype::I64,
            vec![n],
            i64_bytes(&demo.mode_index),
        ),
        ("step", Dtype::I64, vec![n], i64_bytes(&demo.step)),
        ("particle", Dtype::I64, vec![n], i64_bytes(&demo.particle)),
    ];
    let mut views = Vec::with_capacity(buffers.len());
    for (name, dtype, shape, bytes) in &buffers {
        let view = TensorView::new(*dtype, shape.clone(), bytes)
            .map_err(|e| bad(format!("tensor {name}: {e}")))?;
        views.push((*name, view));
    }
    let modes = serde_json::to_string(&demo.modes).map_err(|e| bad(e.to_string()))?;
    let mut meta: HashMap<String, String> = demo
        .metadata
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    meta.insert("dips.dataset".into(), FORMAT_VERSION.into());
    meta.insert("task".into(), demo.task.name().into());
    meta.insert("seed".into(), demo.seed.to_string());
    meta.insert("modes".into(), modes);
    safetensors::serialize(views, Some(meta)).map_err(|e| bad(e.to_string()))
}

/// Write one demo to `path` atomically (temporary file, then rename). The record is checked
/// first; an inconsistent record is [`DatasetError::BadRecord`] and nothing is written.
pub fn write_demo(path: &Path, demo: &DemoRecord) -> Result<()> {
    let bytes = encode_demo(path, demo)?;
    dips_fs::write_atomic(path, &bytes).map_err(|source| DatasetError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Decode one demo file's bytes; `task` is the task the caller expects.
pub fn decode_demo(path: &Path, bytes: &[u8], task: Task) -> Result<DemoRecord> {
    let fmt = |reason: String| DatasetError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let (_, metadata) = SafeTensors::read_metadata(bytes)
        .map_err(|e| fmt(format!("not a safetensors file: {e}")))?;
    let st =
        SafeTensors::deserialize(bytes).map_err(|e| fmt(format!("not a safetensors file: {e}")))?;
    let meta = metadata
        .metadata()
        .clone()
        .ok_or_else(|| fmt("no __metadata__".into()))?;
    let key = |k: &str| {
        meta.get(k)
            .ok_or_else(|| fmt(format!("metadata key {k:?} is missing")))
    };
    let version = key("dips.dataset")?;
    if version != FORMAT_VERSION {
        return Err(fmt(format!(
            "dips.dataset is {version:?}, this reader knows {FORMAT_VERSION:?}"
        )));
    }
    let task_name = key("task")?;
    let file_task = task_name
        .parse::<Task>()
        .map_err(|_| fmt(format!("task {task_name:?} is unknown")))?;
    if file_task != task {
        return Err(fmt(format!(
            "task is {task_name:?}, expected {:?}",
            task.name()
        )));
    }
    let seed_s = key("seed")?;
    let seed: u64 = seed_s
        .parse()
        .map_err(|_| fmt(format!("seed {seed_s:?} is not an unsigned integer")))?;
    let modes_s = key("modes")?;
    let modes: Vec<String> = serde_json::from_str(modes_s).map_err(|e| {
        fmt(format!(
            "modes {modes_s:?} is not a JSON array of strings: {e}"
        ))
    })?;
    let dims = task.dims();

    let tensor = |name: &str, dtype: Dtype, shape: &[Option<usize>]| {
        let view = st
            .tensor(name)
            .map_err(|_| fmt(format!("tensor {name:?} is missing")))?;
        if view.dtype() != dtype {
            return Err(fmt(format!(
                "tensor {name:?} is {:?}, expected {dtype:?}",
                view.dtype()
            )));
        }
        let got = view.shape();
        let ok = got.len() == shape.len()
            && got
                .iter()
                .zip(shape)
                .all(|(g, w)| w.is_none_or(|w| w == *g));
        if !ok {
            let want: Vec<String> = shape
                .iter()
                .map(|w| w.map_or("N".into(), |w| w.to_string()))
                .collect();
            return Err(fmt(format!(
                "tensor {name:?} has shape {got:?}, expected [{}]",
                want.join(", ")
            )));
        }
        Ok(view)
    };
    let traj = tensor(
        "trajectories",
        Dtype::F32,
        &[None, Some(dims.horizon), Some(dims.dim())],
    )?;
    let n = traj.shape()[0];
    let ctx = tensor("contexts", Dtype::F32, &[Some(n), Some(dims.fingers)])?;
    let mi = tensor("mode_index", Dtype::I64, &[Some(n)])?;
    let step = tensor("step", Dtype::I64, &[Some(n)])?;
    let particle = tensor("particle", Dtype::I64, &[Some(n)])?;

    let f32s = |v: &TensorView<'_>| -> Vec<f32> {
        v.data()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let i64s = |v: &TensorView<'_>| -> Vec<i64> {
        v.data()
            .chunks_exact(8)
            .map(|c| i64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
            .collect()
    };
    let metadata = meta
        .iter()
        .filter(|(k, _)| !RESERVED_KEYS.contains(&k.as_str()))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let demo = DemoRecord {
        task,
        seed,
        modes,
        trajectories: f32s(&traj),
        contexts: f32s(&ctx),
        mode_index: i64s(&mi),
        step: i64s(&step),
        particle: i64s(&particle),
        metadata,
    };
    demo.check().map_err(fmt)?;
    Ok(demo)
}

/// Read one demo file.
pub fn read_demo(path: &Path, task: Task) -> Result<DemoRecord> {
    let bytes = std::fs::read(path).map_err(|source| DatasetError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    decode_demo(path, &bytes, task)
}

/// The demo files of a dataset directory (`DIR/demos/*.safetensors`), sorted by name.
pub fn demo_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let demos = dir.join("demos");
    let entries = std::fs::read_dir(&demos).map_err(|source| DatasetError::Io {
        path: demos.clone(),
        source,
    })?;
    let mut files = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|source| DatasetError::Io {
            path: demos.clone(),
            source,
        })?;
        let path = entry.path();
        if path.extension().is_some_and(|e| e == "safetensors") && path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// A whole dataset: every demo of one task.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The task.
    pub task: Task,
    /// The demos, sorted by seed.
    pub demos: Vec<DemoRecord>,
    /// The file each demo came from (same order), empty for an in-memory dataset.
    pub files: Vec<PathBuf>,
}

impl Dataset {
    /// Where every demo's card pushes aimed ([`DemoRecord::card_goals`]); an error naming two
    /// demos that differ, or one whose settings name no card goals, since models trained on a
    /// mix would plan neither.
    pub fn card_goals(&self) -> Result<CardGoals> {
        let mut first: Option<(u64, CardGoals)> = None;
        for (i, d) in self.demos.iter().enumerate() {
            let path = self.files.get(i).cloned().unwrap_or_default();
            let goals = d.card_goals().ok_or_else(|| DatasetError::Format {
                path: path.clone(),
                reason: format!(
                    "{EXEC_SETTINGS_KEY} names no card goals (expected {})",
                    CardGoals::NAMES.join(" or ")
                ),
            })?;
            match first {
                None => first = Some((d.seed, goals)),
                Some((seed, g)) if g != goals => {
                    return Err(DatasetError::Format {
                        path,
                        reason: format!(
                            "demo {} was made with card goals {goals}, demo {seed} with {g}; \
                             a dataset holds one kind (dips datagen --card-goals)",
                            d.seed
                        ),
                    });
                }
                Some(_) => {}
            }
        }
        Ok(first.map_or(CardGoals::default(), |(_, g)| g))
    }
}

/// Demo indices of a train/held-out split.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Split {
    /// Indices into [`Dataset::demos`] used for training.
    pub train: Vec<usize>,
    /// Indices held out for evaluation.
    pub held_out: Vec<usize>,
}

/// SplitMix64 finaliser: the hash that orders demo seeds for the split.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Dataset {
    /// A dataset from demos in memory (sorted by seed; seeds must be distinct).
    pub fn from_demos(task: Task, mut demos: Vec<DemoRecord>) -> Result<Self> {
        demos.sort_by_key(|d| d.seed);
        for (i, d) in demos.iter().enumerate() {
            let path = PathBuf::from(format!("<demo {i}>"));
            if d.task != task {
                return Err(DatasetError::Format {
                    path,
                    reason: format!("task is {:?}, expected {:?}", d.task.name(), task.name()),
                });
            }
            d.check()
                .map_err(|reason| DatasetError::Format { path, reason })?;
        }
        if let Some(w) = demos.windows(2).find(|w| w[0].seed == w[1].seed) {
            return Err(DatasetError::DuplicateSeed {
                seed: w[0].seed,
                first: PathBuf::from("<memory>"),
                second: PathBuf::from("<memory>"),
            });
        }
        Ok(Self {
            task,
            demos,
            files: Vec::new(),
        })
    }

    /// The task's segment sizes.
    pub fn dims(&self) -> SegmentDims {
        self.task.dims()
    }

    /// [`DemoRecord::drop_modes_after_invalid`] on every demo; the trajectories dropped.
    pub fn drop_modes_after_invalid(&mut self) -> usize {
        self.demos
            .iter_mut()
            .map(DemoRecord::drop_modes_after_invalid)
            .sum()
    }

    /// [`DemoRecord::keep_steps_from`] on every demo; the trajectories dropped.
    pub fn keep_steps_from(&mut self, min_step: usize) -> usize {
        self.demos
            .iter_mut()
            .map(|d| d.keep_steps_from(min_step))
            .sum()
    }

    /// Trajectories over all demos.
    pub fn samples(&self) -> usize {
        self.demos.iter().map(DemoRecord::len).sum()
    }

    /// Split the demos by seed: `round(held_out_fraction · demos)` demos are held out (at
    /// least one and at most all but one when the fraction is positive and there are two or
    /// more demos). The held-out demos are those whose seeds hash ([`mix64`]) lowest, so the
    /// split depends on the set of seeds only, not on file names or their order, and adding
    /// demos moves few of the others.
    pub fn split(&self, held_out_fraction: f64) -> Split {
        let n = self.demos.len();
        let frac = if held_out_fraction.is_finite() {
            held_out_fraction.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut k = (frac * n as f64).round() as usize;
        if frac > 0.0 && n >= 2 {
            k = k.clamp(1, n - 1);
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&i| (mix64(self.demos[i].seed), self.demos[i].seed));
        let mut held_out: Vec<usize> = order[..k].to_vec();
        let mut train: Vec<usize> = order[k..].to_vec();
        held_out.sort_unstable();
        train.sort_unstable();
        Split { train, held_out }
    }
}

/// Read every demo of `DIR/demos/*.safetensors` for `task`. Errors name the file and what is
/// wrong with it; a directory without demo files is [`DatasetError::Empty`].
pub fn read_dir(dir: &Path, task: Task) -> Result<Dataset> {
    let files = demo_files(dir)?;
    if files.is_empty() {
        return Err(DatasetError::Empty {
            dir: dir.to_path_buf(),
        });
    }
    let mut pairs = Vec::with_capacity(files.len());
    for f in files {
        let d = read_demo(&f, task)?;
        pairs.push((d, f));
    }
    pairs.sort_by_key(|(d, _)| d.seed);
    if let Some(w) = pairs.windows(2).find(|w| w[0].0.seed == w[1].0.seed) {
        return Err(DatasetError::DuplicateSeed {
            seed: w[0].0.seed,
            first: w[0].1.clone(),
            second: w[1].1.clone(),
        });
    }
    let (demos, files) = pairs.into_iter().unzip();
    Ok(Dataset { task, demos, files })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn demo(seed: u64) -> DemoRecord {
        let task = Task::Card;
        let dims = task.dims();
        let n = 3;
        DemoRecord {
            task,
            seed,
            modes: vec!["index".into(), "regrasp".into()],
            trajectories: (0..n * dims.floats()).map(|i| i as f32 * 0.01).collect(),
            contexts: vec![1.0, -1.0, 1.0, -1.0, -1.0, -1.0],
            mode_index: vec![0, 0, 1],
            step: vec![0, 1, 0],
            particle: vec![0, 0, 0],
            metadata: BTreeMap::from([("outcome".to_string(), "ok".to_string())]),
        }
    }

    fn tmpdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("dips-dataset-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("demos")).unwrap();
        d
    }

    #[test]
    fn round_trip_and_split() {
        let dir = tmpdir("rt");
        for s in [5u64, 3, 9, 1] {
            write_demo(&dir.join(format!("demos/d{s}.safetensors")), &demo(s)).unwrap();
        }
        let ds = read_dir(&dir, Task::Card).unwrap();
        assert_eq!(
            ds.demos.iter().map(|d| d.seed).collect::<Vec<_>>(),
            [1, 3, 5, 9]
        );
        assert_eq!(ds.demos[0], demo(1));
        assert_eq!(ds.samples(), 12);
        let s = ds.split(0.1);
        assert_eq!((s.train.len(), s.held_out.len()), (3, 1));
        assert_eq!(s, ds.split(0.1));
        assert_eq!(ds.split(0.0).held_out.len(), 0);
        // Wrong task: a typed error naming the file.
        let e = read_dir(&dir, Task::Screwdriver).unwrap_err();
        assert!(matches!(e, DatasetError::Format { .. }), "{e}");
        assert!(e.to_string().contains("d1.safetensors"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_files_and_records_are_typed_errors() {
        let dir = tmpdir("bad");
        assert!(matches!(
            read_dir(&dir, Task::Card),
            Err(DatasetError::Empty { .. })
        ));
        let p = dir.join("demos/x.safetensors");
        std::fs::write(&p, b"not safetensors").unwrap();
        let e = read_dir(&dir, Task::Card).unwrap_err();
        assert!(e.to_string().contains("x.safetensors"), "{e}");

        let mut d = demo(1);
        d.contexts[0] = -1.0;
        let e = write_demo(&p, &d).unwrap_err();
        assert!(matches!(e, DatasetError::BadRecord { .. }), "{e}");
        assert!(e.to_string().contains("contact vector"), "{e}");
        let mut d = demo(1);
        d.trajectories.pop();
        assert!(write_demo(&p, &d).is_err());
        let mut d = demo(1);
        d.modes[0] = "turn".into();
        assert!(write_demo(&p, &d).unwrap_err().to_string().contains("turn"));

        // Two files with one seed.
        write_demo(&p, &demo(4)).unwrap();
        write_demo(&dir.join("demos/y.safetensors"), &demo(4)).unwrap();
        assert!(matches!(
            read_dir(&dir, Task::Card),
            Err(DatasetError::DuplicateSeed { seed: 4, .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[cfg(test)]
mod invalid_mode_tests {
    use std::collections::BTreeMap;

    use super::*;
    use dips_kernel::mode::Task;

    /// A card demo of three modes, two trajectories each, whose trajectories hold their index.
    fn demo(outcome: Option<&str>) -> DemoRecord {
        let task = Task::Card;
        let dims = task.dims();
        let n = 6;
        let modes = ["index", "middle", "both"];
        let mut contexts = Vec::new();
        for i in 0..n {
            let id = task.mode_by_name(modes[i / 2]).unwrap();
            let mut c = [0.0f32; 2];
            task.modes()[id.index()].mode.write_signs(&mut c);
            contexts.extend_from_slice(&c);
        }
        let mut metadata = BTreeMap::new();
        if let Some(o) = outcome {
            metadata.insert("outcome".to_string(), o.to_string());
        }
        DemoRecord {
            task,
            seed: 1,
            modes: modes.iter().map(|m| m.to_string()).collect(),
            trajectories: (0..n)
                .flat_map(|i| std::iter::repeat_n(i as f32, dims.floats()))
                .collect(),
            contexts,
            mode_index: vec![0, 0, 1, 1, 2, 2],
            step: vec![0, 1, 0, 1, 0, 1],
            particle: vec![0; n],
            metadata,
        }
    }

    /// The modes after the first invalid one are dropped with every per-trajectory array;
    /// the mode in which the object fell is kept; demos without a record or without an
    /// invalid mode are untouched.
    #[test]
    fn modes_after_the_fall_are_dropped() {
        let fell = r#"{"valid":false,"modes":[{"valid":true},{"valid":false},{"valid":true}]}"#;
        let mut d = demo(Some(fell));
        assert_eq!(d.first_invalid_mode(), Some(1));
        assert_eq!(d.drop_modes_after_invalid(), 2);
        let dims = d.task.dims();
        assert_eq!(d.len(), 4);
        assert_eq!(d.mode_index, [0, 0, 1, 1]);
        assert_eq!(d.step, [0, 1, 0, 1]);
        assert_eq!(d.modes, ["index", "middle"]);
        assert_eq!(d.trajectories.len(), 4 * dims.floats());
        assert_eq!(d.trajectories[3 * dims.floats()], 3.0);
        assert_eq!(d.contexts.len(), 4 * dims.fingers);
        d.check().unwrap();

        let fine = r#"{"valid":true,"modes":[{"valid":true},{"valid":true},{"valid":true}]}"#;
        for outcome in [Some(fine), None, Some("not json")] {
            let mut d = demo(outcome);
            assert_eq!(d.first_invalid_mode(), None);
            assert_eq!(d.drop_modes_after_invalid(), 0);
            assert_eq!(d.len(), 6);
        }
    }

    /// Only the trajectories of online step ≥ the bound stay, with every per-trajectory
    /// array and the modes' names; a bound of 0 keeps all, one past the last step keeps none.
    #[test]
    fn early_steps_are_dropped() {
        let mut d = demo(None);
        let dims = d.task.dims();
        assert_eq!(d.keep_steps_from(0), 0);
        assert_eq!(d.keep_steps_from(1), 3);
        assert_eq!(d.len(), 3);
        assert_eq!(d.mode_index, [0, 1, 2]);
        assert_eq!(d.step, [1, 1, 1]);
        assert_eq!(d.particle, [0, 0, 0]);
        assert_eq!(d.modes, ["index", "middle", "both"]);
        let first: Vec<f32> = (0..3).map(|i| d.trajectory(i)[0]).collect();
        assert_eq!(first, [1.0, 3.0, 5.0]);
        assert_eq!(d.contexts.len(), 3 * dims.fingers);
        d.check().unwrap();
        assert_eq!(d.keep_steps_from(2), 3);
        assert!(d.is_empty());
    }
}
