//! `dips-firmware-sim`: the kernel as the hand's controller runs it, on a host.
//!
//! The firmware itself is `dips-firmware-core` (`#![no_std]`, no heap): [`Firmware`] answers
//! each [`dips_wire::ToKernel`] message with one [`dips_wire::FromKernel`] message from fixed
//! buffers. This crate is the platform around it that a controller would provide from its
//! UART and timer: [`serve`] runs it over any byte streams (COBS deframing with a
//! fixed-capacity accumulator, postcard decoding, typed errors for bad frames, serving on
//! after any of them, a `Cancel` reaching a running plan), [`MonotonicClock`] is its clock,
//! and the `dips-firmware-sim` binary serves stdio or TCP with static memory.

pub mod link;

pub use dips_firmware_core::{Firmware, planning};
pub use link::{LinkClock, ServeStats, serve};

use std::time::Instant;

use dips_kernel::budget::Clock;

/// Size of each static model buffer of the `dips-firmware-sim` binary, in bytes.
pub const MODEL_CAPACITY_BYTES: usize = 32 * 1024 * 1024;

/// Size of the static planning work area of the `dips-firmware-sim` binary, in `f32`s
/// (64 MiB). The paper's settings (k 16, four card modes) with the fixture-sized models need
/// about 2 M floats; see [`planning::PlanMemory`].
pub const WORK_FLOATS: usize = 16 * 1024 * 1024;

/// Microseconds since the firmware started, from the monotonic clock.
#[derive(Debug, Clone, Copy)]
pub struct MonotonicClock {
    origin: Instant,
}

impl MonotonicClock {
    /// A clock starting now.
    pub fn new() -> Self {
        Self {
            origin: Instant::now(),
        }
    }
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for MonotonicClock {
    fn now_us(&mut self) -> u64 {
        u64::try_from(self.origin.elapsed().as_micros()).unwrap_or(u64::MAX)
    }
}

/// The firmware's memory on the heap, for running it inside a host process (tests, tools):
/// the two model buffers and the staging buffer of `model_capacity` bytes each, and, with
/// [`FirmwareMemory::planning`], a planner and a work area of `work_floats` floats. The
/// binary uses static buffers instead ([`MODEL_CAPACITY_BYTES`], [`WORK_FLOATS`]).
pub struct FirmwareMemory {
    denoiser: Vec<u8>,
    discriminator: Vec<u8>,
    staging: Vec<u8>,
    planning: Option<(Box<dips_kernel::search::PaperPlanner>, Vec<f32>)>,
}

impl std::fmt::Debug for FirmwareMemory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FirmwareMemory")
            .field("model_capacity", &self.denoiser.len())
            .field(
                "work_floats",
                &self.planning.as_ref().map(|(_, work)| work.len()),
            )
            .finish()
    }
}

impl FirmwareMemory {
    /// Model buffers only: a firmware that takes uploads and answers everything but plans.
    pub fn models(model_capacity: usize) -> Self {
        Self {
            denoiser: vec![0; model_capacity],
            discriminator: vec![0; model_capacity],
            staging: vec![0; model_capacity],
            planning: None,
        }
    }

    /// Model buffers and planning memory.
    pub fn planning(model_capacity: usize, work_floats: usize) -> Self {
        Self {
            planning: Some((
                Box::new(dips_kernel::search::PaperPlanner::new()),
                vec![0.0; work_floats],
            )),
            ..Self::models(model_capacity)
        }
    }

    /// A fresh firmware over this memory.
    pub fn firmware(&mut self) -> Firmware<'_> {
        match &mut self.planning {
            Some((planner, work)) => Firmware::with_planning(
                &mut self.denoiser,
                &mut self.discriminator,
                &mut self.staging,
                planning::PlanMemory { planner, work },
            ),
            None => Firmware::new(
                &mut self.denoiser,
                &mut self.discriminator,
                &mut self.staging,
            ),
        }
    }
}
