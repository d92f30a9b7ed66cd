//! `Status` and `Cancel`: what a host can ask a running kernel besides planning.
//!
//! A [`KernelStatus`] names the models the kernel holds (so a host uploads only what differs),
//! the memory it uses, the last planning call and its frame counters. `Cancel` stops a
//! running plan at its next expansion; the plan's reply then carries the best node so far with
//! [`crate::ApproximateReason::Cancelled`].

use serde::{Deserialize, Serialize};

use crate::plan::{PlanStatus, Task};
use crate::size::MaxSize;

/// One loaded model: its identity and the shapes the kernel read from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct ModelIdentity {
    /// Length of the uploaded blob.
    pub len_bytes: u32,
    /// CRC-32 of the blob (the upload's check): equal length and CRC, same model.
    pub crc32: u32,
    /// The task its shapes belong to, `None` when they match neither.
    pub task: Option<Task>,
    /// Rows per trajectory segment.
    pub horizon: u16,
    /// State columns per row.
    pub state_dim: u16,
    /// Action columns per row.
    pub action_dim: u16,
    /// Fingers in the contact-mode context.
    pub fingers: u16,
    /// Diffusion steps the denoiser was trained with (0 for a discriminator).
    pub diffusion_steps: u16,
}

/// The kernel's memory: fixed capacities and what is in use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, MaxSize)]
pub struct MemoryUse {
    /// Capacity of each of the two model buffers.
    pub model_capacity_bytes: u32,
    /// Bytes held by the loaded models together.
    pub models_bytes: u32,
    /// The planner's static state (nodes, particles, open list).
    pub planner_bytes: u32,
    /// Floats of the planning work area.
    pub work_floats: u32,
    /// Floats of it the last planning call used.
    pub work_floats_used: u32,
}

/// The last planning call, with the figures a [`crate::PlanReply`] does not carry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, MaxSize)]
pub struct LastPlan {
    /// Its request's id.
    pub request_id: u32,
    /// How it ended.
    pub status: PlanStatus,
    /// Wall time in milliseconds.
    pub elapsed_ms: u32,
    /// Nodes expanded.
    pub nodes_expanded: u32,
    /// Segments the sampler produced.
    pub segments_sampled: u32,
    /// Particles of the plan's terminal node.
    pub particles: u8,
    /// Their effective number (`1/Σw²`).
    pub effective_particles: f32,
    /// Expected progress at the terminal node (screwdriver yaw rad, card y m).
    pub expected_progress: f32,
    /// Terminal cost `φ` there.
    pub terminal_cost: f32,
    /// Cost-to-come `g` there.
    pub cost_to_come: f32,
    /// Heuristic `h` there.
    pub heuristic: f32,
}

/// Frames the kernel has handled since it started.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, MaxSize)]
pub struct FrameCounts {
    /// Frames decoded into a request.
    pub requests: u32,
    /// Frames refused before decoding (bad COBS, too long, undecodable, unknown variant).
    pub bad_frames: u32,
    /// Replies sent.
    pub replies: u32,
    /// Plans stopped by `Cancel`.
    pub cancelled_plans: u32,
}

/// The answer to `Status`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, MaxSize)]
pub struct KernelStatus {
    /// The loaded denoiser.
    pub denoiser: Option<ModelIdentity>,
    /// The loaded discriminator.
    pub discriminator: Option<ModelIdentity>,
    /// Memory.
    pub memory: MemoryUse,
    /// The last planning call since the kernel started.
    pub last_plan: Option<LastPlan>,
    /// Frame counters.
    pub frames: FrameCounts,
}
