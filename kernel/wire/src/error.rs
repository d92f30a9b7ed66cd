//! Protocol errors, sent by the kernel as an ordinary message.

use core::fmt;

use serde::{Deserialize, Serialize};

use crate::size::MaxSize;
use crate::upload::{ModelRole, UploadError};

/// A plan-request field the kernel refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
#[non_exhaustive]
pub enum RequestField {
    /// The start state (wrong length or not finite).
    StartState,
    /// The goal (not finite).
    Goal,
    /// The search settings (out of range).
    Settings,
    /// The previous mode (not a mode of the task).
    PreviousMode,
    /// A `SetPrior` table (wrong length for the task, negative or not finite, a row of
    /// zeros).
    Prior,
    /// `SetSampler` settings (no DDIM steps, noise factor outside `[0, 1]`, guidance not
    /// finite).
    Sampler,
    /// The first modes (no mode of the task, or a bit beyond its mode table).
    FirstModes,
}

impl fmt::Display for RequestField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::StartState => "start_state",
            Self::Goal => "goal",
            Self::Settings => "settings",
            Self::PreviousMode => "previous_mode",
            Self::Prior => "prior",
            Self::Sampler => "sampler",
            Self::FirstModes => "first_modes",
        })
    }
}

/// Why the kernel refused a frame or a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
#[non_exhaustive]
pub enum WireError {
    /// The bytes between two delimiters are not valid COBS.
    BadFrame,
    /// A frame was longer than the receiver's buffer.
    TooLong {
        /// Encoded length of the frame (saturating).
        len_bytes: u32,
        /// Longest frame accepted.
        max_bytes: u32,
    },
    /// The frame's payload is not a message of this protocol.
    DecodeFailed,
    /// The request's variant tag is unknown (a newer host).
    UnknownRequest {
        /// The variant index received.
        tag: u32,
    },
    /// The host's protocol version or schema key differs from the kernel's.
    VersionMismatch {
        /// The kernel's protocol version.
        kernel_version: u16,
        /// The host's protocol version.
        host_version: u16,
        /// The kernel's schema key.
        kernel_schema_key: u64,
        /// The host's schema key.
        host_schema_key: u64,
    },
    /// A request other than `Hello` came before a successful handshake.
    HandshakeRequired,
    /// The kernel is working on an earlier request.
    Busy,
    /// A model upload step was refused.
    Upload(UploadError),
    /// Planning needs a model that has not been uploaded.
    ModelNotLoaded {
        /// The missing model.
        role: ModelRole,
    },
    /// The kernel has its models but no planner to run them.
    PlannerUnavailable,
    /// A plan-request field is invalid.
    InvalidRequest {
        /// The offending field.
        field: RequestField,
    },
    /// An uploaded model (CRC-correct) cannot be run by this kernel.
    ModelRejected {
        /// The model.
        role: ModelRole,
        /// Why.
        fault: ModelFault,
    },
}

/// Why the kernel cannot run an uploaded model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum ModelFault {
    /// The bytes are not a lowered model this kernel reads (format, version, checksum,
    /// layout or non-finite weights).
    Invalid,
    /// The model is the wrong kind (a denoiser uploaded as the discriminator or the
    /// reverse), or its sizes do not match the other model's or the request's task.
    WrongShape,
    /// The kernel's memory cannot hold the model for one sample (`f32` counts).
    TooLarge {
        /// Floats the model needs for a batch of one.
        needed_floats: u32,
        /// Floats this kernel has for it.
        capacity_floats: u32,
    },
}

impl fmt::Display for ModelFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Invalid => f.write_str("not a model this kernel reads"),
            Self::WrongShape => f.write_str("wrong kind or sizes for this role and task"),
            Self::TooLarge {
                needed_floats,
                capacity_floats,
            } => write!(
                f,
                "needs {needed_floats} floats of memory, the kernel has {capacity_floats}"
            ),
        }
    }
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BadFrame => f.write_str("frame is not valid COBS"),
            Self::TooLong {
                len_bytes,
                max_bytes,
            } => write!(
                f,
                "frame of {len_bytes} bytes exceeds the {max_bytes}-byte limit"
            ),
            Self::DecodeFailed => f.write_str("frame payload does not decode as a message"),
            Self::UnknownRequest { tag } => write!(f, "unknown request variant {tag}"),
            Self::VersionMismatch {
                kernel_version,
                host_version,
                kernel_schema_key,
                host_schema_key,
            } => write!(
                f,
                "protocol mismatch: kernel v{kernel_version} schema {kernel_schema_key:016x}, \
                 host v{host_version} schema {host_schema_key:016x}"
            ),
            Self::HandshakeRequired => f.write_str("send Hello before any other request"),
            Self::Busy => f.write_str("kernel is busy with an earlier request"),
            Self::Upload(e) => write!(f, "model upload refused: {e}"),
            Self::ModelNotLoaded { role } => write!(f, "no {role} model is loaded"),
            Self::PlannerUnavailable => {
                f.write_str("models are loaded but this kernel has no planner wired in")
            }
            Self::InvalidRequest { field } => write!(f, "invalid plan request field {field}"),
            Self::ModelRejected { role, fault } => {
                write!(f, "the {role} model cannot be run: {fault}")
            }
        }
    }
}

impl core::error::Error for WireError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Upload(e) => Some(e),
            _ => None,
        }
    }
}

impl From<UploadError> for WireError {
    fn from(e: UploadError) -> Self {
        Self::Upload(e)
    }
}
