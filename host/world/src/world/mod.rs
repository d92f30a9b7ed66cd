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
mod params;
mod report;
pub mod scripted;
mod socp;
mod state;
mod substep;

use clarabel::solver::SolverStatus;
use nalgebra::{Isometry3, Point3, Vector3};

pub use contacts::ContactReport;
pub use params::{CommandProfile, ConeActivation, FrictionModel, WorldParams};
pub use report::{StepFlag, StepReport, WorldError};
pub use state::ObjectState;
use substep::SubstepResult;

use crate::geometry::Body;
use crate::kinematics::{Finger, HandJoints, HandModel};
use crate::scenes::{SceneKind, card, screwdriver};

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

#[cfg(test)]
mod tests {
    use super::state::wrap_angle;
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
