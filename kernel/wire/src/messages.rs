//! The message enums, one per direction, and the frame that carries them.

use serde::{Deserialize, Serialize, de::DeserializeOwned};

use crate::config::{PriorTable, SamplerSettings};
use crate::error::WireError;
use crate::plan::{PlanReply, PlanRequest};
use crate::size::MaxSize;
use crate::status::KernelStatus;
use crate::upload::{ModelAck, ModelBegin, ModelChunk, ModelLoaded};

/// Every message on the wire travels in a frame; the kernel echoes `request_id` in replies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frame<B> {
    /// Chosen by the host; replies carry the id of the request they answer.
    pub request_id: u32,
    /// The message.
    pub body: B,
}

impl<B: MaxSize> MaxSize for Frame<B> {
    const POSTCARD_MAX_SIZE: usize = u32::POSTCARD_MAX_SIZE + B::POSTCARD_MAX_SIZE;
}

/// First message of a session: the host's protocol version and schema key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct Hello {
    /// The host's [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u16,
    /// The host's [`crate::SCHEMA_KEY`].
    pub schema_key: u64,
}

impl Hello {
    /// The hello this build of the crate sends.
    pub const fn current() -> Self {
        Self {
            protocol_version: crate::PROTOCOL_VERSION,
            schema_key: crate::SCHEMA_KEY,
        }
    }
}

/// The kernel's answer to a matching [`Hello`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct HelloAck {
    /// The kernel's [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u16,
    /// The kernel's [`crate::SCHEMA_KEY`].
    pub schema_key: u64,
    /// Longest frame (COBS-encoded, delimiter included) the kernel accepts.
    pub max_frame_len_bytes: u32,
    /// Most bytes per model chunk.
    pub model_chunk_len_bytes: u32,
}

/// Host → kernel messages. Append-only: never reorder, remove or change a variant.
///
/// `ModelChunk` makes this enum large; that is the price of no heap (boxing is not an option).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, MaxSize)]
pub enum ToKernel {
    /// Handshake; must come first.
    Hello(Hello),
    /// Plan a contact-mode sequence.
    PlanRequest(PlanRequest),
    /// Start a model upload.
    ModelBegin(ModelBegin),
    /// One piece of a model upload.
    ModelChunk(ModelChunk),
    /// Finish a model upload.
    ModelEnd,
    /// Use this prior for the task's plans from now on.
    SetPrior(PriorTable),
    /// Use these sampler settings for plans from now on.
    SetSampler(SamplerSettings),
    /// Report the kernel's status ([`FromKernel::Status`]). Appended.
    Status,
    /// Stop the running plan at its next expansion (its reply then carries the best node so
    /// far); answered [`FromKernel::Applied`], also when no plan is running. Appended.
    Cancel,
}

/// Kernel → host messages. Append-only: never reorder, remove or change a variant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, MaxSize)]
pub enum FromKernel {
    /// The handshake succeeded.
    HelloAck(HelloAck),
    /// The answer to a plan request.
    PlanReply(PlanReply),
    /// A model begin or chunk was accepted.
    ModelAck(ModelAck),
    /// A model upload completed and passed its checks.
    ModelLoaded(ModelLoaded),
    /// The request (or the frame) was refused.
    Error(WireError),
    /// A `SetPrior`, `SetSampler` or `Cancel` took effect.
    Applied,
    /// The answer to [`ToKernel::Status`]. Appended.
    Status(KernelStatus),
}

/// A message enum of this protocol.
pub trait Message: Serialize + DeserializeOwned + MaxSize {
    /// Number of variants this build knows; larger tags are newer variants.
    const VARIANT_COUNT: u32;
}

impl Message for ToKernel {
    const VARIANT_COUNT: u32 = 9;
}

impl Message for FromKernel {
    const VARIANT_COUNT: u32 = 7;
}
