//! Pre-registration of an evaluation (`docs/results/PROTOCOL.md`): `dips eval --protocol FILE`
//! runs only what a committed protocol file says, and labels its results.
//!
//! A protocol ([`Protocol`]) holds a name, the resolved settings `eval.json` holds
//! ([`EvalFile`]: task, methods, seeds, sampler, budgets, mode limit, cost-to-come, search
//! depth, engine) and the sha256 of every model file the run reads ([`model_files`]). Before
//! the first episode, [`ProtocolFile::register`] checks that this run's settings and models are
//! the protocol's (the first difference is named), that the file is committed (tracked and
//! equal to `HEAD`), and finds whether the seed range is already spent: a `registration.json`
//! committed anywhere in the protocol's repository, for the same task, on an overlapping range.
//! The answer is a [`Registration`], which the run writes as `DIR/registration.json`
//! ([`claim_registration`]: a directory holds the results of one registration only, so a
//! rerun never writes into a registered run's directory) and `results.json` copies.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

use dips_onnx::Role;
use dips_planning::online::Method;
use dips_planning::{POLICY_DIR, PRIOR_FILE, model_file};
use dips_world::scenes::SceneKind;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::settings::{EVAL_FILE, EvalFile, EvalSettings};

/// The version of the protocol file format this build reads and writes.
pub const PROTOCOL_FORMAT: u32 = 1;

/// The file of a directory's registration.
pub const REGISTRATION_FILE: &str = "registration.json";

/// Seeds below this are for tuning (`docs/results/PROTOCOL.md`): a protocol on them gives
/// [`RegistrationStatus::Tuning`] results, never registered ones.
pub const FIRST_EVALUATION_SEED: u64 = 1000;

/// Why a protocol cannot be read, written or run. Every message is one line and names the
/// file, the field or the setting.
#[derive(Debug, thiserror::Error)]
pub enum ProtocolError {
    /// The file cannot be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not JSON of a protocol's shape.
    #[error("{path} is not a protocol file: {source}")]
    Json {
        /// The file.
        path: PathBuf,
        /// What serde found.
        #[source]
        source: serde_json::Error,
    },
    /// A field every protocol spells out is missing (a protocol written by hand, not from a
    /// run's settings).
    #[error("{path}: missing field `{field}`")]
    MissingField {
        /// The file.
        path: PathBuf,
        /// The field (`eval.episode.sampler`).
        field: String,
    },
    /// A field no protocol has (a typo would otherwise be ignored).
    #[error("{path}: unknown field `{field}`")]
    UnknownField {
        /// The file.
        path: PathBuf,
        /// The field.
        field: String,
    },
    /// A value that no run can have (unknown task or method, a bad hash, ...).
    #[error("{path}: `{field}` {why}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The field.
        field: String,
        /// What is wrong and what is allowed.
        why: String,
    },
    /// `dips eval --write-protocol` does not overwrite.
    #[error("{0} exists; a protocol is written once (remove it first, or choose another file)")]
    Exists(PathBuf),
    /// This run's settings are not the protocol's.
    #[error("{setting} is {protocol} in the protocol and {run} in this run")]
    Differs {
        /// The setting, as its field in `eval.json` (`episode.sampler`, `first_seed`).
        setting: String,
        /// Its value in the protocol, as JSON.
        protocol: String,
        /// Its value in this run, as JSON.
        run: String,
    },
    /// A model file's content is not the protocol's.
    #[error("{file}: sha256 {found}, the protocol's is {expected}; run with the protocol's models")]
    ModelHash {
        /// The model file.
        file: PathBuf,
        /// Its hash in the protocol.
        expected: String,
        /// Its hash here.
        found: String,
    },
    /// A model file the protocol hashed is not there.
    #[error("{file} is missing; the protocol has it with sha256 {expected}")]
    ModelMissing {
        /// The model file.
        file: PathBuf,
        /// Its hash in the protocol.
        expected: String,
    },
    /// This run reads a model file the protocol does not name.
    #[error("{file} (sha256 {found}) is read by this run but is not in the protocol")]
    ModelNotInProtocol {
        /// The model file.
        file: PathBuf,
        /// Its hash here.
        found: String,
    },
    /// git could not be run.
    #[error("cannot run `git {args}` in {dir}: {why}")]
    Git {
        /// Where.
        dir: PathBuf,
        /// Its arguments.
        args: String,
        /// Why.
        why: String,
    },
    /// The protocol file is not committed as it is.
    #[error(
        "{path} {why}: commit it before the run (`git add {path} && git commit`), or run it \
         uncommitted to label the results unregistered"
    )]
    NotCommitted {
        /// The protocol file.
        path: PathBuf,
        /// What git says (`is not tracked by git`, `differs from HEAD`).
        why: String,
    },
    /// The output directory holds registered results and this run has no protocol.
    #[error(
        "{dir} {holds}; a run without a protocol would mix into them (resume with the \
         protocol {protocol}): use another output directory"
    )]
    Unregistered {
        /// The output directory.
        dir: PathBuf,
        /// What it holds.
        holds: String,
        /// The protocol file of its registration.
        protocol: String,
    },
    /// The output directory holds results of another registration, or none.
    #[error("{dir} {holds}; {why}: use another output directory")]
    Directory {
        /// The output directory.
        dir: PathBuf,
        /// What it holds.
        holds: String,
        /// Why this run may not write there.
        why: String,
    },
    /// A registration file cannot be read.
    #[error("{path} is not a registration file: {source}")]
    Registration {
        /// The file.
        path: PathBuf,
        /// What serde found.
        #[source]
        source: serde_json::Error,
    },
}

