//! The quasi-static test world that stands in for Isaac Gym (spec §1.2 and §4).
//!
//! One action is the paper's 1 s held joint-position command, split into
//! [`WorldParams::substeps`] sub-steps of length `h`. Each sub-step solves a second-order cone
//! program with Clarabel (see `socp`): the task fingers are stiff joint springs (stiffness `kp`)
//! toward their commanded positions, the object carries an `s`-scaled mass regulariser plus
//! damping `D/h` and gravity, and every contact within [`WorldParams::contact_margin`] adds one
//! friction cone: the Anitescu cone (screwdriver), or non-penetration plus a
//! maximum-dissipation cone with a normal force iterated to a fixed point (card; see
//! [`FrictionModel`]). The duals are the contact forces. Sub-steps stop early once
//! `‖δq‖ < early_stop`. See `docs/world.md` for the model and its artifacts.

pub mod bench;
mod contacts;
pub mod scripted;
mod socp;

use clarabel::solver::SolverStatus;
use nalgebra::{
    DMatrix, Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use serde::{Deserialize, Serialize};

pub use contacts::ContactReport;

use crate::geometry::Body;
use crate::kinematics::{Finger, FingerFrames, HandJoints, HandModel};
use crate::scenes::{GRAVITY, SceneKind, card, screwdriver};

/// Physical and numerical parameters of the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldParams {
    /// Duration of one action (s); Isaac holds each target for 1 s.
    pub action_duration: f64,
    /// Sub-steps per action (`h = action_duration / substeps`).
    pub substeps: usize,
    /// Joint stiffness of the task fingers (N·m/rad).
    pub kp: f64,
    /// Joint damping of the task fingers (N·m·s/rad). It enters as `D/h` on the joint
    /// diagonal, so a free finger closes `kp/(kp + D/h)` of its remaining error per sub-step:
    /// a first-order lag with time constant `D/kp`. Default 0 (spec §1.2: stiff impedance, a
    /// free finger reaches its command, as CSVTO's free-motion model assumes); Isaac's PD
    /// drive uses 1.0, which leaves ≈ 7 % of a screwdriver command (kp = 3) unreached after 1 s.
    pub joint_damping: f64,
    /// Mass-regularisation scale `s`: the largest object mass entry becomes `kp/s` (qsim's
    /// `unactuated_mass_scale`).
    pub mass_scale: f64,
    /// Contacts with signed distance up to this are candidates of the contact step (m).
    pub contact_margin: f64,
    /// Which candidates get friction under [`FrictionModel::Anitescu`] ([`ConeActivation::All`]
    /// for logs written before this field existed).
    #[serde(default = "legacy_cone_activation")]
    pub cone_activation: ConeActivation,
    /// How the joint controller's setpoint moves during an action ([`CommandProfile::Step`]
    /// for logs written before this field existed).
    #[serde(default = "legacy_command_profile")]
    pub command_profile: CommandProfile,
    /// With [`CommandProfile::Ramp`], the fraction of the action over which the setpoint
    /// moves; it holds the command for the rest (in whole sub-steps: the ramp ends at sub-step
    /// `ceil(ramp_fraction · substeps)`). A finger that slides while pressing ends each
    /// Anitescu sub-step lifted by μ·slip; the settling sub-steps bring it back onto the
    /// surface before the action ends. In (0, 1].
    #[serde(default = "full_ramp")]
    pub ramp_fraction: f64,
    /// Finger–object friction coefficient.
    pub finger_friction: f64,
    /// Card–table friction coefficient (card scene).
    pub table_friction: f64,
    /// Finger–table friction coefficient (card scene).
    pub finger_table_friction: f64,
    /// Object damping: screwdriver roll/pitch/yaw, or the card's value on all six coordinates.
    pub damping: [f64; 3],
    /// Stop the sub-steps once the increment norm falls below this.
    pub early_stop: f64,
    /// Gravity (m/s²).
    pub gravity: f64,
    /// Keep the task joints within their limits with linear constraints.
    pub enforce_joint_limits: bool,
    /// Clarabel's interior-point iteration limit per solve.
    pub solver_max_iter: u32,
    /// How friction is formulated.
    pub friction_model: FrictionModel,
    /// Most solves per sub-step for [`FrictionModel::Staggered`].
    pub staggered_iterations: usize,
    /// Staggered iterations stop when no normal force changes by more than
    /// `staggered_tolerance + staggered_relative_tolerance · max normal force` (N).
    pub staggered_tolerance: f64,
    /// Relative part of the staggered stopping rule.
    pub staggered_relative_tolerance: f64,
    /// Staggered iterations also require the linearised signed distances to match the true
    /// ones at the solution to within this (m).
    pub geometry_tolerance: f64,
    /// When staggered iterations do not settle, solve that sub-step with the Anitescu cone
    /// (flagged `friction_fallback`) instead of applying the last iterate (flagged
    /// `friction_not_converged`). Off by default: on the card the cone's drag is worse than
    /// an unsettled iterate (CSVTO's single-finger pushes lose their centimetre with it).
    pub staggered_fallback: bool,
}

fn legacy_cone_activation() -> ConeActivation {
    ConeActivation::All
}

fn full_ramp() -> f64 {
    1.0
}

fn legacy_command_profile() -> CommandProfile {
    CommandProfile::Step
}

/// Which contact candidates get a friction cone under [`FrictionModel::Anitescu`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConeActivation {
    /// Every candidate within [`WorldParams::contact_margin`] (the plain Anitescu model). A
    /// candidate that slides must separate by μ·slip, so a finger gliding past the object
    /// without pressing drags it along (`docs/world.md`).
    All,
    /// Only candidates that press: each sub-step is first solved with frictionless
    /// non-penetration rows, and the candidates that carry a normal force there, or carried
    /// one at the end of the previous sub-step, get the cone in the solve that is applied;
    /// the others keep their frictionless row. A finger that does not press cannot push the
    /// object sideways. Two solves per sub-step where some candidate presses, one where none
    /// does.
    Pressing,
}

/// How the task fingers' setpoint moves within one action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CommandProfile {
    /// The setpoint moves linearly from the joints measured at the start of the action to the
    /// command, reaching it at the last sub-step, as a position controller tracks an
    /// interpolated target. A free finger still ends the action at its command.
    Ramp,
    /// The setpoint jumps to the command at the first sub-step (a step input): a free finger
    /// makes its whole move in the first sub-step.
    Step,
}

