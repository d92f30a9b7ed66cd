//! [`JointModel`]: the main workspace's [`Plant`] (no MuJoCo). Each of the sixteen joints is
//! a second-order system driven by its motor torque,
//!
//! ```text
//! I·q̈ = τ − b·q̇ − τ_c·sign(q̇)
//! ```
//!
//! with Coulomb friction that sticks (a joint at rest stays at rest while `|τ| ≤ τ_c`) and hard
//! stops at the [`HandModel::allegro_v4`] joint limits (the position is clamped and the
//! velocity into the stop zeroed: an inelastic stop). Integration is semi-implicit Euler at
//! the emulator's sub-step: the velocity first, with the viscous term implicit and the
//! friction as an impulse bounded by `τ_c·dt` (so a joint whose momentum plus torque impulse
//! lies within the friction impulse stops exactly, without chattering around zero), then the
//! position from the new velocity.
//!
//! There is no gravity in this model: the fingers are driven as if weightless, so a driver's
//! gravity compensation has nothing to cancel here (its torques only offset the joints'
//! equilibria by `τ_g/kp`). Joints are independent: no coupling inertia between links.
//!
//! The object: [`JointModel::with_world`] couples the joints to our quasi-static
//! [`World`]. Every [`JointModelParams::world_period`] seconds of plant time the world executes
//! one action ([`World::step_targets`]) toward `q + τ̄/kp`: the emulated joints' positions
//! offset by the motors' mean torque over the period divided by the world's joint stiffness.
//! The world's hand is a spring of that stiffness about its targets, so it follows the
//! emulated hand and presses on the object with the torques the driver sent (in free space the
//! offset is the small torque that friction and damping take). Where the world could not follow
//! (a fingertip against the object or the table), the world's joint stopped short of its
//! target: the emulated joint may then go no further than the world's in that direction (it
//! is put back there if it has gone past it) and its velocity into the contact is zeroed, so
//! the fingers cannot pass through the object. Fingers that are not the scene's task fingers
//! the world holds at its defaults; those are left to the joint model alone.
//!
//! The world runs on a thread of its own ([`JointModel::with_world`]: a real-time emulator's
//! sub-steps never wait for it; its result applies at the first sub-step after it is ready,
//! a few milliseconds late in a release build) or inline ([`JointModel::with_world_inline`]:
//! each action inside the sub-step that asks for it, deterministic, for offline runs and
//! tests).

use dips_world::hand::ObjectPose;
use dips_world::kinematics::{Finger, HandJoints, HandModel};
use dips_world::scenes::SceneKind;
use dips_world::world::World;

use super::world_link::{WorldLink, WorldResult, pose_of};
use super::{Plant, PlantError};

/// The plant's name in reports.
pub const JOINT_MODEL_NAME: &str = "joint-model";

/// A world joint this far (rad) short of its target counts as stopped by a contact
/// (about a hundredth of an encoder count: far above the contact solver's tolerance on a free
/// finger, far below anything the encoder resolves).
const PUSHBACK_TOLERANCE: f64 = 1e-6;

/// The joint model's physical figures, per joint in bus order `[finger][joint]`.
///
/// They are of the right order for the Allegro V4 (geared DC motors, 0.7 N·m at full-scale
/// PWM), not calibrated against a real hand.
#[derive(Debug, Clone, PartialEq)]
pub struct JointModelParams {
    /// Inertia about each joint axis (kg·m²): 1e-3 on every joint. The reflected inertia of
    /// the joint's geared motor (rotor inertia times the gear ratio squared) dominates the
    /// links' own (≈ 1e-5 kg·m² for a distal link); 1e-3 is the armature our MuJoCo scene gives
    /// every finger joint (`docs/mujoco.md`). With the vendor's kp (4000 PWM/rad ≈ 2.3 N·m/rad)
    /// it puts a joint's natural frequency near 48 rad/s, so a 333 Hz PD tick is 0.14 rad of
    /// it: stable with the torque held between ticks.
    pub inertia: HandJoints,
    /// Viscous damping (N·m·s/rad): 0.05 on every joint. A DC motor driven by PWM voltage
    /// loses torque with speed through its back-EMF, which reflected through the gears acts as
    /// viscous damping `b = τ_stall / ω_no-load`; 0.05 gives a no-load joint speed of
    /// 0.7 / 0.05 = 14 rad/s at full-scale PWM and a mechanical time constant `I/b` of 20 ms.
    /// The vendor's kd (150 PWM per rad/s ≈ 0.09 N·m·s/rad) adds to it.
    pub damping: HandJoints,
    /// Coulomb (dry) friction of the gear train (N·m): 0.015 on every joint, about 2 % of the
    /// 0.7 N·m full scale, the order of a small multi-stage gearhead's no-load friction. It is
    /// also the stiction level: a joint at rest moves only under more than this. Against the
    /// vendor's kp it leaves a dead band of ≈ 6 mrad (0.37°, 72 counts) around a target.
    pub coulomb: HandJoints,
    /// Plant time between two steps of the coupled world (s): 0.05 (20 Hz). A world action
    /// costs milliseconds; the object moves slowly beside the joints, so 20 Hz follows it.
    pub world_period: f64,
}

