//! The object's configuration (screwdriver on its pivot, free card) and its angles.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::scenes::{SceneKind, card, screwdriver};

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

pub(super) fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let r = (a + std::f64::consts::PI).rem_euclid(two_pi) - std::f64::consts::PI;
    if r <= -std::f64::consts::PI {
        r + two_pi
    } else {
        r
    }
}

/// Heading of a rotation about world z (yaw of a ZYX decomposition).
pub(super) fn heading(r: &UnitQuaternion<f64>) -> f64 {
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

    /// Task validity ([`SceneKind::pose_valid`]): screwdriver cap within 0.02 m of nominal;
    /// card still lying on the table (centre within 5 mm of its resting height).
    pub fn valid(&self) -> bool {
        let scene = match self {
            ObjectState::Screwdriver { .. } => SceneKind::Screwdriver,
            ObjectState::Card { .. } => SceneKind::Card,
        };
        scene.pose_valid(&self.pose())
    }

    /// Apply a world-frame increment: `ω` (screwdriver) or `(δp, ω)` (card).
    pub(super) fn apply(&mut self, dq: &[f64]) {
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
