//! Allegro hand (right, v4, UM-ARM-Lab "Xela" variant) kinematics: forward kinematics,
//! Jacobians of points on the distal links, joint limits and fingertip spheres.
//!
//! The joint table lives in `host/data/allegro_v4.json` (embedded as the default with
//! `include_str!`, and loadable at run time with [`HandModel::load`] so a user can edit it).
//! Frames follow the URDF: each joint's origin is given in its parent frame with rpy meaning
//! `R = Rz(y)·Ry(p)·Rx(r)`, followed by a rotation about the joint axis by the joint angle.
//! Everything is `f64` and nalgebra; world-frame quantities take the hand base pose as an
//! [`Isometry3`] (see [`crate::scenes`] for the two task placements).

use std::path::Path;

use nalgebra::{
    Isometry3, Matrix3, Matrix3x4, Point3, Translation3, Unit, UnitQuaternion, Vector3,
};
use serde::Deserialize;

/// The default hand description, compiled in.
pub const DEFAULT_HAND_JSON: &str = include_str!("../../data/allegro_v4.json");

/// One finger of the hand. The discriminant is the finger's index in [`HandJoints`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Finger {
    /// Index finger (joints 0..3).
    Index = 0,
    /// Middle finger (joints 4..7).
    Middle = 1,
    /// Ring finger (joints 8..11).
    Ring = 2,
    /// Thumb (joints 12..15).
    Thumb = 3,
}

impl Finger {
    /// All fingers in the semantic order index, middle, ring, thumb.
    pub const ALL: [Finger; 4] = [Finger::Index, Finger::Middle, Finger::Ring, Finger::Thumb];

    /// Position of this finger in [`HandJoints`] and in the hand file.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Lower-case name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Finger::Index => "index",
            Finger::Middle => "middle",
            Finger::Ring => "ring",
            Finger::Thumb => "thumb",
        }
    }

    /// Parse a lower-case finger name.
    pub fn from_name(name: &str) -> Option<Finger> {
        Finger::ALL.into_iter().find(|f| f.name() == name)
    }
}

/// Joint angles of one finger (radians), proximal to distal.
pub type FingerJoints = [f64; 4];

/// Joint angles of the whole hand, indexed by [`Finger::index`].
pub type HandJoints = [FingerJoints; 4];

/// Errors reading or validating a hand description.
#[derive(Debug, thiserror::Error)]
pub enum KinematicsError {
    /// The file could not be read.
    #[error("cannot read hand description {path}: {source}")]
    Io {
        /// The path that failed.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The text is not valid JSON of the expected shape.
    #[error("hand description is not valid JSON of the expected shape: {0}")]
    Json(#[from] serde_json::Error),
    /// The fingers are not exactly index, middle, ring, thumb in that order.
    #[error(
        "hand description must list fingers index, middle, ring, thumb in that order; found {0:?}"
    )]
    FingerOrder(Vec<String>),
    /// A number is NaN or infinite.
    #[error("hand description: {what} is not finite")]
    NonFinite {
        /// Which field.
        what: String,
    },
    /// A joint axis has (near) zero length.
    #[error("hand description: {finger} joint {joint} has a zero axis")]
    ZeroAxis {
        /// Finger name.
        finger: String,
        /// Joint number within the finger (0..3).
        joint: usize,
    },
    /// A joint's lower limit is above its upper limit.
    #[error(
        "hand description: {finger} joint {joint} has lower limit {lower} above upper limit {upper}"
    )]
    BadLimits {
        /// Finger name.
        finger: String,
        /// Joint number within the finger (0..3).
        joint: usize,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// The fingertip radius is not positive.
    #[error("hand description: tip_radius must be positive, got {0}")]
    BadRadius(f64),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct HandFile {
    name: String,
    #[serde(default)]
    #[allow(dead_code)]
    comment: Option<String>,
    tip_radius: f64,
    fingers: Vec<FingerFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FingerFile {
    name: String,
    joints: [JointFile; 4],
    tip_center: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointFile {
    origin_xyz: [f64; 3],
    origin_rpy: [f64; 3],
    axis: [f64; 3],
    limits: [f64; 2],
}

/// One revolute joint: its fixed origin in the parent frame, axis and limits.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    /// Joint frame origin in the parent link frame (at zero angle).
    pub origin: Isometry3<f64>,
    /// Rotation axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Lower limit (rad).
    pub lower: f64,
    /// Upper limit (rad).
    pub upper: f64,
}

/// One finger: four joints and the fingertip sphere centre in the distal link frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerSpec {
    /// The four joints, proximal to distal.
    pub joints: [JointSpec; 4],
    /// Fingertip sphere centre in the distal link frame.
    pub tip_center: Vector3<f64>,
}

/// World-frame joint origins and axes of one finger at a configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerFrames {
    /// Origin of each joint in the world frame.
    pub joint_origins: [Point3<f64>; 4],
    /// Unit axis of each joint in the world frame.
    pub joint_axes: [Vector3<f64>; 4],
    /// Pose of the distal link in the world frame.
    pub distal: Isometry3<f64>,
    /// Fingertip sphere centre in the world frame.
    pub tip_center: Point3<f64>,
}

