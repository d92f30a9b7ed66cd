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