/// Friction formulation of the contact step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionModel {
    /// One Anitescu cone per contact (spec §1.2, qsim's SOCP). Convex and one solve per
    /// sub-step, but sliding forces a separation of μ·slip: a finger dragged across a light
    /// object without pressing drags the object along (measured in `docs/world.md`).
    Anitescu,
    /// Non-penetration rows plus maximum-dissipation friction bounded by μ times a normal
    /// force estimate, re-solved with the new normal forces until they agree (staggered
    /// projections, warm-started from the previous sub-step), with the contact geometry
    /// re-linearised at each iterate. No hover; a few solves per sub-step. Converges for
    /// moderate μ; where it does not, the step is flagged.
    Staggered,
}

impl WorldParams {
    /// Defaults for a scene (spec §3 and §4).
    pub fn for_scene(scene: SceneKind) -> WorldParams {
        // Friction: the card (μ ≤ 1, a 10 g object) needs the hover-free staggered form, or a
        // grazing finger drags it; the screwdriver (μ = 2.5) uses the single convex Anitescu
        // cone, because staggered iterations can diverge there (wedging: more friction needs
        // more normal force). See docs/world.md.
        let (damping, table, friction_model) = match scene {
            SceneKind::Screwdriver => (screwdriver::DAMPING, 0.0, FrictionModel::Anitescu),
            SceneKind::Card => (
                [card::DAMPING; 3],
                card::TABLE_FRICTION,
                FrictionModel::Staggered,
            ),
        };
        WorldParams {
            action_duration: 1.0,
            substeps: 10,
            kp: scene.kp(),
            joint_damping: 0.0,
            mass_scale: 5.0,
            contact_margin: 0.02,
            cone_activation: ConeActivation::Pressing,
            command_profile: CommandProfile::Ramp,
            ramp_fraction: 0.8,
            finger_friction: scene.finger_friction(),
            table_friction: table,
            finger_table_friction: card::FINGER_TABLE_FRICTION,
            damping,
            early_stop: 1e-6,
            gravity: GRAVITY,
            enforce_joint_limits: true,
            solver_max_iter: 100,
            friction_model,
            staggered_iterations: 12,
            staggered_tolerance: 1e-3,
            staggered_relative_tolerance: 0.02,
            geometry_tolerance: 2e-5,
            staggered_fallback: false,
        }
    }

    /// Sub-steps over which a ramped setpoint moves (at least 1, at most `substeps`).
    pub fn ramp_substeps(&self) -> usize {
        ((self.ramp_fraction * self.substeps as f64).ceil() as usize).clamp(1, self.substeps)
    }

    /// Sub-step length (s).
    pub fn h(&self) -> f64 {
        self.action_duration / self.substeps as f64
    }

    /// Check that every parameter is usable: positive durations, counts and stiffness,
    /// non-negative margins, damping and friction, finite numbers.
    pub fn validate(&self) -> Result<(), WorldError> {
        let bad = |name: &'static str, value: f64, allowed: &'static str| {
            Err(WorldError::Params {
                name,
                value,
                allowed,
            })
        };
        let positive = [
            ("action_duration", self.action_duration),
            ("kp", self.kp),
            ("early_stop", self.early_stop),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v, "a finite number > 0");
            }
        }
        let non_negative = [
            ("joint_damping", self.joint_damping),
            ("contact_margin", self.contact_margin),
            ("finger_friction", self.finger_friction),
            ("table_friction", self.table_friction),
            ("finger_table_friction", self.finger_table_friction),
            ("damping[0]", self.damping[0]),
            ("damping[1]", self.damping[1]),
            ("damping[2]", self.damping[2]),
            ("gravity", self.gravity),
            ("staggered_tolerance", self.staggered_tolerance),
            (
                "staggered_relative_tolerance",
                self.staggered_relative_tolerance,
            ),
            ("geometry_tolerance", self.geometry_tolerance),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, v, "a finite number ≥ 0");
            }
        }
        // The Anitescu cone divides by μ.
        if self.finger_friction == 0.0 {
            return bad("finger_friction", 0.0, "a finite number > 0");
        }
        // `mass_scale` ≤ 0 means "true mass" (see `regulariser`); only NaN is meaningless.
        if self.mass_scale.is_nan() {
            return bad("mass_scale", self.mass_scale, "a number (≤ 0: true mass)");
        }
        let counts = [
            ("substeps", self.substeps),
            ("staggered_iterations", self.staggered_iterations),
            ("solver_max_iter", self.solver_max_iter as usize),
        ];
        for (name, v) in counts {
            if v == 0 {
                return bad(name, 0.0, "a whole number ≥ 1");
            }
        }
        if !(self.ramp_fraction > 0.0 && self.ramp_fraction <= 1.0) {
            return bad("ramp_fraction", self.ramp_fraction, "a number in (0, 1]");
        }
        Ok(())
    }
}

/// The object's configuration.
#[derive(Debug, Clone, PartialEq)]
pub enum ObjectState {
    /// The screwdriver on its spherical pivot.
    Screwdriver {
        /// Orientation `Rx(roll)·Ry(pitch)·Rz(yaw)`.
        orientation: UnitQuaternion<f64>,
        /// Yaw unwrapped across ±π (rad, clockwise negative).
        yaw: f64,
    },
    /// The free card.
    Card {
        /// Pose of the card centre.
        pose: Isometry3<f64>,
        /// Heading about world z, unwrapped (rad).
        theta: f64,
    },
}

fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let r = (a + std::f64::consts::PI).rem_euclid(two_pi) - std::f64::consts::PI;
    if r <= -std::f64::consts::PI {
        r + two_pi
    } else {
        r
    }
}

/// Heading of a rotation about world z (yaw of a ZYX decomposition).
fn heading(r: &UnitQuaternion<f64>) -> f64 {
    let m = r.to_rotation_matrix();
    m[(1, 0)].atan2(m[(0, 0)])
}

impl ObjectState {
    /// The scene's initial object state.
    pub fn initial(scene: SceneKind) -> ObjectState {
        match scene {
            SceneKind::Screwdriver => ObjectState::Screwdriver {
                orientation: UnitQuaternion::identity(),
                yaw: 0.0,
            },
            SceneKind::Card => {
                let [x, y, z] = card::INITIAL_CENTER;
                ObjectState::Card {
                    pose: Isometry3::translation(x, y, z),
                    theta: 0.0,
                }
            }
        }
    }

