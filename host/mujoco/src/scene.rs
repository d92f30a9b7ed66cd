//! The MuJoCo scenes, generated at run time as MJCF text from our own data: the Allegro chain
//! of [`HandModel`] (`host/data/allegro_v4.json`), the hand placement and object geometry of
//! `dips_world::scenes`, and the masses, damping and friction of [`WorldParams`]. What
//! MuJoCo needs and our world lacks (time step, solver, contact softness, link masses,
//! armature) is in [`MujocoParams`]; `docs/mujoco.md` gives each choice and its reason.

use std::fmt::Write as _;

use dips_world::kinematics::{Finger, HandModel};
use dips_world::scenes::{SceneKind, card, screwdriver};
use dips_world::world::WorldParams;
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::MujocoError;

pub use dips_world::kinematics::{FINGER_LINK_MASSES, THUMB_LINK_MASSES};

/// Radius (m) of the solid rod each link's inertia is computed for.
pub const LINK_RADIUS: f64 = 0.012;

/// Everything the MuJoCo hand needs beyond our world's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct MujocoParams {
    /// Rate of the host-side joint PD loop (Hz); the Allegro driver runs at 333 Hz.
    pub control_hz: f64,
    /// MuJoCo steps per PD tick (the torque is held between ticks): the time step is
    /// `1 / (control_hz · steps_per_tick)`.
    pub steps_per_tick: usize,
    /// Duration of one action (s); ours is 1 s.
    pub action_duration: f64,
    /// Joint stiffness kp of the PD (N·m/rad): our scene's.
    pub kp: f64,
    /// Joint damping kd of the PD (N·m·s/rad). Default: critical for the armature,
    /// `2·√(kp·armature)`.
    pub kd: f64,
    /// Reflected motor inertia on every finger joint (kg·m²).
    pub armature: f64,
    /// Add the model's bias forces (gravity, Coriolis) of the finger joints to the PD torque,
    /// as the Allegro driver's gravity compensation does.
    pub gravity_compensation: bool,
    /// Contact time constant (s) of MuJoCo's `solref` (damping ratio 1).
    pub contact_timeconst: f64,
    /// MuJoCo's `impratio`: how much harder the frictional dimensions of a contact are than
    /// its normal one (elliptic cones). At MuJoCo's default 1, a contact below its friction
    /// limit still slips slowly (soft friction); 10, as MuJoCo Menagerie's grasping scenes
    /// use, makes friction stick below the limit as dry friction does, without changing the
    /// friction coefficients (`docs/mujoco.md`).
    pub impratio: f64,
    /// Gaussian noise on the reported object pose: position σ (m), rotation σ (rad, per
    /// axis of a small rotation). `None`: the exact pose.
    pub pose_noise: Option<PoseNoise>,
    /// Our world's parameters: gravity, friction, object damping.
    pub world: WorldParams,
}

/// Gaussian noise of a simulated pose tracker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseNoise {
    /// Position σ (m).
    pub position: f64,
    /// Rotation σ (rad), per axis.
    pub rotation: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl MujocoParams {
    /// The defaults for a scene: our world's parameters and scene kp, the 333 Hz PD with
    /// gravity compensation, and the choices of `docs/mujoco.md`.
    pub fn for_scene(scene: SceneKind) -> MujocoParams {
        let world = WorldParams::for_scene(scene);
        let armature = 1e-3;
        MujocoParams {
            control_hz: 333.0,
            steps_per_tick: 6,
            action_duration: world.action_duration,
            kp: world.kp,
            kd: 2.0 * (world.kp * armature).sqrt(),
            armature,
            gravity_compensation: true,
            contact_timeconst: 0.01,
            impratio: 10.0,
            pose_noise: None,
            world,
        }
    }

    /// The MuJoCo time step (s).
    pub fn timestep(&self) -> f64 {
        1.0 / (self.control_hz * self.steps_per_tick as f64)
    }

    /// PD ticks per action.
    pub fn ticks_per_action(&self) -> usize {
        (self.action_duration * self.control_hz).round() as usize
    }

    /// Check every number; the error names the first bad one.
    pub fn validate(&self) -> Result<(), MujocoError> {
        let positive = [
            ("control_hz", self.control_hz),
            ("action_duration", self.action_duration),
            ("kp", self.kp),
            ("armature", self.armature),
            ("contact_timeconst", self.contact_timeconst),
            ("impratio", self.impratio),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(MujocoError::Settings(format!("{name} = {v} must be > 0")));
            }
        }
        if !(self.kd.is_finite() && self.kd >= 0.0) {
            return Err(MujocoError::Settings(format!(
                "kd = {} must be ≥ 0",
                self.kd
            )));
        }
        if self.steps_per_tick == 0 || self.ticks_per_action() == 0 {
            return Err(MujocoError::Settings(
                "steps_per_tick and action_duration·control_hz must be ≥ 1".into(),
            ));
        }
        if self.contact_timeconst < 2.0 * self.timestep() {
            return Err(MujocoError::Settings(format!(
                "contact_timeconst = {} is under two time steps ({}): MuJoCo would stiffen it",
                self.contact_timeconst,
                2.0 * self.timestep()
            )));
        }
        if let Some(n) = self.pose_noise
            && !(n.position.is_finite()
                && n.position >= 0.0
                && n.rotation.is_finite()
                && n.rotation >= 0.0)
        {
            return Err(MujocoError::Settings(format!(
                "pose noise σ must be finite and ≥ 0: {n:?}"
            )));
        }
        Ok(())
    }
}