/// A protocol file: what a registered evaluation runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Protocol {
    /// [`PROTOCOL_FORMAT`].
    pub format: u32,
    /// Its name (quoted with the results).
    pub name: String,
    /// The resolved settings, as `eval.json` holds them. `episode.models` is where the models
    /// were when the protocol was written, for people: the models are compared by
    /// [`Protocol::models`], not by path.
    pub eval: EvalFile,
    /// sha256 (lowercase hex) of every model file the run reads, by its path in the models
    /// directory ([`model_files`]).
    pub models: BTreeMap<String, String>,
}

/// The files under a models directory that a run of `methods` reads, by their path in it:
/// the denoiser, the discriminator and the prior (when present; the planner uses the paper's
/// without it) for every method but `csvto-sampled`, and the policy's denoiser for
/// `diffusion-policy`.
pub fn model_files(methods: &[Method], dir: &Path) -> Vec<String> {
    let mut files = Vec::new();
    if methods.iter().any(|m| m.needs_models()) {
        files.push(model_file(Role::Denoiser).to_string());
        files.push(model_file(Role::Discriminator).to_string());
        if dir.join(PRIOR_FILE).is_file() {
            files.push(PRIOR_FILE.to_string());
        }
    }
    if methods.contains(&Method::DiffusionPolicy) {
        files.push(format!("{POLICY_DIR}/{}", model_file(Role::Denoiser)));
    }
    files
}

/// The sha256 of a file's bytes, lowercase hex.
pub fn sha256_file(path: &Path) -> Result<String, ProtocolError> {
    let io = |source| ProtocolError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buf).map_err(io)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    Ok(hex(&hasher.finalize()))
}

