//! `dips-link`: the host's side of the wire (`docs/wire.md`).
//!
//! A [`Link`] carries request frames to a DIPS kernel and waits for the reply with the same
//! request id, within a timeout: a kernel that dies or stops answering is an error naming the
//! last request, never a hang. The kernel is `dips-firmware-sim`, started as a child over its
//! stdin/stdout ([`KernelTarget::Spawn`]) or reached over TCP ([`KernelTarget::Tcp`]); a real
//! controller would sit behind the same frames on a UART.
//!
//! A [`RemotePlanner`] plans through a link as [`dips_planning::PlanService`]: it asks
//! the kernel's `Status` once and uploads only the models the kernel does not already hold
//! (same length and CRC-32), sends the prior and the sampler settings when they change, and
//! answers each call with the same [`dips_planning::PlanOutcome`] an in-process session
//! gives, bit for bit.

mod remote;
mod target;
mod transport;

pub use remote::{RemoteError, RemotePlanner};
pub use target::{FIRMWARE_ENV, KernelTarget, KernelTargetError, NoFirmware, find_firmware};
pub use transport::{Link, LinkError, Timeouts, request_name};