    /// Build from the state's three object coordinates: `(roll, pitch, yaw)` for the
    /// screwdriver, `(x, y, θ)` for the card (resting flat on the table).
    pub fn from_coords(scene: SceneKind, coords: [f64; 3]) -> ObjectState {
        match scene {
            SceneKind::Screwdriver => {
                let r = screwdriver::rotation(coords[0], coords[1], coords[2]);
                ObjectState::Screwdriver {
                    orientation: UnitQuaternion::from_rotation_matrix(&r),
                    yaw: coords[2],
                }
            }
            SceneKind::Card => ObjectState::Card {
                pose: Isometry3::from_parts(
                    Translation3::new(coords[0], coords[1], card::INITIAL_CENTER[2]),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), coords[2]),
                ),
                theta: coords[2],
            },
        }
    }

    /// World pose of the object frame (screwdriver: at the pivot).
    pub fn pose(&self) -> Isometry3<f64> {
        match self {
            ObjectState::Screwdriver { orientation, .. } => {
                let [x, y, z] = screwdriver::PIVOT;
                Isometry3::from_parts(Translation3::new(x, y, z), *orientation)
            }
            ObjectState::Card { pose, .. } => *pose,
        }
    }

    /// State coordinates: `(roll, pitch, yaw)` or `(x, y, θ)`, angles unwrapped.
    pub fn coords(&self) -> [f64; 3] {
        match self {
            ObjectState::Screwdriver { orientation, yaw } => {
                let e = screwdriver::euler_xyz(orientation.to_rotation_matrix().matrix());
                [e[0], e[1], *yaw]
            }
            ObjectState::Card { pose, theta } => [pose.translation.x, pose.translation.y, *theta],
        }
    }

    /// Task validity: screwdriver cap within 0.02 m of nominal; card still lying on the table
    /// (centre within 5 mm of its resting height).
    pub fn valid(&self) -> bool {
        match self {
            ObjectState::Screwdriver { orientation, .. } => {
                screwdriver::is_valid(&orientation.to_rotation_matrix())
            }
            ObjectState::Card { pose, .. } => {
                (pose.translation.z - card::INITIAL_CENTER[2]).abs() <= 5e-3
            }
        }
    }

    /// Apply a world-frame increment: `ω` (screwdriver) or `(δp, ω)` (card).
    fn apply(&mut self, dq: &[f64]) {
        match self {
            ObjectState::Screwdriver { orientation, yaw } => {
                let w = Vector3::new(dq[0], dq[1], dq[2]);
                let before = screwdriver::euler_xyz(orientation.to_rotation_matrix().matrix())[2];
                let mut next = UnitQuaternion::from_scaled_axis(w) * *orientation;
                next.renormalize();
                let after = screwdriver::euler_xyz(next.to_rotation_matrix().matrix())[2];
                *yaw += wrap_angle(after - before);
                *orientation = next;
            }
            ObjectState::Card { pose, theta } => {
                let before = heading(&pose.rotation);
                pose.translation.vector += Vector3::new(dq[0], dq[1], dq[2]);
                let mut rot = UnitQuaternion::from_scaled_axis(Vector3::new(dq[3], dq[4], dq[5]))
                    * pose.rotation;
                rot.renormalize();
                pose.rotation = rot;
                *theta += wrap_angle(heading(&rot) - before);
            }
        }
    }
}

/// Something noteworthy about a step that did not stop it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StepFlag {
    /// Clarabel returned `AlmostSolved` (reduced accuracy) at this sub-step; the step was applied.
    ReducedAccuracy {
        /// Sub-step index within the action.
        substep: usize,
    },
    /// The screwdriver's roll or pitch passed its ±1.57 joint limit (not modelled as a stop).
    TiltLimit,
    /// Staggered friction iterations hit their limit before the normal forces (and the
    /// re-linearised geometry) settled; the last iterate was applied.
    FrictionNotConverged {
        /// Sub-step index within the action.
        substep: usize,
        /// Largest remaining normal-force change (N) or signed-distance mismatch (m).
        change: f64,
    },
    /// Staggered friction did not settle and this sub-step used the Anitescu cone instead
    /// ([`WorldParams::staggered_fallback`]).
    FrictionFallback {
        /// Sub-step index within the action.
        substep: usize,
        /// Largest remaining normal-force change (N) or signed-distance mismatch (m).
        change: f64,
    },
}

/// What one action did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepReport {
    /// Sub-steps solved (fewer than `substeps` when stopped early).
    pub substeps_run: usize,
    /// Contacts of the last solved sub-step with their forces.
    pub contacts: Vec<ContactReport>,
    /// Deepest penetration among fingertip/object/table pairs after the action (m, ≥ 0).
    pub max_penetration: f64,
    /// Interior-point iterations summed over all solves.
    pub iterations: u32,
    /// Clarabel solves (more than one per sub-step with staggered friction).
    pub solves: u32,
    /// Warnings that did not stop the step.
    pub flags: Vec<StepFlag>,
}

/// Errors from the world.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// The action has the wrong length for the scene.
    #[error("action has {got} numbers but the {scene} task needs {expected}")]
    ActionLength {
        /// Scene name.
        scene: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A state row has the wrong length for the scene.
    #[error("state has {got} numbers but the {scene} task needs {expected}")]
    StateLength {
        /// Scene name.
        scene: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A number in an action, target or state is NaN or infinite.
    #[error("{what} entry {index} is not finite ({value})")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Index in it.
        index: usize,
        /// The value.
        value: f64,
    },
    /// Clarabel did not solve a sub-step; the world is left as it was before the action.
    #[error("contact solve failed at sub-step {substep}: Clarabel status {status}")]
    Solver {
        /// Sub-step index within the action.
        substep: usize,
        /// Clarabel's status.
        status: String,
    },
    /// A world parameter is out of range.
    #[error("world parameter {name} = {value} is not allowed: it must be {allowed}")]
    Params {
        /// Parameter name (a [`WorldParams`] field).
        name: &'static str,
        /// The given value.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// Clarabel rejected the problem data (a defect in the world).
    #[error("contact program rejected by Clarabel: {0}")]
    Setup(String),
}

/// The simulated hand and object.
#[derive(Debug, Clone)]
pub struct World {
    scene: SceneKind,
    hand: HandModel,
    base: Isometry3<f64>,
    params: WorldParams,
    joints: HandJoints,
    object: ObjectState,
    object_body: Body,
    table: Option<Body>,
    last_contacts: Vec<ContactReport>,
    /// Normal forces of the last sub-step by contact key (warm start for staggered friction).
    normal_memory: Vec<(ContactKey, f64)>,
}

type ContactKey = (&'static str, &'static str, usize);

fn check_finite(what: &'static str, v: &[f64]) -> Result<(), WorldError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(WorldError::NonFinite {
            what,
            index,
            value: v[index],
        }),
        None => Ok(()),
    }
}