/// The first joint value of `q` that is NaN or infinite, with its finger-major index (what a
/// hand refuses as a target or a torque).
pub fn first_non_finite(q: &HandJoints) -> Option<(usize, f64)> {
    q.iter()
        .flatten()
        .copied()
        .enumerate()
        .find(|(_, v)| !v.is_finite())
}

/// The largest absolute difference between two sets of joint values.
pub fn max_joint_difference(a: &HandJoints, b: &HandJoints) -> f64 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Link masses (kg) of an index/middle/ring finger, proximal to distal (the distal entry
/// includes the fingertip). Our hand file has no masses; these are of the order of the
/// Allegro v4 URDF's (`docs/mujoco.md`). The MuJoCo scene and the Allegro driver's gravity
/// compensation use them.
pub const FINGER_LINK_MASSES: [f64; 4] = [0.0119, 0.065, 0.0355, 0.0264];

/// Link masses (kg) of the thumb, proximal to distal (distal with its tip).
pub const THUMB_LINK_MASSES: [f64; 4] = [0.0176, 0.0119, 0.038, 0.0724];

/// The hand: four fingers and the fingertip sphere radius.
#[derive(Debug, Clone, PartialEq)]
pub struct HandModel {
    /// Human-readable name from the file.
    pub name: String,
    /// Fingertip sphere radius (m).
    pub tip_radius: f64,
    /// Fingers in [`Finger::ALL`] order.
    pub fingers: [FingerSpec; 4],
}

/// URDF rpy to a rotation: `Rz(y)·Ry(p)·Rx(r)`.
pub fn rpy_to_rotation(rpy: [f64; 3]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rpy[2])
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), rpy[1])
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), rpy[0])
}

fn check_finite(values: &[f64], what: impl FnOnce() -> String) -> Result<(), KinematicsError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(KinematicsError::NonFinite { what: what() })
    }
}

impl HandModel {
    /// The compiled-in Allegro v4 description (`host/data/allegro_v4.json`).
    pub fn allegro_v4() -> HandModel {
        // The embedded file is checked by this module's tests; failure here is a build defect.
        HandModel::from_json_str(DEFAULT_HAND_JSON).expect("embedded allegro_v4.json is valid")
    }

    /// Read a hand description from a JSON file.
    pub fn load(path: &Path) -> Result<HandModel, KinematicsError> {
        let text = std::fs::read_to_string(path).map_err(|source| KinematicsError::Io {
            path: path.display().to_string(),
            source,
        })?;
        HandModel::from_json_str(&text)
    }

    /// Parse and validate a hand description.
    pub fn from_json_str(text: &str) -> Result<HandModel, KinematicsError> {
        let file: HandFile = serde_json::from_str(text)?;
        let names: Vec<String> = file.fingers.iter().map(|f| f.name.clone()).collect();
        if names.len() != 4 || names.iter().zip(Finger::ALL).any(|(n, f)| n != f.name()) {
            return Err(KinematicsError::FingerOrder(names));
        }
        if !(file.tip_radius.is_finite() && file.tip_radius > 0.0) {
            return Err(KinematicsError::BadRadius(file.tip_radius));
        }
        let files: &[FingerFile; 4] = file
            .fingers
            .as_slice()
            .try_into()
            .map_err(|_| KinematicsError::FingerOrder(names.clone()))?;
        // Validate everything first, so the conversion below cannot fail.
        for ff in files {
            check_finite(&ff.tip_center, || format!("{} tip_center", ff.name))?;
            for (j, jf) in ff.joints.iter().enumerate() {
                let what = || format!("{} joint {j}", ff.name);
                check_finite(&jf.origin_xyz, what)?;
                check_finite(&jf.origin_rpy, what)?;
                check_finite(&jf.axis, what)?;
                check_finite(&jf.limits, what)?;
                if Vector3::from(jf.axis).norm() <= 1e-9 {
                    return Err(KinematicsError::ZeroAxis {
                        finger: ff.name.clone(),
                        joint: j,
                    });
                }
                if jf.limits[0] > jf.limits[1] {
                    return Err(KinematicsError::BadLimits {
                        finger: ff.name.clone(),
                        joint: j,
                        lower: jf.limits[0],
                        upper: jf.limits[1],
                    });
                }
            }
        }
        let fingers = files.each_ref().map(|ff| FingerSpec {
            joints: ff.joints.each_ref().map(|jf| JointSpec {
                origin: Isometry3::from_parts(
                    Translation3::from(Vector3::from(jf.origin_xyz)),
                    rpy_to_rotation(jf.origin_rpy),
                ),
                axis: Unit::new_normalize(Vector3::from(jf.axis)),
                lower: jf.limits[0],
                upper: jf.limits[1],
            }),
            tip_center: Vector3::from(ff.tip_center),
        });
        Ok(HandModel {
            name: file.name,
            tip_radius: file.tip_radius,
            fingers,
        })
    }

