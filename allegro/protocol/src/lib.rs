//! `dips-allegro-protocol`: the Allegro Hand V4's CAN protocol as types.
//!
//! The hand speaks classic CAN at 1 Mbit/s with standard 11-bit identifiers. Every frame's
//! identifier is `(command << 2) | device_id` ([`ids`]); a reply reuses its request's command.
//! The host sends [`HostCommand`]s (servo on/off, torques, streaming periods, remote requests);
//! the hand answers [`HandReply`]s (finger encoder poses, hand info, serial, temperatures).
//! [`scale`] converts encoder counts to radians and normalised torques to PWM, both ways.
//!
//! Everything encodes into and decodes from any [`embedded_can::Frame`], so the same code runs
//! with SocketCAN's frames on a host and with a HAL's frames on a controller board;
//! [`CanFrame`] is a plain frame of our own for buses that have none (tests, the emulator).
//! Decoding never panics: a frame this protocol does not know is a [`DecodeError`] naming why.
//!
//! The crate is `#![no_std]` without `alloc`.
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

#[cfg(test)]
extern crate std;

pub mod frame;
pub mod ids;
pub mod message;
pub mod scale;

pub use frame::CanFrame;
pub use ids::{Command, DeviceId, FINGERS, JOINTS, JOINTS_PER_FINGER};
pub use message::{DecodeError, HandInfo, HandReply, HandType, HostCommand, Periods, Status};