impl World {
    /// A scene at its default joints and initial object pose, with default parameters.
    pub fn new(scene: SceneKind) -> World {
        World::build(
            scene,
            HandModel::allegro_v4(),
            WorldParams::for_scene(scene),
        )
    }

    /// A scene with a given hand description and parameters (checked with
    /// [`WorldParams::validate`]).
    pub fn with_model(
        scene: SceneKind,
        hand: HandModel,
        params: WorldParams,
    ) -> Result<World, WorldError> {
        params.validate()?;
        Ok(World::build(scene, hand, params))
    }

    fn build(scene: SceneKind, hand: HandModel, params: WorldParams) -> World {
        let joints = scene.default_joints();
        let (object_body, table) = match scene {
            SceneKind::Screwdriver => (Body::screwdriver(), None),
            SceneKind::Card => (Body::card(), Some(Body::table())),
        };
        let mut world = World {
            scene,
            base: scene.hand_base(),
            hand,
            params,
            joints,
            object: ObjectState::initial(scene),
            object_body,
            table,
            last_contacts: Vec::new(),
            normal_memory: Vec::new(),
        };
        world.resolve_penetration();
        world
    }

    /// Move penetrating task fingertips out of the object (and table) along the contact normal
    /// by a few damped least-squares IK steps, leaving the object where it is. Isaac resolves
    /// the reset's overlaps by running physics; doing it kinematically keeps the object at its
    /// nominal start. [`World::new`] calls this; call it again after [`World::set_state`] if
    /// the new state may overlap.
    pub fn resolve_penetration(&mut self) {
        let r = self.hand.tip_radius;
        for f in self.scene.task_fingers() {
            for _ in 0..20 {
                let q = self.joints[f.index()];
                let c = self.hand.tip_center(&self.base, *f, &q);
                let mut worst: Option<(f64, Vector3<f64>)> = None;
                let mut consider = |phi: f64, n: Vector3<f64>| {
                    if phi < 0.0 && worst.is_none_or(|(w, _)| phi < w) {
                        worst = Some((phi, n));
                    }
                };
                let on_obj = self
                    .object_body
                    .sphere_contact(&self.object.pose(), &c, r, 0.0);
                if let Some(k) = on_obj {
                    consider(k.phi, k.normal);
                }
                if let Some(t) = &self.table
                    && let Some(k) = t.sphere_contact(&Isometry3::identity(), &c, r, 0.0)
                {
                    consider(k.phi, k.normal);
                }
                let Some((phi, n)) = worst else { break };
                if phi > -1e-7 {
                    break;
                }
                let dq = self
                    .hand
                    .tip_ik_step(&self.base, *f, &q, &(n * (-phi + 1e-6)), 1e-3);
                let next: [f64; 4] = std::array::from_fn(|j| q[j] + dq[j]);
                self.joints[f.index()] = self.hand.clamp_to_limits(*f, &next);
            }
        }
    }

    /// The scene.
    pub fn scene(&self) -> SceneKind {
        self.scene
    }

    /// The parameters.
    pub fn params(&self) -> &WorldParams {
        &self.params
    }

    /// The hand description.
    pub fn hand_model(&self) -> &HandModel {
        &self.hand
    }

    /// The hand base pose.
    pub fn hand_base(&self) -> Isometry3<f64> {
        self.base
    }

    /// All sixteen joints (non-task fingers stay at their defaults).
    pub fn joints(&self) -> HandJoints {
        self.joints
    }

    /// The task fingers' joints in `docs/contracts.md` §2 order (12 or 8).
    pub fn task_joints(&self) -> Vec<f64> {
        self.scene
            .task_fingers()
            .iter()
            .flat_map(|f| self.joints[f.index()])
            .collect()
    }

    /// The object's configuration.
    pub fn object(&self) -> &ObjectState {
        &self.object
    }

    /// The object body's parts (for drawing and distance queries).
    pub fn object_body(&self) -> &Body {
        &self.object_body
    }

    /// Raw state row: task joints then `(roll, pitch, yaw)` or `(x, y, θ)` (15 or 11 numbers).
    pub fn state(&self) -> Vec<f64> {
        let mut s = self.task_joints();
        s.extend(self.object.coords());
        s
    }

    /// Set the state from a raw row (task joints then object coordinates). The card is placed
    /// flat at its resting height.
    pub fn set_state(&mut self, state: &[f64]) -> Result<(), WorldError> {
        let n = self.scene.state_dim();
        if state.len() != n {
            return Err(WorldError::StateLength {
                scene: self.scene.name(),
                expected: n,
                got: state.len(),
            });
        }
        check_finite("state", state)?;
        for (k, f) in self.scene.task_fingers().iter().enumerate() {
            let q = [
                state[4 * k],
                state[4 * k + 1],
                state[4 * k + 2],
                state[4 * k + 3],
            ];
            self.joints[f.index()] = self.hand.clamp_to_limits(*f, &q);
        }
        let a = self.scene.action_dim();
        self.object = ObjectState::from_coords(self.scene, [state[a], state[a + 1], state[a + 2]]);
        self.last_contacts.clear();
        self.normal_memory.clear();
        Ok(())
    }

    /// Set all joints directly (clamped to limits).
    pub fn set_joints(&mut self, joints: &HandJoints) {
        for f in Finger::ALL {
            self.joints[f.index()] = self.hand.clamp_to_limits(f, &joints[f.index()]);
        }
    }

    /// Set the object's configuration directly.
    pub fn set_object(&mut self, object: ObjectState) {
        self.object = object;
        self.normal_memory.clear();
    }

    /// Task validity of the current state (see [`ObjectState::valid`]).
    pub fn valid(&self) -> bool {
        self.object.valid()
    }

    /// Contacts of the last solved sub-step.
    pub fn last_contacts(&self) -> &[ContactReport] {
        &self.last_contacts
    }

    /// World-frame fingertip sphere centres of all four fingers.
    pub fn tip_centers(&self) -> [Point3<f64>; 4] {
        self.hand.tip_centers(&self.base, &self.joints)
    }

    /// Signed distance from each task finger's tip sphere to the object (task order).
    pub fn tip_distances(&self) -> Vec<f64> {
        let pose = self.object.pose();
        self.scene
            .task_fingers()
            .iter()
            .map(|f| {
                let c = self
                    .hand
                    .tip_center(&self.base, *f, &self.joints[f.index()]);
                self.object_body
                    .sphere_distance(&pose, &c, self.hand.tip_radius)
            })
            .collect()
    }

