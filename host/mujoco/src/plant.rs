//! [`MujocoPlant`]: MuJoCo's dynamics of the hand and the task object as the emulated
//! Allegro hand's [`Plant`] (`--hand allegro:emulated,plant=mujoco`): the joints move under
//! the torques the driver's PWM frames carry, gravity and contacts act, and the object's true
//! pose is the emulator's truth. The scene is the one `--hand mujoco` uses, without its PD.

use dips_allegro::emu::{Plant, PlantError};
use dips_world::hand::{Hand, ObjectPose};
use dips_world::kinematics::HandJoints;
use dips_world::scenes::SceneKind;

use crate::MujocoHand;

/// The MuJoCo scene driven by torque.
#[derive(Debug)]
pub struct MujocoPlant {
    hand: MujocoHand,
}

fn plant_error(e: impl std::fmt::Display) -> PlantError {
    PlantError {
        plant: "mujoco",
        message: e.to_string(),
    }
}

impl MujocoPlant {
    /// The scene of `scene` at our world's start state (the joints `start` are that state's;
    /// the MuJoCo hand's reset puts them there).
    pub fn new(scene: SceneKind, _start: HandJoints) -> Result<MujocoPlant, PlantError> {
        Ok(MujocoPlant {
            hand: MujocoHand::new(scene).map_err(plant_error)?,
        })
    }

    /// The simulated hand.
    pub fn hand(&self) -> &MujocoHand {
        &self.hand
    }
}

impl Plant for MujocoPlant {
    fn name(&self) -> &'static str {
        "mujoco"
    }

    fn joints(&self) -> HandJoints {
        self.hand.joint_positions()
    }

    fn step(&mut self, torques_nm: &HandJoints, dt: f64) -> Result<(), PlantError> {
        self.hand.step_torques(torques_nm, dt).map_err(plant_error)
    }

    fn object_pose(&self) -> Option<ObjectPose> {
        Some(self.hand.true_object_pose())
    }
}

/// The factory `dips_allegro` opens the emulated hand's plant with.
pub fn mujoco_plant(scene: SceneKind, start: HandJoints) -> Result<Box<dyn Plant>, PlantError> {
    Ok(Box::new(MujocoPlant::new(scene, start)?))
}
