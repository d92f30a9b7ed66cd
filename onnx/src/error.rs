//! Typed errors of the model contract, the engines and the lowering.

use std::path::PathBuf;

/// Everything that can go wrong loading, validating, lowering or running a model.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// A file could not be read or written.
    #[error("cannot {action} {path}: {cause}")]
    Io {
        /// What was being done, e.g. `read model file`, `write tensor file`.
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// The I/O error.
        cause: std::io::Error,
    },
    /// The bytes are not a valid ONNX protobuf (truncated or corrupt file).
    #[error("not a valid ONNX model (corrupt or truncated protobuf): {0}")]
    Protobuf(String),
    /// The model does not follow contract v1 (`docs/contracts.md` §3).
    #[error("model contract violation: {0}")]
    Contract(String),
    /// The model is valid but not the one the caller asked for (task, role).
    #[error("model mismatch: {0}")]
    Mismatch(String),
    /// The graph uses an operator the lowering does not support.
    #[error("unsupported operator {op} at node {node:?}")]
    UnsupportedOp {
        /// ONNX `op_type`.
        op: String,
        /// The node's name (or its first output when unnamed).
        node: String,
    },
    /// The graph is malformed or uses an operator in a way the lowering cannot handle.
    #[error("cannot lower node {node:?} ({op}): {reason}")]
    Lowering {
        /// ONNX `op_type`.
        op: String,
        /// The node's name (or its first output when unnamed).
        node: String,
        /// What is wrong.
        reason: String,
    },
    /// A weight (initializer or constant) holds NaN or infinity.
    #[error("weight {name:?} holds a non-finite value at element {index}")]
    NonFiniteWeight {
        /// Initializer or constant name.
        name: String,
        /// Flat index of the first bad element.
        index: usize,
    },
    /// A call's inputs do not have the shapes the model expects.
    #[error("bad input {name}: {reason}")]
    BadInput {
        /// Input name (`x`, `t`, ...).
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// tract failed to load, optimise or run the model.
    #[error("tract: {0}")]
    Tract(String),
    /// The kernel blob or interpreter rejected the model or the call.
    #[error("kernel engine: {0:?}")]
    Kernel(dips_kernel::nn::NnError),
    /// A JSON file (inputs/outputs) is malformed.
    #[error("bad JSON: {0}")]
    Json(String),
}

impl From<dips_kernel::nn::NnError> for ModelError {
    fn from(e: dips_kernel::nn::NnError) -> Self {
        ModelError::Kernel(e)
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = ModelError> = std::result::Result<T, E>;