    /// Deepest current penetration (m, ≥ 0) among tip/object, tip/table and card/table pairs.
    pub fn max_penetration(&self) -> f64 {
        let pose = self.object.pose();
        let r = self.hand.tip_radius;
        let mut worst: f64 = 0.0;
        for f in self.scene.task_fingers() {
            let c = self
                .hand
                .tip_center(&self.base, *f, &self.joints[f.index()]);
            worst = worst.max(-self.object_body.sphere_distance(&pose, &c, r));
            if let Some(t) = &self.table {
                worst = worst.max(-t.sphere_distance(&Isometry3::identity(), &c, r));
            }
        }
        if self.table.is_some() {
            for p in contacts::card_table_vertices(&pose) {
                worst = worst.max(card::TABLE_TOP - p.z);
            }
        }
        worst
    }

    /// Execute one action: joint deltas for the task fingers (`docs/contracts.md` §2 order) relative
    /// to the current measured joints, held for one action duration.
    pub fn step_action(&mut self, dq: &[f64]) -> Result<StepReport, WorldError> {
        let n = self.scene.action_dim();
        if dq.len() != n {
            return Err(WorldError::ActionLength {
                scene: self.scene.name(),
                expected: n,
                got: dq.len(),
            });
        }
        check_finite("action", dq)?;
        let mut targets = self.joints;
        for (k, f) in self.scene.task_fingers().iter().enumerate() {
            for j in 0..4 {
                targets[f.index()][j] += dq[4 * k + j];
            }
        }
        self.step_targets(&targets)
    }

    /// Execute one action given absolute joint targets for all sixteen joints (targets of
    /// non-task fingers are ignored: they hold their defaults). Targets are clamped to limits.
    pub fn step_targets(&mut self, targets: &HandJoints) -> Result<StepReport, WorldError> {
        check_finite("target", targets.as_flattened())?;
        let fingers = self.scene.task_fingers();
        let q_cmd: Vec<f64> = fingers
            .iter()
            .flat_map(|f| self.hand.clamp_to_limits(*f, &targets[f.index()]))
            .collect();
        let mut report = StepReport {
            substeps_run: 0,
            contacts: Vec::new(),
            max_penetration: 0.0,
            iterations: 0,
            solves: 0,
            flags: Vec::new(),
        };
        let saved = (
            self.joints,
            self.object.clone(),
            self.last_contacts.clone(),
            self.normal_memory.clone(),
        );
        // The controller's setpoint per sub-step (see `CommandProfile`).
        let q_start = self.task_joints();
        let substeps = self.params.substeps;
        let ramping = self.params.command_profile == CommandProfile::Ramp && q_cmd != q_start;
        let ramp = self.params.ramp_substeps();
        for substep in 0..substeps {
            let setpoint: Vec<f64> = if ramping {
                let s = ((substep + 1) as f64 / ramp as f64).min(1.0);
                q_start
                    .iter()
                    .zip(&q_cmd)
                    .map(|(a, b)| a + s * (b - a))
                    .collect()
            } else {
                q_cmd.clone()
            };
            let SubstepResult {
                dx,
                contacts,
                iters,
                solves,
                status,
                unconverged,
                fell_back,
                memory,
            } = match self.solve_substep(&setpoint, substep) {
                Ok(v) => v,
                Err(e) => {
                    (
                        self.joints,
                        self.object,
                        self.last_contacts,
                        self.normal_memory,
                    ) = saved;
                    return Err(e);
                }
            };
            report.substeps_run += 1;
            report.iterations += iters;
            report.solves += solves;
            if status == SolverStatus::AlmostSolved {
                report.flags.push(StepFlag::ReducedAccuracy { substep });
            }
            if let Some(change) = unconverged {
                report.flags.push(if fell_back {
                    StepFlag::FrictionFallback { substep, change }
                } else {
                    StepFlag::FrictionNotConverged { substep, change }
                });
            }
            self.apply_increment(&dx);
            self.last_contacts = contacts;
            self.normal_memory = memory;
            // Settled, and the setpoint will not move any more.
            let norm = dx.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm < self.params.early_stop && (!ramping || substep + 1 >= ramp) {
                break;
            }
        }
        report.contacts = self.last_contacts.clone();
        report.max_penetration = self.max_penetration();
        if let ObjectState::Screwdriver { .. } = self.object {
            let [roll, pitch, _] = self.object.coords();
            if roll.abs() > screwdriver::TILT_LIMIT || pitch.abs() > screwdriver::TILT_LIMIT {
                report.flags.push(StepFlag::TiltLimit);
            }
        }
        Ok(report)
    }

