//! The two task scenes (`screwdriver`, `card`): hand placement, default joints, object geometry,
//! friction and the task metrics. Numbers come from `spec/sim_and_tasks.md` §3.

use nalgebra::{
    Isometry3, Matrix3, Point3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3,
};

use dips_kernel::mode::{Task, TaskMode};

use crate::kinematics::{Finger, HandJoints};

/// Standard gravity (m/s²), acting along world −z.
pub const GRAVITY: f64 = 9.81;

/// Which task scene: the world-side view of the kernel's [`Task`] (one scene per task, the
/// same names; `From` converts both ways). The task's modes, sizes, layout and costs are the
/// kernel's; this adds what only the world and the host know (hand placement, geometry,
/// stiffness, friction).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SceneKind {
    /// Screwdriver turning with thumb, index and middle.
    Screwdriver,
    /// Card sliding with index and middle.
    Card,
}

impl From<Task> for SceneKind {
    fn from(task: Task) -> Self {
        match task {
            Task::Screwdriver => SceneKind::Screwdriver,
            Task::Card => SceneKind::Card,
        }
    }
}

impl From<SceneKind> for Task {
    fn from(scene: SceneKind) -> Self {
        scene.task()
    }
}

impl std::str::FromStr for SceneKind {
    type Err = dips_kernel::name::UnknownValue;

    /// A scene by its task's name (`screwdriver`, `card`): the kernel's [`Task`] `FromStr`,
    /// whose error names the value and the tasks.
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        name.parse::<Task>().map(SceneKind::from)
    }
}

impl std::fmt::Display for SceneKind {
    /// The task's name.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl PartialEq<Task> for SceneKind {
    fn eq(&self, task: &Task) -> bool {
        self.task() == *task
    }
}

impl PartialEq<SceneKind> for Task {
    fn eq(&self, scene: &SceneKind) -> bool {
        *self == scene.task()
    }
}

impl SceneKind {
    /// Both scenes, in the kernel's task order.
    pub const ALL: [SceneKind; 2] = [SceneKind::Screwdriver, SceneKind::Card];

    /// The kernel task of this scene.
    pub const fn task(self) -> Task {
        match self {
            SceneKind::Screwdriver => Task::Screwdriver,
            SceneKind::Card => Task::Card,
        }
    }

    /// Name used on the command line and in files (the task's name).
    pub fn name(self) -> &'static str {
        self.task().name()
    }

    /// The task's modes, in the kernel's table order.
    pub fn modes(self) -> &'static [TaskMode] {
        self.task().named_modes()
    }

    /// The task's fingers in `docs/contracts.md` §2 order.
    pub fn task_fingers(self) -> &'static [Finger] {
        match self {
            SceneKind::Screwdriver => &[Finger::Index, Finger::Middle, Finger::Thumb],
            SceneKind::Card => &[Finger::Index, Finger::Middle],
        }
    }

    /// Number of actuated joints in the task (4 per task finger).
    pub fn action_dim(self) -> usize {
        4 * self.task_fingers().len()
    }

    /// Number of object coordinates in the state (roll, pitch, yaw or x, y, θ).
    pub fn object_dim(self) -> usize {
        3
    }

    /// Length of the raw state row: task joints then object coordinates (15 or 11).
    pub fn state_dim(self) -> usize {
        self.action_dim() + self.object_dim()
    }

    /// Task validity of an object pose in the world (the screwdriver's frame at its pivot):
    /// the screwdriver's cap within [`screwdriver::VALID_RADIUS`] of nominal, the card lying
    /// on the table (centre within [`card::VALID_HEIGHT`] of its resting height). The one
    /// rule every hand, episode and trajectory is scored with.
    pub fn pose_valid(self, pose: &Isometry3<f64>) -> bool {
        match self {
            SceneKind::Screwdriver => screwdriver::is_valid(&pose.rotation.to_rotation_matrix()),
            SceneKind::Card => {
                (pose.translation.vector.z - card::INITIAL_CENTER[2]).abs() <= card::VALID_HEIGHT
            }
        }
    }

    /// Hand base pose in the world.
    pub fn hand_base(self) -> Isometry3<f64> {
        let (p, xyzw) = match self {
            SceneKind::Screwdriver => (
                [0.0, -0.095, 1.33],
                [0.2418448, 0.2418448, 0.664463, 0.664463],
            ),
            SceneKind::Card => (
                [0.03, -0.14, 0.21],
                [-0.4545195, 0.4545195, 0.5416752, 0.5416752],
            ),
        };
        let q =
            UnitQuaternion::from_quaternion(Quaternion::new(xyzw[3], xyzw[0], xyzw[1], xyzw[2]));
        Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), q)
    }

    /// Default joints (index | middle | ring | thumb).
    pub fn default_joints(self) -> HandJoints {
        match self {
            SceneKind::Screwdriver => [
                [0.1, 0.6, 0.6, 0.6],
                [-0.1, 0.5, 0.9, 0.9],
                [0.0, 0.5, 0.65, 0.65],
                [1.2, 0.3, 0.3, 1.2],
            ],
            SceneKind::Card => [
                [0.0, 0.35, 0.5, 0.225],
                [0.0, 0.35, 0.5, 0.225],
                [0.0, 0.2, 0.3, 0.2],
                [1.2, 0.3, 0.0, 0.8],
            ],
        }
    }

    /// Joint stiffness kp of the impedance controller (N·m/rad).
    pub fn kp(self) -> f64 {
        match self {
            SceneKind::Screwdriver => 3.0,
            SceneKind::Card => 10.0,
        }
    }

    /// Finger–object friction coefficient used by the world.
    pub fn finger_friction(self) -> f64 {
        match self {
            SceneKind::Screwdriver => screwdriver::FRICTION,
            SceneKind::Card => card::FINGER_FRICTION,
        }
    }
}

