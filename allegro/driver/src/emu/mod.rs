//! The emulated hand: [`Emulator`] answers the V4 protocol on a
//! [`CanBus`](crate::bus::CanBus) as the hand's
//! firmware does (start-up requests, servo on/off, pose streaming at the `SET_PERIOD` rate,
//! SET_TORQUE applied while the servo is on, hand info, serial, temperatures) and moves its
//! joints with a [`Plant`] under the torques it receives. Encoder readings are quantised to
//! the encoder's counts; frames take their time on a 1 Mbit/s bus. Faults can be injected for
//! tests ([`Fault`]).
//!
//! Plants: [`joint_model::JointModel`] (the main workspace: each joint a documented
//! second-order model, with the object moved by our quasi-static world from the joints'
//! positions) and, in `host/mujoco`, MuJoCo's dynamics of the same scene actuated by torque.
//!
//! Modules: [`firmware`] (the protocol state machine, its configuration and counters),
//! [`runner`] (its real-time thread and the handle), [`joint_model`] (the joint-model plant),
//! and `world_link` (how the joint model reaches its world).

use dips_world::hand::ObjectPose;
use dips_world::kinematics::HandJoints;

pub mod firmware;
pub mod joint_model;
pub mod runner;
mod world_link;

pub use firmware::{EmulatorConfig, EmulatorStats, HOT_TEMPERATURE_C, WIRE_TIME_S};
pub use joint_model::{JointModel, JointModelParams};
pub use runner::{Emulator, EmulatorEnd, EmulatorHandle, EmulatorReport};

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

/// A fault the emulator injects: the type `--hand allegro:emulated,fault=…` parses into
/// (`silence@2`, `garbage`, `hot@3`; its one owner is `dips_world`, which parses and prints
/// it).
pub use dips_world::hand::EmulatorFault as Fault;