    /// Object block of P (regularised mass plus damping over h) and the gravity force term.
    fn object_block(&self) -> (DMatrix<f64>, Vec<f64>) {
        let p = &self.params;
        let h = p.h();
        let g = p.gravity;
        match &self.object {
            ObjectState::Screwdriver { orientation, .. } => {
                let r = orientation.to_rotation_matrix();
                let i_body = Matrix3::from_diagonal(&Vector3::from(screwdriver::INERTIA_PIVOT));
                let max_i = screwdriver::INERTIA_PIVOT
                    .iter()
                    .copied()
                    .fold(0.0, f64::max);
                let eps = regulariser(p.kp, p.mass_scale, max_i);
                let m_world = r.matrix() * i_body * r.matrix().transpose() * eps;
                // Joint-space damping D on (roll, pitch, yaw) mapped to ω: ω = E θ̇, so the
                // damping quadratic form is E⁻ᵀ D E⁻¹.
                let [roll, pitch, _] = self.object.coords();
                let e = Matrix3::from_columns(&[
                    Vector3::x(),
                    Rotation3::from_axis_angle(&Vector3::x_axis(), roll) * Vector3::y(),
                    (Rotation3::from_axis_angle(&Vector3::x_axis(), roll)
                        * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch))
                        * Vector3::z(),
                ]);
                let e_inv = e.try_inverse().unwrap_or_else(Matrix3::identity);
                let d = Matrix3::from_diagonal(&Vector3::from(p.damping));
                let damp = e_inv.transpose() * d * e_inv / h;
                let block = m_world + damp + Matrix3::identity() * 1e-9;
                let com = r * Vector3::new(0.0, 0.0, screwdriver::COM_HEIGHT);
                let torque = com.cross(&Vector3::new(0.0, 0.0, -screwdriver::MASS * g));
                (
                    DMatrix::from_iterator(3, 3, block.iter().copied()),
                    torque.iter().copied().collect(),
                )
            }
            ObjectState::Card { pose, .. } => {
                let inertia = card::inertia();
                let max_m = card::MASS.max(inertia.iter().copied().fold(0.0, f64::max));
                let eps = regulariser(p.kp, p.mass_scale, max_m);
                let rot = pose.rotation.to_rotation_matrix();
                let i_world = rot.matrix()
                    * Matrix3::from_diagonal(&Vector3::from(inertia))
                    * rot.matrix().transpose();
                let mut block = DMatrix::zeros(6, 6);
                for i in 0..3 {
                    block[(i, i)] = eps * card::MASS + p.damping[0] / h + 1e-9;
                    for j in 0..3 {
                        block[(3 + i, 3 + j)] = eps * i_world[(i, j)];
                    }
                    block[(3 + i, 3 + i)] += p.damping[0] / h + 1e-9;
                }
                (block, vec![0.0, 0.0, -card::MASS * g, 0.0, 0.0, 0.0])
            }
        }
    }

    /// Contact candidates at a trial configuration (the start of the sub-step plus `guess`),
    /// with φ shifted so the rows constrain the increment measured from the sub-step start:
    /// `φ(trial) + nᵀJ (δq − guess) ≥ 0`.
    fn candidates_at(&self, guess: &[f64]) -> Vec<contacts::Candidate> {
        let fingers = self.scene.task_fingers();
        let mut joints = self.joints;
        for (k, f) in fingers.iter().enumerate() {
            for j in 0..4 {
                joints[f.index()][j] += guess[4 * k + j];
            }
        }
        let mut object = self.object.clone();
        object.apply(&guess[4 * fingers.len()..]);
        let frames: Vec<FingerFrames> = fingers
            .iter()
            .map(|f| self.hand.finger_frames(&self.base, *f, &joints[f.index()]))
            .collect();
        let names: Vec<&'static str> = fingers.iter().map(|f| f.name()).collect();
        let pose = object.pose();
        let dofs = match object {
            ObjectState::Screwdriver { .. } => contacts::ObjectDofs::Pivot {
                pivot: screwdriver::pivot(),
            },
            ObjectState::Card { pose, .. } => contacts::ObjectDofs::Free {
                origin: Point3::from(pose.translation.vector),
            },
        };
        let mut cands = contacts::candidates(&contacts::ContactInputs {
            scene: self.scene,
            hand: &self.hand,
            frames: &frames,
            finger_names: &names,
            object: &self.object_body,
            object_pose: &pose,
            dofs,
            table: self.table.as_ref(),
            margin: self.params.contact_margin,
            table_margin: 0.25 * self.params.contact_margin,
            finger_friction: self.params.finger_friction,
            finger_table_friction: self.params.finger_table_friction,
            table_friction: self.params.table_friction,
        });
        if guess.iter().any(|g| *g != 0.0) {
            let g = nalgebra::DVector::from_column_slice(guess);
            for cand in &mut cands {
                let moved = (cand.row.normal.transpose() * (&cand.row.jac * &g))[0];
                cand.row.phi -= moved;
            }
        }
        cands
    }

    fn solve_substep(&self, setpoint: &[f64], substep: usize) -> Result<SubstepResult, WorldError> {
        let fingers = self.scene.task_fingers();
        let n_a = 4 * fingers.len();
        let n_u = match self.object {
            ObjectState::Screwdriver { .. } => 3,
            ObjectState::Card { .. } => 6,
        };
        let n = n_a + n_u;
        let (block, force_u) = self.object_block();
        let mut p = DMatrix::zeros(n, n);
        let mut c = vec![0.0; n];
        let q_now = self.task_joints();
        for i in 0..n_a {
            p[(i, i)] = self.params.kp + self.params.joint_damping / self.params.h();
            c[i] = -self.params.kp * (setpoint[i] - q_now[i]);
        }
        p.view_mut((n_a, n_a), (n_u, n_u)).copy_from(&block);
        for (i, f) in force_u.iter().enumerate() {
            c[n_a + i] = -f;
        }
        let bounds: Vec<(f64, f64)> = if self.params.enforce_joint_limits {
            fingers
                .iter()
                .enumerate()
                .flat_map(|(k, f)| {
                    let lim = self.hand.joint_limits(*f);
                    let q = &q_now;
                    (0..4).map(move |j| (lim[j].0 - q[4 * k + j], lim[j].1 - q[4 * k + j]))
                })
                .map(|(lo, hi)| (lo.min(0.0), hi.max(0.0)))
                .collect()
        } else {
            Vec::new()
        };
        let check = |sol: &socp::Solution| -> Result<(), WorldError> {
            match sol.status {
                SolverStatus::Solved | SolverStatus::AlmostSolved => {}
                other => {
                    return Err(WorldError::Solver {
                        substep,
                        status: format!("{other:?}"),
                    });
                }
            }
            if sol
                .x
                .iter()
                .chain(sol.normal_forces.iter())
                .any(|v| !v.is_finite())
            {
                return Err(WorldError::Solver {
                    substep,
                    status: "non-finite solution".into(),
                });
            }
            Ok(())
        };
        let mut iters = 0;
        let mut solves = 0;
        let mut unconverged = None;
        let mut worst_status = SolverStatus::Solved;
        // The Anitescu solve, with the number of solves it took.
        type AnitescuResult = (socp::Solution, Vec<contacts::Candidate>, u32);
        let anitescu = || -> Result<AnitescuResult, WorldError> {
            let cands = self.candidates_at(&vec![0.0; n]);
            let rows: Vec<socp::ConeRow> = cands.iter().map(|c| c.row.clone()).collect();
            let solve_with = |cone: &[bool]| -> Result<socp::Solution, WorldError> {
                let sol = socp::solve(&socp::Program {
                    p: &p,
                    c: &c,
                    cones: &rows,
                    bounds: &bounds,
                    max_iter: self.params.solver_max_iter,
                    friction: socp::FrictionForm::Anitescu { cone },
                })
                .map_err(WorldError::Setup)?;
                check(&sol)?;
                Ok(sol)
            };
            match self.params.cone_activation {
                ConeActivation::All => Ok((solve_with(&vec![true; rows.len()])?, cands, 1)),
                ConeActivation::Pressing => {
                    let probe = solve_with(&vec![false; rows.len()])?;
                    // Pressing in the frictionless probe, or pressed at the end of the
                    // previous sub-step: a pressed contact that slid ends its sub-step lifted
                    // by μ·slip and keeps its friction while it is held against the object.
                    let cone: Vec<bool> = probe
                        .normal_forces
                        .iter()
                        .zip(&cands)
                        .map(|(f, cand)| {
                            *f > PRESSING_FORCE
                                || self
                                    .normal_memory
                                    .iter()
                                    .any(|(k, m)| *k == cand.key && *m > PRESSING_FORCE)
                        })
                        .collect();
                    if !cone.contains(&true) {
                        return Ok((probe, cands, 1));
                    }
                    let sol = solve_with(&cone)?;
                    Ok((
                        socp::Solution {
                            iterations: sol.iterations + probe.iterations,
                            ..sol
                        },
                        cands,
                        2,
                    ))
                }
            }
        };
        let mut fell_back = false;
        let (sol, cands) = match self.params.friction_model {
            FrictionModel::Anitescu => {
                let (sol, cands, n_solves) = anitescu()?;
                iters += sol.iterations;
                solves += n_solves;
                worst_status = sol.status;
                (sol, cands)
            }
            FrictionModel::Staggered => {
                // Two coupled fixed points, iterated together:
                // - the contact geometry is re-linearised at the latest predicted configuration
                //   (sequential convex programming on φ(q + δq) ≥ 0), and
                // - the friction bounds μN use the latest normal forces N (staggered
                //   projections), relaxed with Aitken's dynamic factor: the plain iteration
                //   alternates (ratio ≈ −0.5) on the card and creeps (≈ +0.3) on the screwdriver.
                let mut cands = self.candidates_at(&vec![0.0; n]);
                let mut known: Vec<(ContactKey, f64)> = self.normal_memory.clone();
                let mut omega: f64 = 1.0;
                let mut prev: Option<(Vec<ContactKey>, Vec<f64>)> = None;
                let mut last = None;
                for _ in 0..self.params.staggered_iterations {
                    let keys: Vec<ContactKey> = cands.iter().map(|c| c.key).collect();
                    let normals: Vec<f64> = keys
                        .iter()
                        .map(|key| {
                            known
                                .iter()
                                .find(|(k, _)| k == key)
                                .map_or(0.0, |(_, f)| *f)
                        })
                        .collect();
                    let rows: Vec<socp::ConeRow> = cands.iter().map(|c| c.row.clone()).collect();
                    let prog = socp::Program {
                        p: &p,
                        c: &c,
                        cones: &rows,
                        bounds: &bounds,
                        max_iter: self.params.solver_max_iter,
                        friction: socp::FrictionForm::Lagged(&normals),
                    };
                    let sol = socp::solve(&prog).map_err(WorldError::Setup)?;
                    check(&sol)?;
                    iters += sol.iterations;
                    solves += 1;
                    if sol.status == SolverStatus::AlmostSolved {
                        worst_status = SolverStatus::AlmostSolved;
                    }
                    let residual: Vec<f64> = sol
                        .normal_forces
                        .iter()
                        .zip(&normals)
                        .map(|(g, n)| g.max(0.0) - n)
                        .collect();
                    let change = residual.iter().fold(0.0, |m: f64, r| m.max(r.abs()));
                    let largest = sol.normal_forces.iter().copied().fold(0.0, f64::max);
                    let tol = self.params.staggered_tolerance
                        + self.params.staggered_relative_tolerance * largest;
                    // Geometry: does the linearisation predict the true signed distances at the
                    // solution? (New penetrating contacts count as errors.)
                    let next = self.candidates_at(&sol.x);
                    let xv = nalgebra::DVector::from_column_slice(&sol.x);
                    let mut geom: f64 = 0.0;
                    for nc in &next {
                        match cands.iter().find(|c| c.key == nc.key) {
                            Some(c) => {
                                let predicted =
                                    c.row.phi + (c.row.normal.transpose() * (&c.row.jac * &xv))[0];
                                geom = geom.max((nc.phi_at_trial - predicted).abs());
                            }
                            None => geom = geom.max(-nc.phi_at_trial),
                        }
                    }
                    let converged = change <= tol && geom <= self.params.geometry_tolerance;
                    unconverged = (!converged).then_some(change.max(geom));
                    last = Some((sol, std::mem::replace(&mut cands, next)));
                    if converged {
                        break;
                    }
                    match &prev {
                        Some((prev_keys, prev_res)) if *prev_keys == keys => {
                            let dr: Vec<f64> =
                                residual.iter().zip(prev_res).map(|(a, b)| a - b).collect();
                            let denom: f64 = dr.iter().map(|d| d * d).sum();
                            if denom > 0.0 {
                                let num: f64 = prev_res.iter().zip(&dr).map(|(a, b)| a * b).sum();
                                omega = (-omega * num / denom).clamp(0.4, 1.5);
                            }
                        }
                        _ => omega = 1.0,
                    }
                    known = keys
                        .iter()
                        .zip(normals.iter().zip(&residual))
                        .map(|(k, (n, r))| (*k, (n + omega * r).max(0.0)))
                        .collect();
                    prev = Some((keys, residual));
                }
                let result =
                    last.ok_or_else(|| WorldError::Setup("no staggered iteration ran".into()))?;
                if unconverged.is_some() && self.params.staggered_fallback {
                    // No fixed point (e.g. wedging at high μ): take the convex cone model's
                    // answer for this sub-step and say so.
                    let (sol, cands, n_solves) = anitescu()?;
                    iters += sol.iterations;
                    solves += n_solves;
                    if sol.status == SolverStatus::AlmostSolved {
                        worst_status = SolverStatus::AlmostSolved;
                    }
                    fell_back = true;
                    (sol, cands)
                } else {
                    result
                }
            }
        };
        let memory = cands
            .iter()
            .zip(&sol.normal_forces)
            .map(|(cand, f)| (cand.key, f.max(0.0)))
            .collect();
        let reports = cands
            .iter()
            .zip(&sol.forces_on_a)
            .map(|(cand, f_a)| {
                // Force exerted by A (finger or card) on B (the part) is −(force on A).
                let f = -f_a;
                ContactReport {
                    finger: cand.finger.to_string(),
                    part: cand.part.to_string(),
                    point: [cand.point.x, cand.point.y, cand.point.z],
                    normal: [cand.row.normal.x, cand.row.normal.y, cand.row.normal.z],
                    force: [f.x, f.y, f.z],
                    phi: cand.row.phi,
                }
            })
            .collect();
        Ok(SubstepResult {
            dx: sol.x,
            contacts: reports,
            iters,
            solves,
            status: worst_status,
            unconverged,
            fell_back,
            memory,
        })
    }

    fn apply_increment(&mut self, dx: &[f64]) {
        let fingers = self.scene.task_fingers();
        for (k, f) in fingers.iter().enumerate() {
            for j in 0..4 {
                self.joints[f.index()][j] += dx[4 * k + j];
            }
        }
        self.object.apply(&dx[4 * fingers.len()..]);
    }
}

