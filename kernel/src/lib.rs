//! `dips-kernel`: the part of DIPS that runs on the hand's controller.
//!
//! `#![no_std]` without `alloc`: every buffer has a capacity fixed by const generics or is
//! provided by the caller, and running out of room is reported as a status, never a panic.
//! See `ARCHITECTURE.md` at the workspace root for the crate map and data flow.
//!
//! No `unsafe` but two kinds of call, both in `nn::ops::cpu`: the AVX2 copies of the hot op
//! kernels are entered only after the CPU reports AVX2 (`wide!`), and `sqrt` calls the SSE
//! square root, part of the x86_64 baseline.
#![no_std]
#![deny(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

#[cfg(test)]
extern crate std;

pub mod adapters;
pub mod budget;
pub mod diffusion;
pub mod engine;
pub mod mode;
pub mod name;
pub mod nn;
pub mod prior;
pub mod rng;
pub mod search;
pub mod session;
pub mod task;
pub mod wire_convert;