    /// The description of one finger.
    pub fn finger(&self, finger: Finger) -> &FingerSpec {
        &self.fingers[finger.index()]
    }

    /// `(lower, upper)` joint limits of one finger.
    pub fn joint_limits(&self, finger: Finger) -> [(f64, f64); 4] {
        self.finger(finger)
            .joints
            .each_ref()
            .map(|j| (j.lower, j.upper))
    }

    /// Clamp one finger's joints into their limits.
    pub fn clamp_to_limits(&self, finger: Finger, q: &FingerJoints) -> FingerJoints {
        let lim = self.joint_limits(finger);
        std::array::from_fn(|i| q[i].clamp(lim[i].0, lim[i].1))
    }

    /// World-frame joint frames of one finger for base pose `base` and joints `q`.
    pub fn finger_frames(
        &self,
        base: &Isometry3<f64>,
        finger: Finger,
        q: &FingerJoints,
    ) -> FingerFrames {
        let spec = self.finger(finger);
        let mut pose = *base;
        let mut joint_origins = [Point3::origin(); 4];
        let mut joint_axes = [Vector3::zeros(); 4];
        for (i, joint) in spec.joints.iter().enumerate() {
            pose *= joint.origin;
            joint_origins[i] = Point3::from(pose.translation.vector);
            joint_axes[i] = pose.rotation * joint.axis.into_inner();
            pose *= UnitQuaternion::from_axis_angle(&joint.axis, q[i]);
        }
        let tip_center = pose * Point3::from(spec.tip_center);
        FingerFrames {
            joint_origins,
            joint_axes,
            distal: pose,
            tip_center,
        }
    }

    /// World-frame fingertip sphere centre.
    pub fn tip_center(
        &self,
        base: &Isometry3<f64>,
        finger: Finger,
        q: &FingerJoints,
    ) -> Point3<f64> {
        self.finger_frames(base, finger, q).tip_center
    }

    /// Fingertip sphere centres of all four fingers (world frame), indexed by [`Finger::index`].
    pub fn tip_centers(&self, base: &Isometry3<f64>, q: &HandJoints) -> [Point3<f64>; 4] {
        Finger::ALL.map(|f| self.tip_center(base, f, &q[f.index()]))
    }

    /// Jacobian `∂p/∂q` (3×4, world frame) of a point `p` rigidly attached to the distal link,
    /// given by its current world position.
    pub fn point_jacobian(
        &self,
        base: &Isometry3<f64>,
        finger: Finger,
        q: &FingerJoints,
        p: &Point3<f64>,
    ) -> Matrix3x4<f64> {
        jacobian_from_frames(&self.finger_frames(base, finger, q), p)
    }

    /// Jacobian of the fingertip sphere centre (3×4, world frame).
    pub fn tip_jacobian(
        &self,
        base: &Isometry3<f64>,
        finger: Finger,
        q: &FingerJoints,
    ) -> Matrix3x4<f64> {
        let frames = self.finger_frames(base, finger, q);
        jacobian_from_frames(&frames, &frames.tip_center)
    }

    /// Damped least-squares joint step that moves the fingertip centre by `dp` (world frame):
    /// `dq = Jᵀ (J Jᵀ + λ² I)⁻¹ dp`. Not clamped to limits.
    pub fn tip_ik_step(
        &self,
        base: &Isometry3<f64>,
        finger: Finger,
        q: &FingerJoints,
        dp: &Vector3<f64>,
        damping: f64,
    ) -> FingerJoints {
        let j = self.tip_jacobian(base, finger, q);
        let jjt = j * j.transpose() + Matrix3::identity() * (damping * damping);
        match jjt.try_inverse() {
            Some(inv) => {
                let dq = j.transpose() * (inv * dp);
                [dq[0], dq[1], dq[2], dq[3]]
            }
            None => [0.0; 4],
        }
    }

