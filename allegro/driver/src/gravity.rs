//! Gravity compensation from the hand's model: each link a point mass
//! ([`FINGER_LINK_MASSES`], [`THUMB_LINK_MASSES`]) at the middle of the segment from its joint
//! to the next (or to the fingertip centre), as the MuJoCo scene places them. The torque that
//! holds the links against gravity is `τ_i = −Σ_{k ≥ i} (a_i × (c_k − o_i)) · m_k g`, the
//! gradient of the links' potential energy; [`gravity_pwm`] gives it in PWM.

use dips_world::kinematics::{
    FINGER_LINK_MASSES, Finger, FingerJoints, HandJoints, HandModel, THUMB_LINK_MASSES,
};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

use crate::units::PWM_PER_NEWTON_METRE;

/// Gravity (m/s²) in the world frame.
const GRAVITY: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

/// One finger's joint origins, axes and link centres of mass (world frame).
struct FingerMasses {
    origins: [Point3<f64>; 4],
    axes: [Vector3<f64>; 4],
    coms: [Point3<f64>; 4],
    masses: [f64; 4],
}

fn finger_masses(
    hand: &HandModel,
    base: &Isometry3<f64>,
    finger: Finger,
    q: &FingerJoints,
) -> FingerMasses {
    let spec = hand.finger(finger);
    let mut pose = *base;
    let mut m = FingerMasses {
        origins: [Point3::origin(); 4],
        axes: [Vector3::zeros(); 4],
        coms: [Point3::origin(); 4],
        masses: if finger == Finger::Thumb {
            THUMB_LINK_MASSES
        } else {
            FINGER_LINK_MASSES
        },
    };
    for (j, joint) in spec.joints.iter().enumerate() {
        pose *= joint.origin;
        m.origins[j] = Point3::from(pose.translation.vector);
        m.axes[j] = pose.rotation * joint.axis.into_inner();
        pose *= UnitQuaternion::from_axis_angle(&joint.axis, q[j]);
        let end = if j + 1 < 4 {
            spec.joints[j + 1].origin.translation.vector
        } else {
            spec.tip_center
        };
        m.coms[j] = pose * Point3::from(end * 0.5);
    }
    m
}

/// Joint torques (N·m) that hold the hand's links at `q` against gravity, for the hand base
/// at `base` in the world.
pub fn gravity_torques(hand: &HandModel, base: &Isometry3<f64>, q: &HandJoints) -> HandJoints {
    Finger::ALL.map(|finger| {
        let m = finger_masses(hand, base, finger, &q[finger.index()]);
        std::array::from_fn(|i| {
            -(i..4)
                .map(|k| {
                    m.axes[i]
                        .cross(&(m.coms[k] - m.origins[i]))
                        .dot(&(GRAVITY * m.masses[k]))
                })
                .sum::<f64>()
        })
    })
}

/// [`gravity_torques`] in PWM.
pub fn gravity_pwm(hand: &HandModel, base: &Isometry3<f64>, q: &HandJoints) -> HandJoints {
    gravity_torques(hand, base, q).map(|f| f.map(|t| t * PWM_PER_NEWTON_METRE))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dips_world::scenes::SceneKind;

    /// The links' potential energy (J).
    fn energy(hand: &HandModel, base: &Isometry3<f64>, q: &HandJoints) -> f64 {
        Finger::ALL
            .iter()
            .map(|f| {
                let m = finger_masses(hand, base, *f, &q[f.index()]);
                (0..4)
                    .map(|k| -m.masses[k] * GRAVITY.dot(&m.coms[k].coords))
                    .sum::<f64>()
            })
            .sum()
    }

    #[test]
    fn the_holding_torque_is_the_gradient_of_the_potential_energy() {
        let hand = HandModel::allegro_v4();
        for scene in [SceneKind::Card, SceneKind::Screwdriver] {
            let base = scene.hand_base();
            let q = scene.default_joints();
            let t = gravity_torques(&hand, &base, &q);
            let h = 1e-6;
            for f in 0..4 {
                for j in 0..4 {
                    let (mut qp, mut qm) = (q, q);
                    qp[f][j] += h;
                    qm[f][j] -= h;
                    let grad = (energy(&hand, &base, &qp) - energy(&hand, &base, &qm)) / (2.0 * h);
                    assert!(
                        (t[f][j] - grad).abs() < 1e-7,
                        "{scene:?} {f} {j}: {} vs {grad}",
                        t[f][j]
                    );
                    // A finger of ~0.14 kg on under 0.15 m: below 0.25 N·m (0.7 is full scale).
                    assert!(t[f][j].abs() < 0.25, "{}", t[f][j]);
                }
            }
            // The distal joint of every finger carries some load somewhere in the scenes.
            assert!(t.iter().flatten().any(|x| x.abs() > 1e-4));
        }
    }
}
