//! Typed errors of the trainer.

use std::path::PathBuf;

/// Everything that can go wrong training or exporting.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A setting is out of range; `field` names it.
    #[error("bad setting {field}: {reason}")]
    Settings {
        /// The setting (dotted path in `TrainSettings`).
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The dataset could not be read or is unusable.
    #[error(transparent)]
    Dataset(#[from] dips_dataset::DatasetError),
    /// The dataset is readable but cannot be trained on (e.g. too few demos to hold one out).
    #[error("dataset: {0}")]
    DatasetUnusable(String),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A checkpoint exists but cannot be resumed from; `reason` says why.
    #[error("checkpoint {path}: {reason}")]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The exported model failed the contract or an engine failed on it.
    #[error(transparent)]
    Model(#[from] dips_onnx::ModelError),
    /// The diffusion sampler failed while making the discriminator's diffused trajectories.
    #[error("sampler: {0}")]
    Sampler(String),
    /// Training diverged (a non-finite loss).
    #[error("training diverged at step {step}: loss is {loss}")]
    Diverged {
        /// The optimiser step.
        step: usize,
        /// The loss.
        loss: f32,
    },
    /// The run stopped after this step because `RunOptions::stop_after` asked for it (its
    /// checkpoint is written; calling again resumes).
    #[error("stopped after step {step} as asked; the checkpoint is written")]
    Stopped {
        /// The last optimiser step taken.
        step: usize,
    },
    /// The tensor backend returned data of an unexpected type or size.
    #[error("tensor backend: {0}")]
    Backend(String),
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, TrainError>;

/// Wrap an I/O error with its path.
pub(crate) fn io_err(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> TrainError + '_ {
    move |source| TrainError::Io {
        path: path.to_path_buf(),
        source,
    }
}