/// The sha256 of some bytes, lowercase hex.
pub fn sha256_bytes(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The hashes of the model files a run of `methods` reads from `dir` ([`model_files`]).
pub fn hash_models(
    methods: &[Method],
    dir: &Path,
) -> Result<BTreeMap<String, String>, ProtocolError> {
    model_files(methods, dir)
        .into_iter()
        .map(|f| Ok((f.clone(), sha256_file(&dir.join(&f))?)))
        .collect()
}

/// `value` with `eval.episode.models` (a path, not compared) blanked.
fn without_models_path(mut value: serde_json::Value) -> serde_json::Value {
    if let Some(episode) = value.get_mut("episode").and_then(|e| e.as_object_mut()) {
        episode.insert("models".into(), serde_json::Value::Null);
    }
    value
}

/// The first key of `typed` (what the file parsed to, written back) missing from `raw` (the
/// file), or of `raw` missing from `typed`, as (`field`, whether it is missing).
fn key_difference(
    raw: &serde_json::Value,
    typed: &serde_json::Value,
    at: &str,
) -> Option<(String, bool)> {
    let (Some(r), Some(t)) = (raw.as_object(), typed.as_object()) else {
        return None;
    };
    let name = |k: &str| {
        if at.is_empty() {
            k.to_string()
        } else {
            format!("{at}.{k}")
        }
    };
    for (k, tv) in t {
        match r.get(k) {
            None => return Some((name(k), true)),
            Some(rv) => {
                if let Some(d) = key_difference(rv, tv, &name(k)) {
                    return Some(d);
                }
            }
        }
    }
    r.keys()
        .find(|k| !t.contains_key(*k))
        .map(|k| (name(k), false))
}

impl Protocol {
    /// The protocol of `settings` (resolved as a run resolves them) named `name`, with the
    /// hashes of the models it reads.
    pub fn new(name: &str, settings: &EvalSettings) -> Result<Self, ProtocolError> {
        let mut eval = settings.eval_file();
        // A path for people, relative to the current directory when under it.
        let models = settings
            .models
            .canonicalize()
            .unwrap_or_else(|_| settings.models.clone());
        eval.episode.models = std::env::current_dir()
            .ok()
            .and_then(|cwd| cwd.canonicalize().ok())
            .and_then(|cwd| models.strip_prefix(cwd).ok().map(Path::to_path_buf))
            .unwrap_or(models);
        Ok(Self {
            format: PROTOCOL_FORMAT,
            name: name.to_string(),
            eval,
            models: hash_models(&settings.methods, &settings.models)?,
        })
    }

    /// Parse and check the text of the protocol file `path`: every field present and known,
    /// a known task, known methods (at least one, none twice), at least one trial, a sampler
    /// that parses, and hashes that are sha256 hex.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ProtocolError> {
        let json = |source| ProtocolError::Json {
            path: path.to_path_buf(),
            source,
        };
        let raw: serde_json::Value = serde_json::from_str(text).map_err(json)?;
        // From the text, so that a bad value (an unknown task, method, sampler, ...) is named
        // with its line.
        let protocol: Protocol = serde_json::from_str(text).map_err(json)?;
        let invalid = |field: &str, why: String| ProtocolError::Invalid {
            path: path.to_path_buf(),
            field: field.to_string(),
            why,
        };
        if protocol.format != PROTOCOL_FORMAT {
            return Err(invalid(
                "format",
                format!(
                    "is {}; this build reads format {PROTOCOL_FORMAT}",
                    protocol.format
                ),
            ));
        }
        let typed = serde_json::to_value(&protocol).map_err(json)?;
        if let Some((field, missing)) = key_difference(&raw, &typed, "") {
            let path = path.to_path_buf();
            return Err(if missing {
                ProtocolError::MissingField { path, field }
            } else {
                ProtocolError::UnknownField { path, field }
            });
        }
        if protocol.name.trim().is_empty() {
            return Err(invalid("name", "is empty".into()));
        }
        let e = &protocol.eval;
        if e.methods.is_empty() {
            return Err(invalid("eval.methods", "is empty".into()));
        }
        for (i, m) in e.methods.iter().enumerate() {
            if e.methods[..i].contains(m) {
                return Err(invalid("eval.methods", format!("names {m} twice")));
            }
        }
        if e.trials == 0 {
            return Err(invalid("eval.trials", "is 0; at least 1".into()));
        }
        if e.first_seed.checked_add(e.trials as u64).is_none() {
            return Err(invalid(
                "eval.first_seed",
                "+ trials overflows the seed range".into(),
            ));
        }
        for (file, hash) in &protocol.models {
            if hash.len() != 64 || !hash.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f')) {
                return Err(invalid(
                    &format!("models.{file}"),
                    format!("is {hash:?}, not a sha256 (64 lowercase hex digits)"),
                ));
            }
        }
        Ok(protocol)
    }

    /// The protocol's task.
    pub fn task(&self) -> SceneKind {
        self.eval.episode.task
    }

    /// The protocol's methods, in table order.
    pub fn methods(&self) -> &[Method] {
        &self.eval.methods
    }

    /// Whether any of its seeds is below [`FIRST_EVALUATION_SEED`] (a tuning protocol).
    pub fn tuning(&self) -> bool {
        self.eval.first_seed < FIRST_EVALUATION_SEED
    }

    /// Write the protocol to `path` (pretty JSON, a final newline); never over an existing file.
    pub fn write(&self, path: &Path) -> Result<(), ProtocolError> {
        if path.exists() {
            return Err(ProtocolError::Exists(path.to_path_buf()));
        }
        let io = |source| ProtocolError::Io {
            path: path.to_path_buf(),
            source,
        };
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(io)?;
        }
        let mut text =
            serde_json::to_string_pretty(self).map_err(|source| ProtocolError::Json {
                path: path.to_path_buf(),
                source,
            })?;
        text.push('\n');
        std::fs::write(path, text).map_err(io)
    }

    /// Check that `settings` are the protocol's: task, methods, seeds and every episode
    /// setting (the models' path aside); the first difference is named by its field.
    pub fn check_settings(&self, settings: &EvalSettings) -> Result<(), ProtocolError> {
        let value = |e: &EvalFile| {
            serde_json::to_value(e)
                .map(without_models_path)
                .map_err(|source| ProtocolError::Json {
                    path: PathBuf::from(EVAL_FILE),
                    source,
                })
        };
        let (ours, run) = (value(&self.eval)?, value(&settings.eval_file())?);
        if ours != run {
            let (field, protocol, run) = dips_batch::first_difference(&ours, &run, "");
            return Err(ProtocolError::Differs {
                setting: field.trim_start_matches('.').to_string(),
                protocol,
                run,
            });
        }
        Ok(())
    }

    /// Check that the model files `settings` reads have the protocol's hashes.
    pub fn check_models(&self, settings: &EvalSettings) -> Result<(), ProtocolError> {
        let dir = &settings.models;
        let wanted = model_files(&settings.methods, dir);
        for (file, expected) in &self.models {
            let path = dir.join(file);
            if !path.is_file() {
                return Err(ProtocolError::ModelMissing {
                    file: path,
                    expected: expected.clone(),
                });
            }
            let found = sha256_file(&path)?;
            if &found != expected {
                return Err(ProtocolError::ModelHash {
                    file: path,
                    expected: expected.clone(),
                    found,
                });
            }
        }
        if let Some(extra) = wanted.iter().find(|f| !self.models.contains_key(*f)) {
            let file = dir.join(extra);
            return Err(ProtocolError::ModelNotInProtocol {
                found: sha256_file(&file)?,
                file,
            });
        }
        Ok(())
    }
}