/// The force columns of a `docs/contracts.md` §2 action row from a step's contacts: for each task
/// finger the force it exerts on the object (world frame, N; zero when not touching), then for
/// the card the environment force `f_env`, the force of the table on the card. 9 numbers in
/// both scenes.
pub fn force_columns(scene: SceneKind, contacts: &[ContactReport]) -> Vec<f64> {
    let object_parts: &[&str] = match scene {
        SceneKind::Screwdriver => &["shaft", "handle", "cap"],
        SceneKind::Card => &["card"],
    };
    let mut out = Vec::with_capacity(9);
    for f in scene.task_fingers() {
        let mut sum = [0.0; 3];
        for c in contacts
            .iter()
            .filter(|c| c.finger == f.name() && object_parts.contains(&c.part.as_str()))
        {
            for (s, f) in sum.iter_mut().zip(c.force) {
                *s += f;
            }
        }
        out.extend(sum);
    }
    if scene == SceneKind::Card {
        let mut env = [0.0; 3];
        for c in contacts
            .iter()
            .filter(|c| c.finger == "card" && c.part == "table")
        {
            for (e, f) in env.iter_mut().zip(c.force) {
                *e -= f;
            }
        }
        out.extend(env);
    }
    out
}

/// A candidate presses when its frictionless normal force (or its normal force at the end of
/// the previous sub-step) exceeds this (N); interior-point duals of separated candidates are
/// ≲ 1e-7 N.
const PRESSING_FORCE: f64 = 1e-5;

