//! `dips-wire`: postcard messages and COBS framing between the DIPS host and kernel.
//!
//! One message enum per direction ([`ToKernel`], [`FromKernel`]), each wrapped in a
//! [`Frame`] whose `request_id` the kernel echoes in its reply. Frames are postcard-encoded
//! and COBS-framed (a `0x00` byte ends every frame); [`FrameAccumulator`] turns an arbitrary
//! byte stream back into frames so that a corrupted frame costs only itself.
//!
//! Rules (`docs/contracts.md` §6): enum variants are append-only (postcard encodes the variant
//! index), no `usize`/`isize` and no nalgebra types on the wire, units in field names, bounded
//! containers only. Any change to the encoded layout changes [`SCHEMA_KEY`] (the golden-bytes
//! tests fail until it is updated) and a breaking change bumps [`PROTOCOL_VERSION`].
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

#[cfg(test)]
extern crate std;

pub mod config;
pub mod error;
pub mod framing;
pub mod messages;
pub mod plan;
pub mod schema;
pub mod size;
pub mod status;
pub mod upload;

pub use config::{MAX_PRIOR_FLOATS, MAX_PRIOR_MODES, PriorTable, SamplerMethod, SamplerSettings};
pub use error::{ModelFault, RequestField, WireError};
pub use framing::{
    DecodeError, Feed, FrameAccumulator, MAX_ENCODED_FRAME_LEN, MAX_FRAME_LEN, NO_REQUEST_ID,
    decode_frame, encode_frame,
};
pub use messages::{Frame, FromKernel, Hello, HelloAck, Message, ToKernel};
pub use plan::{
    ApproximateReason, CardGoals, CostToCome, MAX_PLAN_MODES, MAX_STATE_DIM, PlanCapacity,
    PlanReply, PlanRequest, PlanStats, PlanStatus, SearchSettings, SearchVariant, SettingsField,
    Task,
};
pub use schema::{PROTOCOL_VERSION, SCHEMA_KEY};
pub use status::{FrameCounts, KernelStatus, LastPlan, MemoryUse, ModelIdentity};
pub use upload::{
    MODEL_CHUNK_LEN, ModelAck, ModelAssembler, ModelBegin, ModelChunk, ModelLoaded, ModelRole,
    UploadError, UploadMessages, crc32, upload_messages,
};