/// Name of the hinge joint `j` (0..4) of a finger, and of the finger's tip geom.
pub fn joint_name(finger: Finger, j: usize) -> String {
    format!("{}_{j}", finger.name())
}

/// Name of a finger's fingertip sphere geom.
pub fn tip_name(finger: Finger) -> String {
    format!("{}_tip", finger.name())
}

/// Name of the object body (`screwdriver` or `card`).
pub fn object_body(scene: SceneKind) -> &'static str {
    scene.name()
}

fn v3(v: &Vector3<f64>) -> String {
    format!("{:?} {:?} {:?}", v.x, v.y, v.z)
}

fn quat(q: &UnitQuaternion<f64>) -> String {
    format!("{:?} {:?} {:?} {:?}", q.w, q.i, q.j, q.k)
}

fn frame(iso: &Isometry3<f64>) -> String {
    format!(
        r#"pos="{}" quat="{}""#,
        v3(&iso.translation.vector),
        quat(&iso.rotation)
    )
}

/// The MJCF text of a scene.
pub fn scene_xml(scene: SceneKind, hand: &HandModel, params: &MujocoParams) -> String {
    let w = &params.world;
    let mut x = String::new();
    let _ = writeln!(x, r#"<mujoco model="dips-{}">"#, scene.name());
    let _ = writeln!(x, r#"  <compiler angle="radian" autolimits="true"/>"#);
    let _ = writeln!(
        x,
        r#"  <option timestep="{:?}" gravity="0 0 {:?}" integrator="implicitfast" cone="elliptic" impratio="{:?}" solver="Newton" iterations="100" tolerance="1e-10"/>"#,
        params.timestep(),
        -w.gravity,
        params.impratio
    );
    let _ = writeln!(
        x,
        r#"  <default><geom contype="0" conaffinity="0" condim="3" solref="{:?} 1"/><joint armature="{:?}"/></default>"#,
        params.contact_timeconst, params.armature
    );
    let _ = writeln!(x, "  <worldbody>");
    // The hand: a fixed palm at the scene's base pose and four 4-joint chains.
    let _ = writeln!(x, r#"    <body name="palm" {}>"#, frame(&scene.hand_base()));
    for finger in Finger::ALL {
        let spec = hand.finger(finger);
        let masses = if finger == Finger::Thumb {
            THUMB_LINK_MASSES
        } else {
            FINGER_LINK_MASSES
        };
        for (j, joint) in spec.joints.iter().enumerate() {
            let indent = "  ".repeat(3 + j);
            let (lo, hi) = (joint.lower, joint.upper);
            // The link runs from this joint's origin to the next one (or to the tip centre).
            let end = if j + 1 < 4 {
                spec.joints[j + 1].origin.translation.vector
            } else {
                spec.tip_center
            };
            let m = masses[j];
            let l = end.norm();
            let r = LINK_RADIUS;
            let inertia = m * (3.0 * r * r + l * l) / 12.0;
            let _ = writeln!(
                x,
                r#"{indent}<body name="{}_link{j}" {}>"#,
                finger.name(),
                frame(&joint.origin)
            );
            let _ = writeln!(
                x,
                r#"{indent}  <joint name="{}" type="hinge" axis="{}" range="{lo:?} {hi:?}"/>"#,
                joint_name(finger, j),
                v3(&joint.axis.into_inner())
            );
            let _ = writeln!(
                x,
                r#"{indent}  <inertial pos="{}" mass="{m:?}" diaginertia="{inertia:?} {inertia:?} {inertia:?}"/>"#,
                v3(&(end * 0.5))
            );
        }
        let indent = "  ".repeat(7);
        let _ = writeln!(
            x,
            r#"{indent}<geom name="{}" type="sphere" size="{:?}" pos="{}"/>"#,
            tip_name(finger),
            hand.tip_radius,
            v3(&spec.tip_center)
        );
        for j in (0..4).rev() {
            let _ = writeln!(x, "{}</body>", "  ".repeat(3 + j));
        }
    }
    let _ = writeln!(x, "    </body>");
    match scene {
        SceneKind::Screwdriver => {
            let [px, py, pz] = screwdriver::PIVOT;
            let m = screwdriver::MASS;
            let c = screwdriver::COM_HEIGHT;
            let [ix, iy, iz] = screwdriver::INERTIA_PIVOT;
            // Parallel axis: our inertia is about the pivot, MuJoCo's about the centre of mass.
            let (icx, icy) = (ix - m * c * c, iy - m * c * c);
            let _ = writeln!(
                x,
                r#"    <body name="screwdriver" pos="{px:?} {py:?} {pz:?}">"#
            );
            // Roll, pitch, yaw as three hinges at the pivot: R = Rx·Ry·Rz, our state's
            // convention, each with our damping on its rate.
            for (axis, name, d) in [
                ("1 0 0", "roll", w.damping[0]),
                ("0 1 0", "pitch", w.damping[1]),
                ("0 0 1", "yaw", w.damping[2]),
            ] {
                let _ = writeln!(
                    x,
                    r#"      <joint name="screwdriver_{name}" type="hinge" axis="{axis}" damping="{d:?}" armature="0"/>"#
                );
            }
            let _ = writeln!(
                x,
                r#"      <inertial pos="0 0 {c:?}" mass="{m:?}" diaginertia="{icx:?} {icy:?} {iz:?}"/>"#
            );
            for (name, r, z0, z1) in [
                (
                    "shaft",
                    screwdriver::SHAFT_RADIUS,
                    0.0,
                    screwdriver::SHAFT_LENGTH,
                ),
                (
                    "handle",
                    screwdriver::HANDLE_RADIUS,
                    screwdriver::HANDLE_Z0,
                    screwdriver::HANDLE_Z1,
                ),
                (
                    "cap",
                    screwdriver::CAP_RADIUS,
                    screwdriver::HANDLE_Z1,
                    screwdriver::CAP_Z1,
                ),
            ] {
                let _ = writeln!(
                    x,
                    r#"      <geom name="{name}" type="cylinder" size="{r:?} {:?}" pos="0 0 {:?}" mass="0"/>"#,
                    0.5 * (z1 - z0),
                    0.5 * (z0 + z1)
                );
            }
            let _ = writeln!(x, "    </body>");
        }
        SceneKind::Card => {
            let [tx, ty, tz] = card::TABLE_CENTER;
            let [thx, thy, thz] = card::TABLE_HALF_EXTENTS;
            let _ = writeln!(
                x,
                r#"    <geom name="table" type="box" pos="{tx:?} {ty:?} {tz:?}" size="{thx:?} {thy:?} {thz:?}"/>"#
            );
            let [cx, cy, cz] = card::INITIAL_CENTER;
            let [hx, hy, hz] = card::HALF_EXTENTS;
            let [ix, iy, iz] = card::inertia();
            let _ = writeln!(x, r#"    <body name="card" pos="{cx:?} {cy:?} {cz:?}">"#);
            let _ = writeln!(x, r#"      <freejoint name="card"/>"#);
            let _ = writeln!(
                x,
                r#"      <inertial pos="0 0 0" mass="{:?}" diaginertia="{ix:?} {iy:?} {iz:?}"/>"#,
                card::MASS
            );
            let _ = writeln!(
                x,
                r#"      <geom name="card" type="box" size="{hx:?} {hy:?} {hz:?}" mass="0"/>"#
            );
            let _ = writeln!(x, "    </body>");
        }
    }
    let _ = writeln!(x, "  </worldbody>");
    // Only the task fingers' tips collide, as in our world; every pair with our friction.
    let _ = writeln!(x, "  <contact>");
    // A `<pair>` takes its `solref` from the pair defaults, never from the geoms': it is
    // written on every pair (without it MuJoCo's 0.02 s applied, not ours).
    let timeconst = params.contact_timeconst;
    let mut pair = |g1: &str, g2: &str, mu: f64| {
        let _ = writeln!(
            x,
            r#"    <pair geom1="{g1}" geom2="{g2}" condim="3" friction="{mu:?} {mu:?} 0.005 0.0001 0.0001" solref="{timeconst:?} 1"/>"#
        );
    };
    for finger in scene.task_fingers() {
        let tip = tip_name(*finger);
        match scene {
            SceneKind::Screwdriver => {
                for part in ["shaft", "handle", "cap"] {
                    pair(&tip, part, w.finger_friction);
                }
            }
            SceneKind::Card => {
                pair(&tip, "card", w.finger_friction);
                pair(&tip, "table", w.finger_table_friction);
            }
        }
    }
    if scene == SceneKind::Card {
        pair("card", "table", w.table_friction);
    }
    let _ = writeln!(x, "  </contact>");
    let _ = writeln!(x, "</mujoco>");
    x
}
