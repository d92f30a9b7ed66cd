//! The emulated hand: [`Emulator`] answers the V4 protocol on a [`CanBus`] as the hand's
//! firmware does (start-up requests, servo on/off, pose streaming at the `SET_PERIOD` rate,
//! SET_TORQUE applied while the servo is on, hand info, serial, temperatures) and moves its
//! joints with a [`Plant`] under the torques it receives. Encoder readings are quantised to
//! the encoder's counts; frames take their time on a 1 Mbit/s bus. Faults can be injected for
//! tests ([`Fault`]).
//!
//! Plants: [`joint_model::JointModel`] (the main workspace: each joint a documented
//! second-order model, with the object moved by our quasi-static world from the joints'
//! positions) and, in `host/mujoco`, MuJoCo's dynamics of the same scene actuated by torque.

use std::time::Duration;

use dips_world::hand::ObjectPose;
use dips_world::kinematics::HandJoints;

use crate::bus::CanBus;

/// What moves the emulated joints: torques in, positions out, in real time steps.
pub trait Plant: Send {
    /// The plant's name, as reports record it (`joint-model`, `mujoco`).
    fn name(&self) -> &'static str;
    /// Joint positions (rad), bus order `[finger][joint]` (index, middle, ring, thumb).
    fn joints(&self) -> HandJoints;
    /// Advance the plant by `dt` seconds holding joint torques `torques_nm` (N·m, bus order).
    fn step(&mut self, torques_nm: &HandJoints, dt: f64) -> Result<(), PlantError>;
    /// The object's true pose, where the plant simulates an object.
    fn object_pose(&self) -> Option<ObjectPose>;
}

/// A plant that could not advance.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{plant} plant: {message}")]
pub struct PlantError {
    /// Which plant.
    pub plant: &'static str,
    /// What went wrong.
    pub message: String,
}

/// A fault the emulator injects (`fault=` in `allegro:emulated,fault=...`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// From `at` (seconds after the servo first comes on) the hand sends nothing more.
    SilenceAt(Duration),
    /// Malformed frames (unknown ids, wrong lengths, extended ids, stray remote frames) are
    /// interleaved with every pose set.
    Garbage,
    /// From `at` the joints' temperatures read above any sane limit and the status byte's
    /// high-temperature bit is set.
    HotAt(Duration),
}

#[doc(hidden)]
pub fn _interface_check(_: &dyn CanBus) {}