/// Screwdriver geometry, mass properties and metrics. Object frame: origin at the pivot (the
/// screwdriver's tip), +z along the shaft; orientation `R = Rx(roll)·Ry(pitch)·Rz(yaw)`.
pub mod screwdriver {
    use super::*;

    /// Pivot (spherical joint) position in the world.
    pub const PIVOT: [f64; 3] = [0.0, 0.0, 1.205];
    /// Shaft cylinder radius; it spans z ∈ [0, SHAFT_LENGTH].
    pub const SHAFT_RADIUS: f64 = 0.005;
    /// Shaft length.
    pub const SHAFT_LENGTH: f64 = 0.1;
    /// Handle cylinder radius; it spans z ∈ [HANDLE_Z0, HANDLE_Z1].
    pub const HANDLE_RADIUS: f64 = 0.02;
    /// Handle bottom (object z).
    pub const HANDLE_Z0: f64 = 0.1;
    /// Handle top (object z).
    pub const HANDLE_Z1: f64 = 0.2;
    /// Cap disk radius; it spans z ∈ [HANDLE_Z1, CAP_Z1].
    pub const CAP_RADIUS: f64 = 0.02;
    /// Cap top (object z).
    pub const CAP_Z1: f64 = 0.201;
    /// Total mass (kg).
    pub const MASS: f64 = 0.355;
    /// Centre of mass height above the pivot (object z).
    pub const COM_HEIGHT: f64 = 0.1366;
    /// Inertia about the pivot in the object frame (kg·m²), diagonal.
    pub const INERTIA_PIVOT: [f64; 3] = [7.4e-3, 7.4e-3, 6.1e-5];
    /// Joint damping for roll, pitch, yaw (N·m·s/rad), the DIPS-era Isaac values.
    pub const DAMPING: [f64; 3] = [2.5, 2.5, 0.1];
    /// Finger–screwdriver friction coefficient in Isaac.
    pub const FRICTION: f64 = 2.5;
    /// Friction coefficient the CSVTO planner assumes.
    pub const PLANNER_FRICTION: f64 = 0.95;
    /// Cap frame origin in the object frame (the validity check point).
    pub const CAP_ORIGIN: [f64; 3] = [0.0, 0.0, 0.2];
    /// Nominal cap position in the world (upright).
    pub const CAP_NOMINAL: [f64; 3] = [0.0, 0.0, 1.405];
    /// The screwdriver is valid (not dropped) while the cap is within this distance (m).
    pub const VALID_RADIUS: f64 = 0.02;
    /// Roll/pitch joint limit (rad).
    pub const TILT_LIMIT: f64 = 1.57;

