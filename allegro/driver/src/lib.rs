//! `dips-allegro`: the Allegro Hand V4 driver.
//!
//! - [`bus`]: the CAN buses, Linux SocketCAN and an in-process pair.
//! - [`controller`]: the joint PD loop on its own thread at the pose stream's rate (≈ 333 Hz):
//!   decode the four fingers' poses, filter velocity, PD with the vendor's gains (or a gains
//!   file), optional gravity compensation, clamp, PWM out; the reference moves linearly from
//!   the last target to the new one over each action, as every [`dips_world::hand::Hand`]
//!   does. It fails safe: a watchdog, joint, torque and temperature limits, and on every exit
//!   path (an error, a stop, Ctrl-C, a panic in any thread) zero torques, `SYSTEM_OFF` and
//!   streaming stopped.
//! - [`hand`]: [`hand::AllegroHand`], a [`dips_world::hand::Hand`] with the object pose from a
//!   [`pose`] source.
//! - [`emu`]: the emulated hand, answering the V4 protocol and moving under a [`emu::Plant`].
//! - [`units`]: what PWM means in N·m.

pub mod bus;
pub mod controller;
pub mod emu;
pub mod filter;
pub mod gains;
pub mod gravity;
pub mod hand;
pub mod pose;
pub mod realtime;
pub mod safety;
pub mod stats;
pub mod units;