/// What the results of a run under a protocol are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RegistrationStatus {
    /// The first run of a committed protocol on a fresh range: the result to quote.
    Registered,
    /// A committed protocol whose range was already spent (a registration of the same task on
    /// an overlapping range is committed): never replaces the registered result.
    Rerun,
    /// A protocol with seeds below [`FIRST_EVALUATION_SEED`]: tuning, never registered.
    Tuning,
    /// A protocol that was not committed (`--protocol-uncommitted`).
    Unregistered,
}

impl RegistrationStatus {
    /// Its name in `registration.json`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Registered => "registered",
            Self::Rerun => "rerun",
            Self::Tuning => "tuning",
            Self::Unregistered => "unregistered",
        }
    }
}

/// Where and on what a run was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunStamp {
    /// `HEAD` of the protocol's repository (`None` outside one).
    pub commit: Option<String>,
    /// Whether its tracked files differed from `HEAD` (`None` outside a repository).
    pub dirty: Option<bool>,
    /// The CPU ([`cpu_model`]).
    pub cpu: String,
}

/// `registration.json` of an evaluation directory, and the `registration` block of its
/// `results.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Registration {
    /// What the results are.
    pub status: RegistrationStatus,
    /// The protocol file, as given.
    pub protocol: String,
    /// The protocol's name.
    pub name: String,
    /// sha256 of the protocol file's bytes.
    pub protocol_sha256: String,
    /// `HEAD`, dirtiness and CPU of the run that claimed the directory.
    #[serde(flatten)]
    pub stamp: RunStamp,
    /// The run's resolved settings (its models' path included).
    pub settings: EvalFile,
    /// The models' hashes (equal to the protocol's).
    pub models: BTreeMap<String, String>,
    /// For a rerun: the committed registrations that spent the range.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub spent_by: Vec<String>,
    /// Later runs into the directory (resumes, shards) on another commit, tree state or CPU
    /// (shards claiming at once may each keep only their own).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub later_runs: Vec<RunStamp>,
}