impl Default for JointModelParams {
    fn default() -> Self {
        JointModelParams {
            inertia: [[1e-3; 4]; 4],
            damping: [[0.05; 4]; 4],
            coulomb: [[0.015; 4]; 4],
            world_period: 0.05,
        }
    }
}

impl JointModelParams {
    /// Check that every figure is usable: inertias finite and positive, damping and friction
    /// finite and non-negative, the world period finite and positive.
    pub fn validate(&self) -> Result<(), PlantError> {
        let bad = |what: &str, value: f64, allowed: &str| {
            Err(PlantError {
                plant: JOINT_MODEL_NAME,
                message: format!("parameter {what} = {value}: it must be {allowed}"),
            })
        };
        for (name, table, positive) in [
            ("inertia", &self.inertia, true),
            ("damping", &self.damping, false),
            ("coulomb", &self.coulomb, false),
        ] {
            for (f, row) in table.iter().enumerate() {
                for (j, &x) in row.iter().enumerate() {
                    let ok = x.is_finite() && if positive { x > 0.0 } else { x >= 0.0 };
                    if !ok {
                        let allowed = if positive {
                            "finite and > 0"
                        } else {
                            "finite and ≥ 0"
                        };
                        return bad(&format!("{name}[{f}][{j}]"), x, allowed);
                    }
                }
            }
        }
        if !(self.world_period.is_finite() && self.world_period > 0.0) {
            return bad("world_period", self.world_period, "finite and > 0 (s)");
        }
        Ok(())
    }
}

/// Sixteen independent joints with friction and hard stops, optionally moving our world's
/// object (see the module documentation).
#[derive(Debug)]
pub struct JointModel {
    scene: SceneKind,
    limits: [[(f64, f64); 4]; 4],
    params: JointModelParams,
    q: HandJoints,
    v: HandJoints,
    world: Option<WorldLink>,
    /// The fingers the world moves (its scene's task fingers).
    coupled: &'static [Finger],
    object: Option<ObjectPose>,
    since_world: f64,
    world_steps: u64,
    /// The world's joint stiffness (N·m/rad): its hand is a spring about its targets.
    world_kp: f64,
    /// ∫τ dt since the last world action, per joint (N·m·s).
    impulse: HandJoints,
}

impl JointModel {
    /// The hand of `scene` at rest at `start` (clamped to the joint limits), with the default
    /// parameters and no object.
    pub fn new(scene: SceneKind, start: HandJoints) -> JointModel {
        let model = HandModel::allegro_v4();
        let limits = Finger::ALL.map(|f| model.joint_limits(f));
        let q = Finger::ALL.map(|f| model.clamp_to_limits(f, &start[f.index()]));
        JointModel {
            scene,
            limits,
            params: JointModelParams::default(),
            q,
            v: [[0.0; 4]; 4],
            world: None,
            coupled: &[],
            object: None,
            since_world: 0.0,
            world_steps: 0,
            world_kp: 0.0,
            impulse: [[0.0; 4]; 4],
        }
    }

    /// The same with other parameters (checked with [`JointModelParams::validate`]).
    pub fn with_params(mut self, params: JointModelParams) -> Result<JointModel, PlantError> {
        params.validate()?;
        self.params = params;
        Ok(self)
    }

    /// Couple the joints to `world` (see the module documentation), the world stepped on a
    /// thread of its own (inline, as [`JointModel::with_world_inline`], should no thread
    /// start). The world's joints are set to the emulated ones and any fingertip inside the
    /// object moved out of it ([`World::resolve_penetration`]); the emulated task fingers
    /// then start where the world's are. The world's scene decides which fingers are coupled.
    pub fn with_world(self, world: World) -> JointModel {
        let (mut model, world) = self.attach(world);
        model.world = Some(WorldLink::thread(world).unwrap_or_else(|(w, _)| WorldLink::inline(w)));
        model
    }

    /// [`JointModel::with_world`] with every world action run inline, inside the sub-step
    /// that asks for it: deterministic, but a sub-step then takes as long as the action.
    pub fn with_world_inline(self, world: World) -> JointModel {
        let (mut model, world) = self.attach(world);
        model.world = Some(WorldLink::inline(world));
        model
    }