/// What one sub-step produced.
struct SubstepResult {
    dx: Vec<f64>,
    contacts: Vec<ContactReport>,
    iters: u32,
    solves: u32,
    status: SolverStatus,
    unconverged: Option<f64>,
    fell_back: bool,
    memory: Vec<(ContactKey, f64)>,
}

/// qsim's mass scaling: `ε` such that the largest mass entry becomes `kp / s` (spec §1.1).
/// A non-positive or non-finite `s` means "use the true mass" (ε = 1).
fn regulariser(kp: f64, s: f64, max_mass: f64) -> f64 {
    if s.is_finite() && s > 0.0 && max_mass > 0.0 {
        kp / (s * max_mass)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_and_unwrap_yaw() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        let mut o = ObjectState::initial(SceneKind::Screwdriver);
        for _ in 0..40 {
            o.apply(&[0.0, 0.0, -0.2]);
        }
        assert!((o.coords()[2] + 8.0).abs() < 1e-9, "{:?}", o.coords());
    }

    #[test]
    fn force_columns_follow_the_contract() {
        let c = |finger: &str, part: &str, force: [f64; 3]| ContactReport {
            finger: finger.into(),
            part: part.into(),
            point: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
            force,
            phi: 0.0,
        };
        let contacts = vec![
            c("index", "card", [0.0, -1.0, -2.0]),
            c("index", "table", [5.0, 5.0, 5.0]),
            c("card", "table", [0.0, 0.5, -1.0]),
            c("card", "table", [0.0, 0.5, -1.1]),
        ];
        let cols = force_columns(SceneKind::Card, &contacts);
        assert_eq!(cols.len(), 9);
        assert_eq!(&cols[..3], &[0.0, -1.0, -2.0]);
        assert_eq!(&cols[3..6], &[0.0; 3]);
        assert!((cols[7] + 1.0).abs() < 1e-12 && (cols[8] - 2.1).abs() < 1e-12);
        let sd = vec![
            c("thumb", "handle", [1.0, 0.0, 0.0]),
            c("thumb", "cap", [0.0, 1.0, 0.0]),
        ];
        assert_eq!(
            force_columns(SceneKind::Screwdriver, &sd)[6..],
            [1.0, 1.0, 0.0]
        );
    }

    /// A free finger ends the action at its command under either profile; the ramp stops one
    /// sub-step after it reaches the command (8 of 10, then one settled sub-step), the step
    /// input one sub-step after the first.
    #[test]
    fn free_finger_reaches_its_command() {
        for profile in [CommandProfile::Ramp, CommandProfile::Step] {
            let mut params = WorldParams::for_scene(SceneKind::Card);
            params.command_profile = profile;
            let mut w =
                World::with_model(SceneKind::Card, HandModel::allegro_v4(), params).unwrap();
            // Lift the index and middle 2 cm (free motion), then command a joint move.
            let up = scripted::card_push_action(&w, 0.0, -0.02);
            w.step_action(&up).unwrap();
            let before = w.task_joints();
            let dq = [0.05, -0.04, 0.03, 0.02, -0.05, 0.04, -0.03, 0.02];
            let r = w.step_action(&dq).unwrap();
            let after = w.task_joints();
            for ((a, b), d) in after.iter().zip(&before).zip(&dq) {
                assert!((a - b - d).abs() < 1e-9, "{profile:?}: {a} vs {}", b + d);
            }
            let expected = match profile {
                CommandProfile::Ramp => 9,
                CommandProfile::Step => 2,
            };
            assert_eq!(r.substeps_run, expected, "{profile:?}");
        }
    }

    #[test]
    fn invalid_params_are_errors() {
        let mut p = WorldParams::for_scene(SceneKind::Screwdriver);
        p.substeps = 0;
        let e = World::with_model(SceneKind::Screwdriver, HandModel::allegro_v4(), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("substeps") && e.contains("≥ 1"), "{e}");
        let mut p = WorldParams::for_scene(SceneKind::Card);
        p.kp = f64::NAN;
        assert!(matches!(
            p.validate(),
            Err(WorldError::Params { name: "kp", .. })
        ));
        let mut p = WorldParams::for_scene(SceneKind::Card);
        p.finger_friction = 0.0;
        assert!(p.validate().is_err());
        assert!(WorldParams::for_scene(SceneKind::Card).validate().is_ok());
    }

    #[test]
    fn state_round_trip() {
        let mut w = World::new(SceneKind::Card);
        let mut s = w.state();
        assert_eq!(s.len(), 11);
        s[8] = 0.01;
        s[9] = -0.02;
        s[10] = 0.1;
        w.set_state(&s).unwrap();
        let back = w.state();
        for (a, b) in s.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!(matches!(
            w.set_state(&s[..5]),
            Err(WorldError::StateLength { .. })
        ));
        assert!(matches!(
            w.step_action(&[0.0; 3]),
            Err(WorldError::ActionLength { .. })
        ));
        assert!(matches!(
            w.step_action(&[f64::NAN; 8]),
            Err(WorldError::NonFinite { .. })
        ));
    }
}