    /// Pivot as a point.
    pub fn pivot() -> Point3<f64> {
        Point3::from(PIVOT)
    }

    /// Rotation `Rx(roll)·Ry(pitch)·Rz(yaw)`.
    pub fn rotation(roll: f64, pitch: f64, yaw: f64) -> Rotation3<f64> {
        Rotation3::from_axis_angle(&Vector3::x_axis(), roll)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
    }

    /// Intrinsic XYZ Euler angles `(roll, pitch, yaw)` of `R = Rx·Ry·Rz`; yaw in (−π, π].
    pub fn euler_xyz(r: &Matrix3<f64>) -> [f64; 3] {
        let pitch = r[(0, 2)].clamp(-1.0, 1.0).asin();
        let roll = (-r[(1, 2)]).atan2(r[(2, 2)]);
        let yaw = (-r[(0, 1)]).atan2(r[(0, 0)]);
        [roll, pitch, yaw]
    }

    /// World position of the cap frame origin for a screwdriver orientation.
    pub fn cap_position(rotation: &Rotation3<f64>) -> Point3<f64> {
        pivot() + rotation * Vector3::from(CAP_ORIGIN)
    }

    /// Distance of the cap from its nominal position (m).
    pub fn cap_distance(rotation: &Rotation3<f64>) -> f64 {
        (cap_position(rotation) - Point3::from(CAP_NOMINAL)).norm()
    }

    /// Validity: the cap is within [`VALID_RADIUS`] of nominal (`spec` §3.3).
    pub fn is_valid(rotation: &Rotation3<f64>) -> bool {
        cap_distance(rotation) <= VALID_RADIUS
    }
}

/// Card and table geometry, friction and the distance metric.
pub mod card {
    /// Card half extents (x, y, z) of the 0.15 × 0.20 × 0.01 m box.
    pub const HALF_EXTENTS: [f64; 3] = [0.075, 0.1, 0.005];
    /// Card mass (kg).
    pub const MASS: f64 = 0.01;
    /// Card centre at rest on the table (Isaac starts it at z = 0.132 and it settles).
    pub const INITIAL_CENTER: [f64; 3] = [0.0, 0.0, 0.130];
    /// How far (m) the card's centre may leave its resting height and the card still count
    /// as lying on the table ([`SceneKind::pose_valid`](super::SceneKind::pose_valid)).
    pub const VALID_HEIGHT: f64 = 5e-3;
    /// Table box centre.
    pub const TABLE_CENTER: [f64; 3] = [0.0, 0.1, 0.1];
    /// Table box half extents (0.4 × 0.4 × 0.05 m).
    pub const TABLE_HALF_EXTENTS: [f64; 3] = [0.2, 0.2, 0.025];
    /// Table top height.
    pub const TABLE_TOP: f64 = 0.125;
    /// Finger–card friction.
    pub const FINGER_FRICTION: f64 = 1.0;
    /// Card–table friction (PhysX average of 1.0 and 1e-6).
    pub const TABLE_FRICTION: f64 = 0.5;
    /// Finger–table friction (average of 1.0 and 1e-6).
    pub const FINGER_TABLE_FRICTION: f64 = 0.5;
    /// Card damping on every coordinate (Isaac 0.001).
    pub const DAMPING: f64 = 0.001;
    /// Task goal: the card's y displacement from its start (toward the palm).
    pub const GOAL_DY: f64 = -0.06;

    /// Card box inertia about its centre, body frame, diagonal (kg·m²).
    pub fn inertia() -> [f64; 3] {
        let [a, b, c] = HALF_EXTENTS.map(|h| 2.0 * h);
        let k = MASS / 12.0;
        [
            k * (b * b + c * c),
            k * (a * a + c * c),
            k * (a * a + b * b),
        ]
    }

    /// The task goal `(x, y)` for a card that started at `(x0, y0)`.
    pub fn goal_from_start(x0: f64, y0: f64) -> [f64; 2] {
        [x0, y0 + GOAL_DY]
    }