    /// Joints that bring the fingertip centre to `target` (world frame): `iterations` damped
    /// least-squares steps from `q0`, each clamped to the joint limits. Returns the best found.
    pub fn solve_tip_ik(
        &self,
        base: &Isometry3<f64>,
        finger: Finger,
        q0: &FingerJoints,
        target: &Point3<f64>,
        iterations: usize,
    ) -> FingerJoints {
        let mut q = *q0;
        for _ in 0..iterations {
            let err = target - self.tip_center(base, finger, &q);
            if err.norm() < 1e-9 {
                break;
            }
            let dq = self.tip_ik_step(base, finger, &q, &err, 1e-3);
            let next: FingerJoints = std::array::from_fn(|i| q[i] + dq[i]);
            q = self.clamp_to_limits(finger, &next);
        }
        q
    }
}

/// Jacobian of a world point `p` attached to the distal link, from precomputed frames:
/// column `i` is `aᵢ × (p − oᵢ)`.
pub fn jacobian_from_frames(frames: &FingerFrames, p: &Point3<f64>) -> Matrix3x4<f64> {
    let mut j = Matrix3x4::zeros();
    for i in 0..4 {
        let col = frames.joint_axes[i].cross(&(p - frames.joint_origins[i]));
        j.set_column(i, &col);
    }
    j
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_file_loads_with_spec_limits() {
        let hand = HandModel::allegro_v4();
        assert_eq!(hand.tip_radius, 0.015);
        assert_eq!(hand.joint_limits(Finger::Thumb)[0], (0.263, 1.5));
        assert_eq!(
            hand.finger(Finger::Index).joints[1]
                .origin
                .translation
                .vector
                .z,
            0.0204
        );
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let hand = HandModel::allegro_v4();
        let base = Isometry3::from_parts(
            Translation3::new(0.1, -0.2, 0.3),
            UnitQuaternion::from_euler_angles(0.3, -0.4, 1.1),
        );
        let q = [0.1, 0.5, 0.7, 0.4];
        for f in Finger::ALL {
            let q = if f == Finger::Thumb {
                [1.0, 0.3, 0.4, 0.5]
            } else {
                q
            };
            let j = hand.tip_jacobian(&base, f, &q);
            for i in 0..4 {
                let eps = 1e-6;
                let mut qp = q;
                qp[i] += eps;
                let mut qm = q;
                qm[i] -= eps;
                let fd =
                    (hand.tip_center(&base, f, &qp) - hand.tip_center(&base, f, &qm)) / (2.0 * eps);
                assert!((fd - j.column(i)).norm() < 1e-8, "{f:?} joint {i}");
            }
        }
    }

    #[test]
    fn ik_reaches_a_nearby_target() {
        let hand = HandModel::allegro_v4();
        let base = Isometry3::identity();
        let q0 = [0.0, 0.5, 0.5, 0.5];
        let target =
            hand.tip_center(&base, Finger::Middle, &q0) + Vector3::new(0.01, -0.005, 0.004);
        let q = hand.solve_tip_ik(&base, Finger::Middle, &q0, &target, 20);
        assert!((hand.tip_center(&base, Finger::Middle, &q) - target).norm() < 1e-7);
    }

    #[test]
    fn bad_files_get_typed_errors() {
        assert!(matches!(
            HandModel::from_json_str("{"),
            Err(KinematicsError::Json(_))
        ));
        let swapped = DEFAULT_HAND_JSON.replacen("\"index\"", "\"pinky\"", 1);
        assert!(matches!(
            HandModel::from_json_str(&swapped),
            Err(KinematicsError::FingerOrder(_))
        ));
        let bad_radius =
            DEFAULT_HAND_JSON.replacen("\"tip_radius\": 0.015", "\"tip_radius\": -1", 1);
        assert!(matches!(
            HandModel::from_json_str(&bad_radius),
            Err(KinematicsError::BadRadius(_))
        ));
        let zero_axis =
            DEFAULT_HAND_JSON.replacen("\"axis\": [0.0, 0.0, 1.0]", "\"axis\": [0.0, 0.0, 0.0]", 1);
        assert!(matches!(
            HandModel::from_json_str(&zero_axis),
            Err(KinematicsError::ZeroAxis { .. })
        ));
        let bad_lim = DEFAULT_HAND_JSON.replacen("[-0.47, 0.47]", "[0.47, -0.47]", 1);
        assert!(matches!(
            HandModel::from_json_str(&bad_lim),
            Err(KinematicsError::BadLimits { .. })
        ));
        let missing = std::path::Path::new("/nonexistent/hand.json");
        assert!(matches!(
            HandModel::load(missing),
            Err(KinematicsError::Io { .. })
        ));
    }
}