    fn attach(mut self, mut world: World) -> (JointModel, Box<World>) {
        world.set_joints(&self.q);
        world.resolve_penetration();
        let wq = world.joints();
        self.coupled = world.scene().task_fingers();
        for f in self.coupled {
            self.q[f.index()] = wq[f.index()];
        }
        self.object = Some(pose_of(&world));
        self.since_world = 0.0;
        self.world_kp = world.params().kp;
        (self, Box::new(world))
    }

    /// The scene this hand was built for.
    pub fn scene(&self) -> SceneKind {
        self.scene
    }

    /// The parameters.
    pub fn params(&self) -> &JointModelParams {
        &self.params
    }

    /// Joint velocities (rad/s), bus order.
    pub fn velocities(&self) -> HandJoints {
        self.v
    }

    /// World actions executed so far.
    pub fn world_steps(&self) -> u64 {
        self.world_steps
    }

    fn error(message: String) -> PlantError {
        PlantError {
            plant: JOINT_MODEL_NAME,
            message,
        }
    }

    /// Advance one joint by `dt` under torque `tau`.
    fn step_joint(&mut self, f: usize, j: usize, tau: f64, dt: f64) {
        let inertia = self.params.inertia[f][j];
        let b = self.params.damping[f][j];
        let impulse = inertia * self.v[f][j] + dt * tau;
        let friction = dt * self.params.coulomb[f][j];
        let mut v = if impulse.abs() <= friction {
            0.0
        } else {
            (impulse - friction * impulse.signum()) / (inertia + dt * b)
        };
        let (lo, hi) = self.limits[f][j];
        let mut q = self.q[f][j] + dt * v;
        if q <= lo {
            q = lo;
            v = v.max(0.0);
        } else if q >= hi {
            q = hi;
            v = v.min(0.0);
        }
        self.q[f][j] = q;
        self.v[f][j] = v;
    }

    /// Apply a finished world action: a joint the world stopped short of its target may go
    /// no further than the world's joint in that direction.
    fn apply_world(&mut self, r: &WorldResult) -> Result<(), PlantError> {
        for f in self.coupled {
            let i = f.index();
            for j in 0..4 {
                let (wq, target) = (r.joints[i][j], r.targets[i][j]);
                if !wq.is_finite() {
                    return Err(Self::error(format!("world joint [{i}][{j}] is {wq}")));
                }
                // The direction the world could not follow in.
                let blocked = target - wq;
                if blocked.abs() <= PUSHBACK_TOLERANCE {
                    continue;
                }
                if (self.q[i][j] - wq) * blocked > 0.0 {
                    let (lo, hi) = self.limits[i][j];
                    self.q[i][j] = wq.clamp(lo, hi);
                }
                if self.v[i][j] * blocked > 0.0 {
                    self.v[i][j] = 0.0;
                }
            }
        }
        self.object = Some(r.pose.clone());
        self.world_steps += 1;
        Ok(())
    }

    /// Ask for a world action every `world_period`; apply what the world has finished.
    fn step_world(&mut self, dt: f64) -> Result<(), PlantError> {
        let period = self.params.world_period;
        let Some(link) = self.world.as_mut() else {
            return Ok(());
        };
        self.since_world += dt;
        if self.since_world >= period && link.idle() {
            // The world's hand is a spring of stiffness kp about its targets: aiming it at
            // `q + τ̄/kp` makes it press with the motors' mean torque τ̄ over the period, so the
            // object feels the torques the driver sent, not the world's own stiffness.
            let elapsed = self.since_world.max(dt);
            let kp = self.world_kp.max(1e-9);
            let targets: HandJoints = std::array::from_fn(|f| {
                std::array::from_fn(|j| self.q[f][j] + self.impulse[f][j] / elapsed / kp)
            });
            self.impulse = [[0.0; 4]; 4];
            // A late action (the last one took longer than a period) restarts the count.
            self.since_world = (self.since_world - period).min(period);
            link.submit(targets);
        }
        if let Some(outcome) = link.poll() {
            let r = outcome.map_err(Self::error)?;
            self.apply_world(&r)?;
        }
        Ok(())
    }
}