/// The CPU's model name (`/proc/cpuinfo`'s first `model name`), `unknown` where there is none.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines().find_map(|l| {
                let (k, v) = l.split_once(':')?;
                (k.trim() == "model name").then(|| v.trim().to_string())
            })
        })
        .unwrap_or_else(|| "unknown".into())
}

/// The directory git runs in for `path` (its parent, or `.`).
fn dir_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `git -C dir ARGS`: its output when it exited 0, `None` when it failed; an error when git
/// cannot be started.
fn git(dir: &Path, args: &[&str]) -> Result<Option<Vec<u8>>, ProtocolError> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .map_err(|e| ProtocolError::Git {
            dir: dir.to_path_buf(),
            args: args.join(" "),
            why: e.to_string(),
        })?;
    Ok(out.status.success().then_some(out.stdout))
}

fn trimmed(bytes: Vec<u8>) -> String {
    String::from_utf8_lossy(&bytes).trim().to_string()
}

/// Check that the file `path` is committed: inside a git repository, tracked, and equal to its
/// version in `HEAD`.
pub fn check_committed(path: &Path) -> Result<(), ProtocolError> {
    let dir = dir_of(path);
    let not = |why: &str| ProtocolError::NotCommitted {
        path: path.to_path_buf(),
        why: why.to_string(),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if git(&dir, &["rev-parse", "--show-toplevel"])?.is_none() {
        return Err(not("is not inside a git repository"));
    }
    let full = git(
        &dir,
        &["ls-files", "--full-name", "--error-unmatch", "--", &name],
    )?
    .map(trimmed)
    .filter(|f| !f.is_empty())
    .ok_or_else(|| not("is not tracked by git"))?;
    let committed = git(&dir, &["show", &format!("HEAD:{full}")])?
        .ok_or_else(|| not("is not in HEAD (added but not committed)"))?;
    let here = std::fs::read(path).map_err(|source| ProtocolError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if committed != here {
        return Err(not("differs from HEAD (changed since its last commit)"));
    }
    Ok(())
}

/// `HEAD` and dirtiness of the repository holding `dir` (both `None` outside one), and this
/// machine's CPU.
pub fn run_stamp(dir: &Path) -> Result<RunStamp, ProtocolError> {
    let commit = git(dir, &["rev-parse", "--verify", "HEAD"])?.map(trimmed);
    let dirty = match commit {
        Some(_) => {
            git(dir, &["status", "--porcelain", "--untracked-files=no"])?.map(|out| !out.is_empty())
        }
        None => None,
    };
    Ok(RunStamp {
        commit,
        dirty,
        cpu: cpu_model(),
    })
}

/// Every `registration.json` committed in `HEAD` of the repository holding `dir`, with its
/// path in the repository (none outside a repository or before the first commit).
pub fn committed_registrations(dir: &Path) -> Result<Vec<(String, Registration)>, ProtocolError> {
    let Some(listing) = git(
        dir,
        &["ls-tree", "-r", "--name-only", "--full-tree", "HEAD"],
    )?
    else {
        return Ok(Vec::new());
    };
    let listing = String::from_utf8_lossy(&listing).into_owned();
    let mut found = Vec::new();
    for file in listing
        .lines()
        .filter(|f| *f == REGISTRATION_FILE || f.ends_with(&format!("/{REGISTRATION_FILE}")))
    {
        let Some(bytes) = git(dir, &["show", &format!("HEAD:{file}")])? else {
            continue;
        };
        let registration =
            serde_json::from_slice(&bytes).map_err(|source| ProtocolError::Registration {
                path: PathBuf::from(format!("HEAD:{file}")),
                source,
            })?;
        found.push((file.to_string(), registration));
    }
    Ok(found)
}

/// Whether the seed ranges of two evaluations overlap.
fn overlap(a: &EvalFile, b: &EvalFile) -> bool {
    let end = |e: &EvalFile| e.first_seed.saturating_add(e.trials as u64);
    a.first_seed < end(b) && b.first_seed < end(a)
}

/// A protocol file as read: its path, the sha256 of its bytes and what it says.
#[derive(Debug, Clone)]
pub struct ProtocolFile {
    /// The file, as given.
    pub path: PathBuf,
    /// sha256 of its bytes.
    pub sha256: String,
    /// Its content.
    pub protocol: Protocol,
}

impl ProtocolFile {
    /// Read and check the protocol file `path` ([`Protocol::parse`]).
    pub fn read(path: &Path) -> Result<Self, ProtocolError> {
        let bytes = std::fs::read(path).map_err(|source| ProtocolError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let text = String::from_utf8_lossy(&bytes);
        Ok(Self {
            path: path.to_path_buf(),
            sha256: sha256_bytes(&bytes),
            protocol: Protocol::parse(&text, path)?,
        })
    }

    /// Register a run of `settings` under this protocol, before its first episode: its
    /// settings and models must be the protocol's ([`Protocol::check_settings`],
    /// [`Protocol::check_models`]) and the file committed ([`check_committed`]; with
    /// `allow_uncommitted` an uncommitted file gives unregistered results). The status:
    /// tuning for seeds below [`FIRST_EVALUATION_SEED`], else unregistered when not committed,
    /// else a rerun when a registration of the same task on an overlapping range, run after
    /// this protocol was committed, is committed in the protocol's repository, else registered.
    pub fn register(
        &self,
        settings: &EvalSettings,
        allow_uncommitted: bool,
    ) -> Result<Registration, ProtocolError> {
        Ok(self.register_with_spending(settings, allow_uncommitted)?.0)
    }

    /// [`ProtocolFile::register`], with the committed registrations that spent the range
    /// (file in the repository, registration) that its `spent_by` describes.
    fn register_with_spending(
        &self,
        settings: &EvalSettings,
        allow_uncommitted: bool,
    ) -> Result<(Registration, Vec<(String, Registration)>), ProtocolError> {
        self.protocol.check_settings(settings)?;
        self.protocol.check_models(settings)?;
        let committed = match check_committed(&self.path) {
            Ok(()) => true,
            Err(ProtocolError::NotCommitted { .. }) if allow_uncommitted => false,
            Err(e) => return Err(e),
        };
        let dir = dir_of(&self.path);
        let mut spending = Vec::new();
        if !self.protocol.tuning() {
            let registered_at = self.registered_at()?;
            for (file, r) in committed_registrations(&dir)? {
                if self.spent_by(&r, registered_at.as_deref())? {
                    spending.push((file, r));
                }
            }
        }
        let spent_by: Vec<String> = spending
            .iter()
            .map(|(file, r)| {
                format!(
                    "{file} ({} of {}, seeds {}–{})",
                    r.status.name(),
                    r.name,
                    r.settings.first_seed,
                    r.settings.first_seed + r.settings.trials.saturating_sub(1) as u64
                )
            })
            .collect();
        let status = if self.protocol.tuning() {
            RegistrationStatus::Tuning
        } else if !committed {
            RegistrationStatus::Unregistered
        } else if !spent_by.is_empty() {
            RegistrationStatus::Rerun
        } else {
            RegistrationStatus::Registered
        };
        let registration = Registration {
            status,
            protocol: self.path.display().to_string(),
            name: self.protocol.name.clone(),
            protocol_sha256: self.sha256.clone(),
            stamp: run_stamp(&dir)?,
            settings: settings.eval_file(),
            models: self.protocol.models.clone(),
            spent_by,
            later_runs: Vec::new(),
        };
        Ok((registration, spending))
    }

    /// Whether the committed registration `r` spends this protocol's range: anything but
    /// tuning, of the same task on an overlapping seed range, whose run started after this
    /// protocol was committed in its present form (`registered_at`, the last commit that
    /// touched the file; `None` outside a repository), or of this very protocol. Another
    /// protocol committed before `r`'s first episode was fixed before any of `r`'s outcomes
    /// could be seen: the arms of one experiment registered together (a transfer experiment's
    /// hands, several trained models) share their seeds (`docs/results/PROTOCOL.md`).
    fn spent_by(
        &self,
        r: &Registration,
        registered_at: Option<&str>,
    ) -> Result<bool, ProtocolError> {
        if r.status == RegistrationStatus::Tuning
            || r.settings.episode.task != self.protocol.eval.episode.task
            || !overlap(&r.settings, &self.protocol.eval)
        {
            return Ok(false);
        }
        // The same protocol run again is a rerun wherever it runs (a resume in the
        // registered run's own directory is `register_in`'s case).
        if r.protocol_sha256 == self.sha256 {
            return Ok(true);
        }
        let (Some(mine), Some(theirs)) = (registered_at, r.stamp.commit.as_deref()) else {
            return Ok(true);
        };
        let before = git(
            &dir_of(&self.path),
            &["merge-base", "--is-ancestor", mine, theirs],
        )?
        .is_some();
        Ok(!before)
    }

    /// The last commit that touched this protocol file (`None` outside a repository or when
    /// it is not committed).
    fn registered_at(&self) -> Result<Option<String>, ProtocolError> {
        let name = self
            .path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(git(
            &dir_of(&self.path),
            &["log", "-1", "--format=%H", "--", &name],
        )?
        .map(trimmed)
        .filter(|c| !c.is_empty()))
    }

    /// [`ProtocolFile::register`] for a run writing into `out`: when the only registrations
    /// that spent the range are `out`'s own, of this very protocol file and registered, the run
    /// is that registered run resumed (its partial results were committed, e.g. at the end of
    /// a working session) and stays registered; anything else is as `register` says.
    pub fn register_in(
        &self,
        settings: &EvalSettings,
        allow_uncommitted: bool,
        out: &Path,
    ) -> Result<Registration, ProtocolError> {
        let (mut r, spending) = self.register_with_spending(settings, allow_uncommitted)?;
        if r.status != RegistrationStatus::Rerun {
            return Ok(r);
        }
        let Some(own) = read_registration(out)? else {
            return Ok(r);
        };
        let ours =
            own.protocol_sha256 == self.sha256 && own.status == RegistrationStatus::Registered;
        let own_file = out.join(REGISTRATION_FILE);
        let only_own = spending.iter().all(|(file, c)| {
            c.protocol_sha256 == self.sha256
                && c.status == RegistrationStatus::Registered
                && own_file.ends_with(file)
        });
        if ours && only_own {
            r.status = RegistrationStatus::Registered;
            r.spent_by.clear();
        }
        Ok(r)
    }
}

/// Read `dir/registration.json` if present.
pub fn read_registration(dir: &Path) -> Result<Option<Registration>, ProtocolError> {
    let path = dir.join(REGISTRATION_FILE);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(ProtocolError::Io { path, source }),
    };
    serde_json::from_slice(&bytes)
        .map(Some)
        .map_err(|source| ProtocolError::Registration { path, source })
}

/// Write `dir/registration.json` (atomically, safe for shards sharing `dir`).
pub fn write_registration(dir: &Path, registration: &Registration) -> Result<(), ProtocolError> {
    let path = dir.join(REGISTRATION_FILE);
    let text = serde_json::to_string_pretty(registration).map_err(|source| {
        ProtocolError::Registration {
            path: path.clone(),
            source,
        }
    })?;
    dips_fs::write_atomic(&path, text.as_bytes())
        .map_err(|source| ProtocolError::Io { path, source })
}

/// A registration's one-line description (`the registered results of protocol card-10000`).
fn describe(r: &Registration) -> String {
    format!(
        "the {} results of protocol {} ({}, sha256 {})",
        r.status.name(),
        r.name,
        r.protocol,
        r.protocol_sha256.chars().take(12).collect::<String>()
    )
}

/// Claim `dir` for a run registered as `ours` (`None`: a run without a protocol), before its
/// `eval.json` is written. A directory holds the results of one registration: a run without a
/// protocol may not write into a registered directory, a protocol run not into a directory of
/// episodes run without one, and a run of another protocol file or another status (a rerun
/// into a registered run's directory) not at all. A later run of the same registration (a
/// resume, a shard) is recorded in [`Registration::later_runs`] when its commit, tree state or
/// CPU differ.
pub fn claim_registration(dir: &Path, ours: Option<&Registration>) -> Result<(), ProtocolError> {
    let theirs = read_registration(dir)?;
    let refuse = |holds: String, why: &str| ProtocolError::Directory {
        dir: dir.to_path_buf(),
        holds,
        why: why.to_string(),
    };
    match (theirs, ours) {
        (None, None) => Ok(()),
        (Some(t), None) => Err(ProtocolError::Unregistered {
            dir: dir.to_path_buf(),
            holds: format!("holds {}", describe(&t)),
            protocol: t.protocol,
        }),
        (None, Some(o)) => {
            if dir.join(EVAL_FILE).exists() {
                return Err(refuse(
                    "holds an evaluation run without a protocol".into(),
                    &format!(
                        "the {} results of protocol {} would mix with it",
                        o.status.name(),
                        o.name
                    ),
                ));
            }
            write_registration(dir, o)
        }
        (Some(mut t), Some(o)) => {
            if t.protocol_sha256 != o.protocol_sha256 || t.status != o.status {
                let why = format!(
                    "this run is {} under protocol {} (sha256 {}){}",
                    o.status.name(),
                    o.name,
                    o.protocol_sha256.chars().take(12).collect::<String>(),
                    if t.status == RegistrationStatus::Registered {
                        ", and nothing else ever writes into registered results"
                    } else {
                        ""
                    }
                );
                return Err(refuse(format!("holds {}", describe(&t)), &why));
            }
            if o.stamp != t.stamp && !t.later_runs.contains(&o.stamp) {
                t.later_runs.push(o.stamp.clone());
                write_registration(dir, &t)?;
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sha256_of_known_bytes() {
        assert_eq!(
            sha256_bytes(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn missing_and_unknown_keys_are_found() {
        let typed = serde_json::json!({"a": {"b": 1, "c": null}, "d": 2});
        let raw = serde_json::json!({"a": {"b": 1}, "d": 2});
        assert_eq!(key_difference(&raw, &typed, ""), Some(("a.c".into(), true)));
        let raw = serde_json::json!({"a": {"b": 1, "c": null}, "d": 2, "e": 3});
        assert_eq!(key_difference(&raw, &typed, ""), Some(("e".into(), false)));
        assert_eq!(key_difference(&typed, &typed, ""), None);
    }

    #[test]
    fn ranges_overlap_only_when_they_share_a_seed() {
        let e = |first_seed, trials| EvalFile {
            episode: crate::settings::EpisodeSettings {
                task: SceneKind::Card,
                sampler: "ddpm:16"
                    .parse::<dips_kernel::diffusion::SamplerConfig>()
                    .unwrap()
                    .method,
                time_budget_s: 300.0,
                node_budget: 0,
                max_modes: None,
                cost_to_come: Default::default(),
                search_depth: dips_planning::online::SearchDepth::ModesLeft,
                alpha: None,
                beta: None,
                models: "/m".into(),
                engine: dips_onnx::EngineKind::Kernel,
                hand: Default::default(),
                tracker_noise: None,
                card_goals: Default::default(),
                stop_rule: Default::default(),
                first_mode: Default::default(),
                planner_size: Default::default(),
                exec_profile: Default::default(),
                pose_estimate: Default::default(),
                regrasp_guard: Default::default(),
                press: Default::default(),
            },
            methods: vec![Method::Dips],
            first_seed,
            trials,
        };
        assert!(overlap(&e(10000, 10), &e(10009, 1)));
        assert!(!overlap(&e(10000, 10), &e(10010, 5)));
        assert!(!overlap(&e(10010, 5), &e(10000, 10)));
    }
}