    /// Planar distance of the card centre `(x, y)` to the goal (the card metric).
    pub fn distance_to_goal(x: f64, y: f64, goal: [f64; 2]) -> f64 {
        ((x - goal[0]).powi(2) + (y - goal[1]).powi(2)).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::HandModel;

    fn close(p: &Point3<f64>, expect: [f64; 3], tol: f64) -> bool {
        (p - Point3::from(expect)).norm() < tol
    }

    #[test]
    fn hand_base_rotations_match_spec() {
        let r = SceneKind::Screwdriver
            .hand_base()
            .rotation
            .to_rotation_matrix();
        assert!((r.matrix().column(0) - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-3);
        assert!((r.matrix().column(2) - Vector3::new(0.643, 0.0, 0.766)).norm() < 1e-3);
        let r = SceneKind::Card.hand_base().rotation.to_rotation_matrix();
        assert!((r.matrix().column(0) - Vector3::new(0.0, 0.174, -0.985)).norm() < 1e-3);
        assert!((r.matrix().column(1) - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-3);
    }

    /// Fingertip sphere centres at the default joints agree with the spec's table (§3.1, §3.2),
    /// which gives them to the millimetre.
    #[test]
    fn default_fingertips_match_spec() {
        let hand = HandModel::allegro_v4();
        let s = SceneKind::Screwdriver;
        let tips = hand.tip_centers(&s.hand_base(), &s.default_joints());
        assert!(
            close(&tips[0], [-0.003, 0.008, 1.420], 1.5e-3),
            "index {tips:?}"
        );
        assert!(
            close(&tips[1], [0.039, -0.004, 1.362], 1.5e-3),
            "middle {tips:?}"
        );
        assert!(
            close(&tips[2], [0.085, 0.003, 1.353], 1.5e-3),
            "ring {tips:?}"
        );
        assert!(
            close(&tips[3], [-0.036, -0.002, 1.348], 1.5e-3),
            "thumb {tips:?}"
        );
        let c = SceneKind::Card;
        let tips = hand.tip_centers(&c.hand_base(), &c.default_joints());
        assert!(
            close(&tips[0], [-0.023, -0.016, 0.150], 1.5e-3),
            "index {tips:?}"
        );
        assert!(
            close(&tips[1], [0.030, -0.013, 0.150], 1.5e-3),
            "middle {tips:?}"
        );
        assert!((tips[2].z - 0.18).abs() < 5e-3, "ring {tips:?}");
        assert!(
            (tips[3].z - 0.08).abs() < 5e-3 && (tips[3].y + 0.157).abs() < 5e-3,
            "thumb {tips:?}"
        );
    }

    #[test]
    fn euler_round_trip_and_validity() {
        let r = screwdriver::rotation(0.03, -0.02, 2.5);
        let e = screwdriver::euler_xyz(r.matrix());
        assert!(
            (e[0] - 0.03).abs() < 1e-12
                && (e[1] + 0.02).abs() < 1e-12
                && (e[2] - 2.5).abs() < 1e-12
        );
        assert!(screwdriver::is_valid(&screwdriver::rotation(0.0, 0.0, 3.0)));
        assert!(screwdriver::is_valid(&screwdriver::rotation(
            0.09, 0.0, 0.0
        )));
        assert!(!screwdriver::is_valid(&screwdriver::rotation(
            0.11, 0.0, 0.0
        )));
    }

    #[test]
    fn pose_validity_is_the_task_rule() {
        let tilted = |roll: f64| {
            let r = UnitQuaternion::from_rotation_matrix(&screwdriver::rotation(roll, 0.0, 1.0));
            Isometry3::from_parts(Translation3::new(0.0, 0.0, 1.0), r)
        };
        assert!(SceneKind::Screwdriver.pose_valid(&tilted(0.09)));
        assert!(!SceneKind::Screwdriver.pose_valid(&tilted(0.11)));
        let [x, y, z] = card::INITIAL_CENTER;
        let card_at = |dz: f64| Isometry3::translation(x + 0.03, y - 0.05, z + dz);
        assert!(SceneKind::Card.pose_valid(&card_at(0.0)));
        assert!(SceneKind::Card.pose_valid(&card_at(-0.004)));
        assert!(!SceneKind::Card.pose_valid(&card_at(0.006)));
        assert!(!SceneKind::Card.pose_valid(&card_at(-0.006)));
    }
}