impl Plant for JointModel {
    fn name(&self) -> &'static str {
        JOINT_MODEL_NAME
    }

    fn joints(&self) -> HandJoints {
        self.q
    }

    fn step(&mut self, torques_nm: &HandJoints, dt: f64) -> Result<(), PlantError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Self::error(format!(
                "time step {dt} s is not finite and > 0"
            )));
        }
        for (f, row) in torques_nm.iter().enumerate() {
            for (j, &tau) in row.iter().enumerate() {
                if !tau.is_finite() {
                    return Err(Self::error(format!("torque [{f}][{j}] is {tau}")));
                }
            }
        }
        for (f, row) in torques_nm.iter().enumerate() {
            for (j, &tau) in row.iter().enumerate() {
                self.step_joint(f, j, tau, dt);
                self.impulse[f][j] += tau * dt;
            }
        }
        self.step_world(dt)
    }

    fn object_pose(&self) -> Option<ObjectPose> {
        self.object.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(plant: &mut JointModel, tau: &HandJoints, seconds: f64) {
        let dt = 1e-3;
        for _ in 0..(seconds / dt).round() as usize {
            plant.step(tau, dt).unwrap();
            for f in Finger::ALL {
                let lim = plant.limits[f.index()];
                for (j, q) in plant.joints()[f.index()].iter().enumerate() {
                    assert!(*q >= lim[j].0 && *q <= lim[j].1, "{f:?} {j}: {q}");
                }
            }
        }
    }

    #[test]
    fn a_constant_torque_drives_a_joint_to_its_hard_stop_and_holds_it_there() {
        let start = SceneKind::Card.default_joints();
        let mut plant = JointModel::new(SceneKind::Card, start);
        let mut tau = [[0.0; 4]; 4];
        tau[0][1] = 0.2;
        tau[3][2] = -0.2;
        run(&mut plant, &tau, 1.0);
        let q = plant.joints();
        let index = HandModel::allegro_v4().joint_limits(Finger::Index);
        let thumb = HandModel::allegro_v4().joint_limits(Finger::Thumb);
        assert_eq!(q[0][1], index[1].1);
        assert_eq!(q[3][2], thumb[2].0);
        assert_eq!(plant.velocities()[0][1], 0.0);
        // Every other joint stayed where it started.
        for f in 0..4 {
            for j in 0..4 {
                if (f, j) != (0, 1) && (f, j) != (3, 2) {
                    assert_eq!(q[f][j], start[f][j], "[{f}][{j}]");
                }
            }
        }
        // Released, the joint stays at the stop; pushed back, it leaves it.
        run(&mut plant, &[[0.0; 4]; 4], 0.2);
        assert_eq!(plant.joints()[0][1], index[1].1);
        tau[0][1] = -0.2;
        run(&mut plant, &tau, 0.05);
        assert!(plant.joints()[0][1] < index[1].1);
    }

    #[test]
    fn friction_holds_a_joint_below_its_level_and_stops_it_when_released() {
        let mut plant = JointModel::new(SceneKind::Card, SceneKind::Card.default_joints());
        let q0 = plant.joints();
        let mut tau = [[0.0; 4]; 4];
        tau[1][2] = 0.9 * plant.params().coulomb[1][2];
        run(&mut plant, &tau, 0.2);
        assert_eq!(plant.joints(), q0);
        tau[1][2] = 0.05;
        run(&mut plant, &tau, 0.02);
        assert!(plant.joints()[1][2] > q0[1][2]);
        assert!(plant.velocities()[1][2] > 0.0);
        run(&mut plant, &[[0.0; 4]; 4], 0.2);
        assert_eq!(plant.velocities()[1][2], 0.0);
        let held = plant.joints();
        run(&mut plant, &[[0.0; 4]; 4], 0.1);
        assert_eq!(plant.joints(), held);
    }

    #[test]
    fn terminal_speed_is_torque_less_friction_over_damping() {
        let mut plant = JointModel::new(SceneKind::Card, [[0.0; 4]; 4]);
        let mut tau = [[0.0; 4]; 4];
        tau[0][0] = 0.05;
        run(&mut plant, &tau, 0.15);
        let p = plant.params();
        let want = (0.05 - p.coulomb[0][0]) / p.damping[0][0];
        assert!((plant.velocities()[0][0] - want).abs() < 0.01 * want);
    }

    #[test]
    fn bad_torques_time_steps_and_parameters_are_errors() {
        let mut plant = JointModel::new(SceneKind::Screwdriver, [[0.0; 4]; 4]);
        let mut tau = [[0.0; 4]; 4];
        tau[2][3] = f64::NAN;
        assert!(plant.step(&tau, 1e-3).is_err());
        assert!(plant.step(&[[0.0; 4]; 4], 0.0).is_err());
        assert!(plant.step(&[[0.0; 4]; 4], f64::INFINITY).is_err());
        let mut p = JointModelParams::default();
        p.inertia[1][1] = 0.0;
        let e = JointModel::new(SceneKind::Card, [[0.0; 4]; 4])
            .with_params(p)
            .unwrap_err();
        assert!(e.to_string().contains("inertia[1][1]"), "{e}");
        assert!(plant.object_pose().is_none());
    }
}
