//! [`MujocoHand`]: a [`Hand`] executed as on the real Allegro hand. Each command is one
//! action: a host-side joint PD at 333 Hz tracks a reference that moves linearly from the
//! previous target to the new one over the action, with gravity and full dynamics in
//! MuJoCo; the object pose comes back as a tracker gives it (optionally with Gaussian noise).

use std::sync::Arc;

use dips_world::hand::{Hand, HandError, ObjectPose};
use dips_world::kinematics::{Finger, HandJoints, HandModel, first_non_finite};
use dips_world::scenes::{SceneKind, screwdriver};
use dips_world::world::{ContactReport, World, WorldError};
use mujoco_rs::prelude::*;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::scene::{self, MujocoParams};
use crate::{MujocoError, check_version};

/// Wrap an angle into (−π, π].
fn wrap_angle(a: f64) -> f64 {
    let r = (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    if r <= -std::f64::consts::PI {
        r + std::f64::consts::TAU
    } else {
        r
    }
}

/// The card's heading: its x axis's angle in the world x–y plane (our world's definition).
fn heading(r: &UnitQuaternion<f64>) -> f64 {
    let m = r.to_rotation_matrix();
    m[(1, 0)].atan2(m[(0, 0)])
}

/// The raw (wrapped) angle that the state's third coordinate unwraps.
fn raw_angle(scene: SceneKind, r: &UnitQuaternion<f64>) -> f64 {
    match scene {
        SceneKind::Screwdriver => screwdriver::euler_xyz(r.to_rotation_matrix().matrix())[2],
        SceneKind::Card => heading(r),
    }
}

/// `pose` with task coordinates, its third coordinate unwrapped by continuity from `raw`
/// (the previous raw angle) and `angle` (the previous unwrapped one), both updated.
fn unwrapped(scene: SceneKind, pose: Isometry3<f64>, raw: &mut f64, angle: &mut f64) -> ObjectPose {
    let r = raw_angle(scene, &pose.rotation);
    *angle += wrap_angle(r - *raw);
    *raw = r;
    let coords = match scene {
        SceneKind::Screwdriver => {
            let e = screwdriver::euler_xyz(pose.rotation.to_rotation_matrix().matrix());
            [e[0], e[1], *angle]
        }
        SceneKind::Card => [pose.translation.x, pose.translation.y, *angle],
    };
    ObjectPose { pose, coords }
}

/// A seeded Gaussian source (SplitMix64 + Box–Muller): the tracker's noise.
#[derive(Debug, Clone)]
struct Gaussian {
    state: u64,
}

impl Gaussian {
    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn uniform(&mut self) -> f64 {
        // In (0, 1]: never 0, so the logarithm below is finite.
        ((self.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// Where the finger joints and the object live in MuJoCo's arrays.
#[derive(Debug, Clone)]
struct Layout {
    /// `qpos` address of each finger joint, `[finger][joint]`.
    qpos: [[usize; 4]; 4],
    /// `qvel` (dof) address of each finger joint.
    dof: [[usize; 4]; 4],
    /// `qpos` address of the object's first coordinate.
    object_qpos: usize,
    /// The object body.
    object_body: usize,
    /// Each finger's tip sphere geom.
    tips: [usize; 4],
}

impl Layout {
    fn of(model: &MjModel, scene: SceneKind) -> Result<Layout, MujocoError> {
        let id = |ty: MjtObjBase, name: &str| {
            model
                .name_to_id(ty, name)
                .ok_or_else(|| MujocoError::Model(format!("the generated scene has no {name}")))
        };
        let qposadr = model.jnt_qposadr();
        let dofadr = model.jnt_dofadr();
        let mut qpos = [[0; 4]; 4];
        let mut dof = [[0; 4]; 4];
        let mut tips = [0; 4];
        for f in Finger::ALL {
            for j in 0..4 {
                let jid = id(MjtObjBase::mjOBJ_JOINT, &scene::joint_name(f, j))?;
                qpos[f.index()][j] = qposadr[jid] as usize;
                dof[f.index()][j] = dofadr[jid] as usize;
            }
            tips[f.index()] = id(MjtObjBase::mjOBJ_GEOM, &scene::tip_name(f))?;
        }
        let first_object_joint = match scene {
            SceneKind::Screwdriver => "screwdriver_roll",
            SceneKind::Card => "card",
        };
        let object_qpos = qposadr[id(MjtObjBase::mjOBJ_JOINT, first_object_joint)?] as usize;
        let object_body = id(MjtObjBase::mjOBJ_BODY, scene::object_body(scene))?;
        Ok(Layout {
            qpos,
            dof,
            object_qpos,
            object_body,
            tips,
        })
    }
}

/// Divergence warnings MuJoCo counts (it resets the state when they fire).
const DIVERGENCE_WARNINGS: [MjtWarning; 3] = [
    MjtWarning::mjWARN_BADQACC,
    MjtWarning::mjWARN_BADQPOS,
    MjtWarning::mjWARN_BADQVEL,
];

/// The Allegro hand and the task object simulated by MuJoCo, driven as the real hand is.
#[derive(Debug)]
pub struct MujocoHand {
    scene: SceneKind,
    hand: HandModel,
    params: MujocoParams,
    data: MjData<Arc<MjModel>>,
    layout: Layout,
    /// The PD's reference at the end of the last action (the last target).
    reference: HandJoints,
    /// The unwrapped third object coordinate of the last reported pose.
    angle: f64,
    /// The raw angle it was unwrapped from.
    raw: f64,
    /// The pose the tracker last reported.
    pose: ObjectPose,
    /// The true pose at the last report, unwrapped by its own continuity.
    truth: ObjectPose,
    /// The unwrapped third coordinate of the true pose.
    true_angle: f64,
    /// The raw angle it was unwrapped from.
    true_raw: f64,
    noise: Option<Gaussian>,
    xml: String,
}

impl MujocoHand {
    /// A scene with our Allegro description and the default parameters.
    pub fn new(scene: SceneKind) -> Result<MujocoHand, MujocoError> {
        MujocoHand::with_params(
            scene,
            HandModel::allegro_v4(),
            MujocoParams::for_scene(scene),
        )
    }

    /// A scene with a hand description and parameters. Checks the linked library's version
    /// first (an error naming `scripts/fetch-mujoco.sh`, never a panic), then builds the
    /// scene's MJCF and resets it to our world's start state.
    pub fn with_params(
        scene: SceneKind,
        hand: HandModel,
        params: MujocoParams,
    ) -> Result<MujocoHand, MujocoError> {
        check_version()?;
        params.validate()?;
        let xml = scene::scene_xml(scene, &hand, &params);
        let model =
            MjModel::from_xml_string(&xml).map_err(|e| MujocoError::Model(e.to_string()))?;
        let model = Arc::new(model);
        let layout = Layout::of(&model, scene)?;
        let data = MjData::try_new(model).map_err(|e| MujocoError::Model(e.to_string()))?;
        let noise = params.pose_noise.map(|n| Gaussian { state: n.seed });
        let mut this = MujocoHand {
            scene,
            hand,
            params,
            data,
            layout,
            reference: scene.default_joints(),
            angle: 0.0,
            raw: 0.0,
            pose: ObjectPose {
                pose: Isometry3::identity(),
                coords: [0.0; 3],
            },
            truth: ObjectPose {
                pose: Isometry3::identity(),
                coords: [0.0; 3],
            },
            true_angle: 0.0,
            true_raw: 0.0,
            noise,
            xml,
        };
        this.reset();
        Ok(this)
    }

    /// Back to our world's start state: the joints of [`World::new`] (default joints with the
    /// penetrating tips moved out) and the object at its nominal pose, at rest.
    pub fn reset(&mut self) {
        let start = World::new(self.scene);
        self.data.reset();
        let joints = start.joints();
        self.set_joints(&joints);
        let q = self.layout.object_qpos;
        match self.scene {
            SceneKind::Screwdriver => {
                let c = start.object().coords();
                self.data.qpos_mut()[q..q + 3].copy_from_slice(&c);
            }
            SceneKind::Card => {
                let p = start.object().pose();
                let r = p.rotation.quaternion();
                let v = [
                    p.translation.x,
                    p.translation.y,
                    p.translation.z,
                    r.w,
                    r.i,
                    r.j,
                    r.k,
                ];
                self.data.qpos_mut()[q..q + 7].copy_from_slice(&v);
            }
        }
        self.data.forward();
        self.reference = joints;
        let rot = self.true_pose().rotation;
        self.raw = raw_angle(self.scene, &rot);
        self.angle = start.object().coords()[2];
        self.true_raw = self.raw;
        self.true_angle = self.angle;
        self.observe();
    }

    /// Set the sixteen joint positions (velocities untouched; call `forward` to see them).
    fn set_joints(&mut self, q: &HandJoints) {
        for (addrs, values) in self.layout.qpos.iter().zip(q) {
            for (a, v) in addrs.iter().zip(values) {
                self.data.qpos_mut()[*a] = *v;
            }
        }
    }

    /// The generated MJCF text of this scene.
    pub fn xml(&self) -> &str {
        &self.xml
    }

    /// The parameters in use.
    pub fn params(&self) -> &MujocoParams {
        &self.params
    }

    /// The hand description the scene was generated from.
    pub fn hand_model(&self) -> &HandModel {
        &self.hand
    }

    /// The true object pose (no tracker noise).
    pub fn true_pose(&self) -> Isometry3<f64> {
        let b = self.layout.object_body;
        let p = self.data.xpos()[b];
        let q = self.data.xquat()[b];
        Isometry3::from_parts(
            Translation3::new(p[0], p[1], p[2]),
            UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
        )
    }

    /// Fingertip sphere centres as MuJoCo places them (world frame, indexed by
    /// [`Finger::index`]), after [`MujocoHand::set_joints_kinematic`] or an action.
    pub fn tip_centers(&self) -> [nalgebra::Point3<f64>; 4] {
        Finger::ALL.map(|f| {
            let g = self.data.geom_xpos()[self.layout.tips[f.index()]];
            nalgebra::Point3::new(g[0], g[1], g[2])
        })
    }

    /// Put the joints at `q` and run MuJoCo's kinematics (no time passes): for checking the
    /// generated chain against our forward kinematics.
    pub fn set_joints_kinematic(&mut self, q: &HandJoints) {
        self.set_joints(q);
        self.data.forward();
    }

    /// Read the pose as a tracker reports it now (the true pose with the configured noise)
    /// and the true pose, each with its third coordinate unwrapped by continuity from its
    /// previous reading.
    fn observe(&mut self) {
        let truth = self.true_pose();
        let mut pose = truth;
        if let (Some(g), Some(n)) = (self.noise.as_mut(), self.params.pose_noise) {
            let dp = Vector3::new(g.normal(), g.normal(), g.normal()) * n.position;
            let dr = Vector3::new(g.normal(), g.normal(), g.normal()) * n.rotation;
            pose.translation.vector += dp;
            pose.rotation = UnitQuaternion::from_scaled_axis(dr) * pose.rotation;
        }
        self.truth = unwrapped(self.scene, truth, &mut self.true_raw, &mut self.true_angle);
        self.pose = unwrapped(self.scene, pose, &mut self.raw, &mut self.angle);
    }

    /// The contacts MuJoCo found at the current state, in our report's form: `finger` is the
    /// pushing body (a fingertip's finger, or `card` on the table), `part` the touched geom,
    /// `point` on the part's surface, `normal` out of the part, `force` exerted by `finger`
    /// on `part` (world frame, N) and `phi` the signed distance (negative: penetration).
    pub fn contacts(&self) -> Vec<ContactReport> {
        let model = self.data.model();
        let name = |g: i32| {
            usize::try_from(g)
                .ok()
                .and_then(|g| model.id_to_name(MjtObjBase::mjOBJ_GEOM, g))
                .unwrap_or("?")
                .to_string()
        };
        self.data
            .contact()
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let (g1, g2) = (name(c.geom1), name(c.geom2));
                // The frame's first row is the normal, from geom1 to geom2; the force in the
                // contact frame is what geom1 exerts on geom2.
                let n = Vector3::new(c.frame[0], c.frame[1], c.frame[2]);
                let t1 = Vector3::new(c.frame[3], c.frame[4], c.frame[5]);
                let t2 = Vector3::new(c.frame[6], c.frame[7], c.frame[8]);
                let f = self.data.contact_force(i);
                let on_g2 = n * f[0] + t1 * f[1] + t2 * f[2];
                let pos = Vector3::from(c.pos);
                // The pusher is the fingertip, or the card on the table; MuJoCo may list it
                // second.
                let pusher_first = g1.ends_with("_tip") || (g1 == "card" && g2 == "table");
                let (pusher, part, force, normal, point) = if pusher_first {
                    (g1, g2, on_g2, -n, pos + n * (0.5 * c.dist))
                } else {
                    (g2, g1, -on_g2, n, pos - n * (0.5 * c.dist))
                };
                ContactReport {
                    finger: pusher.strip_suffix("_tip").unwrap_or(&pusher).to_string(),
                    part,
                    point: point.into(),
                    normal: normal.into(),
                    force: force.into(),
                    phi: c.dist,
                }
            })
            .collect()
    }

    /// The deepest penetration among the current contacts (m; 0 when none penetrates).
    pub fn max_penetration(&self) -> f64 {
        self.data
            .contact()
            .iter()
            .map(|c| -c.dist)
            .fold(0.0, f64::max)
    }

    fn warnings(&self) -> i64 {
        let w = self.data.warning();
        DIVERGENCE_WARNINGS
            .iter()
            .map(|k| i64::from(w[*k as usize].number))
            .sum()
    }

    /// Advance `dt` seconds (rounded to whole MuJoCo steps, at least one) with the finger
    /// joints driven by `torques` (N·m, bus order) and no PD of ours: what the emulated
    /// Allegro hand does under the torques its driver sends. Gravity acts; the driver's own
    /// gravity compensation, when on, is in `torques`. The tracker's pose is refreshed after.
    pub fn step_torques(&mut self, torques: &HandJoints, dt: f64) -> Result<(), MujocoError> {
        if let Some((index, value)) = first_non_finite(torques) {
            return Err(MujocoError::Target { index, value });
        }
        let steps = (dt / self.params.timestep()).round().max(1.0) as usize;
        let warnings = self.warnings();
        {
            let applied = self.data.qfrc_applied_mut();
            for f in 0..4 {
                for j in 0..4 {
                    applied[self.layout.dof[f][j]] = torques[f][j];
                }
            }
        }
        for _ in 0..steps {
            self.data.step();
        }
        if self.warnings() != warnings {
            return Err(MujocoError::Diverged {
                time: self.data.time(),
            });
        }
        self.data.forward();
        self.observe();
        Ok(())
    }

    /// Run one action towards `targets` (clamped to the joint limits): the PD reference moves
    /// linearly from the last target over the action. On divergence the state is left as
    /// MuJoCo reset it and the error says so.
    pub fn run_action(&mut self, targets: &HandJoints) -> Result<(), MujocoError> {
        if let Some((index, value)) = first_non_finite(targets) {
            return Err(MujocoError::Target { index, value });
        }
        let goal: HandJoints =
            Finger::ALL.map(|f| self.hand.clamp_to_limits(f, &targets[f.index()]));
        let start = self.reference;
        let ticks = self.params.ticks_per_action();
        let (kp, kd) = (self.params.kp, self.params.kd);
        let warnings = self.warnings();
        for tick in 1..=ticks {
            let s = tick as f64 / ticks as f64;
            // One PD update: the torque is held for the tick's MuJoCo steps.
            let mut torques = [[0.0; 4]; 4];
            {
                let qpos = self.data.qpos();
                let qvel = self.data.qvel();
                let bias = self.data.qfrc_bias();
                for f in 0..4 {
                    for j in 0..4 {
                        let r = start[f][j] + s * (goal[f][j] - start[f][j]);
                        let (a, d) = (self.layout.qpos[f][j], self.layout.dof[f][j]);
                        let mut t = kp * (r - qpos[a]) - kd * qvel[d];
                        if self.params.gravity_compensation {
                            t += bias[d];
                        }
                        torques[f][j] = t;
                    }
                }
            }
            {
                let applied = self.data.qfrc_applied_mut();
                for f in 0..4 {
                    for j in 0..4 {
                        applied[self.layout.dof[f][j]] = torques[f][j];
                    }
                }
            }
            for _ in 0..self.params.steps_per_tick {
                self.data.step();
            }
            if self.warnings() != warnings {
                return Err(MujocoError::Diverged {
                    time: self.data.time(),
                });
            }
        }
        self.reference = goal;
        // Positions after the last step: refresh the kinematics the tracker reads.
        self.data.forward();
        self.observe();
        Ok(())
    }
}

impl Hand for MujocoHand {
    fn name(&self) -> &'static str {
        "mujoco"
    }

    fn scene(&self) -> SceneKind {
        self.scene
    }

    fn joint_positions(&self) -> HandJoints {
        let q = self.data.qpos();
        Finger::ALL.map(|f| self.layout.qpos[f.index()].map(|a| q[a]))
    }

    fn object_pose(&self) -> ObjectPose {
        self.pose.clone()
    }

    fn true_object_pose(&self) -> ObjectPose {
        self.truth.clone()
    }

    fn command(&mut self, targets: &HandJoints) -> Result<(), HandError> {
        self.run_action(targets).map_err(|e| match e {
            MujocoError::Target { index, value } => HandError::World(WorldError::NonFinite {
                what: "joint target",
                index,
                value,
            }),
            other => HandError::Other {
                hand: "MuJoCo",
                message: other.to_string(),
            },
        })
    }

    fn contact_readings(&self) -> Option<Vec<ContactReport>> {
        Some(self.contacts())
    }
}
