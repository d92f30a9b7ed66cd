//! Finger forward kinematics over a generic [`Scalar`], built from the world's
//! [`HandModel`] data so planner and world share one hand description.

use nalgebra::Isometry3;

use super::dual::{M3, Scalar, V3};
use dips_world::kinematics::{Finger, HandModel};

/// One finger's constant kinematic data, with the hand base folded into the first joint.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerChain {
    /// Joint origin translations in the parent frame (the first one in the world).
    trans: [[f64; 3]; 4],
    /// Joint origin rotations (the first one in the world).
    rots: [[[f64; 3]; 3]; 4],
    /// Joint axes in the joint frame.
    axes: [[f64; 3]; 4],
    /// Sphere centre in the distal frame.
    tip: [f64; 3],
    /// `(lower, upper)` joint limits.
    pub limits: [(f64, f64); 4],
}

/// World-frame joint origins and axes and the sphere centre of one finger.
#[derive(Debug, Clone, Copy)]
pub struct Frames<S> {
    /// Joint origins.
    pub origins: [V3<S>; 4],
    /// Unit joint axes.
    pub axes: [V3<S>; 4],
    /// Fingertip sphere centre.
    pub tip: V3<S>,
}

fn mat3(m: &nalgebra::Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

impl FingerChain {
    /// The chain of `finger` of `hand` mounted at `base`.
    pub fn new(hand: &HandModel, base: &Isometry3<f64>, finger: Finger) -> Self {
        let spec = hand.finger(finger);
        let mut trans = [[0.0; 3]; 4];
        let mut rots = [[[0.0; 3]; 3]; 4];
        let mut axes = [[0.0; 3]; 4];
        for (k, j) in spec.joints.iter().enumerate() {
            let o = if k == 0 { base * j.origin } else { j.origin };
            let t = o.translation.vector;
            trans[k] = [t.x, t.y, t.z];
            rots[k] = mat3(o.rotation.to_rotation_matrix().matrix());
            let a = j.axis.into_inner();
            axes[k] = [a.x, a.y, a.z];
        }
        let t = spec.tip_center;
        Self {
            trans,
            rots,
            axes,
            tip: [t.x, t.y, t.z],
            limits: hand.joint_limits(finger),
        }
    }

    /// Frames at joints `q`.
    pub fn frames<S: Scalar>(&self, q: &[S; 4]) -> Frames<S> {
        let mut r = M3::<S>::cst(self.rots[0]);
        let mut p = V3::<S>::cst(self.trans[0]);
        let mut origins = [V3::zero(); 4];
        let mut axes = [V3::zero(); 4];
        for k in 0..4 {
            if k > 0 {
                p = p.add(&r.mul_v(&V3::cst(self.trans[k])));
                r = r.mul_f(&self.rots[k]);
            }
            origins[k] = p;
            axes[k] = r.mul_v(&V3::cst(self.axes[k]));
            r = r.mul(&M3::rot_axis(&self.axes[k], q[k]));
        }
        let tip = p.add(&r.mul_v(&V3::cst(self.tip)));
        Frames { origins, axes, tip }
    }

    /// Sphere centre at `q`.
    pub fn tip<S: Scalar>(&self, q: &[S; 4]) -> V3<S> {
        self.frames(q).tip
    }
}

impl<S: Scalar> Frames<S> {
    /// Jacobian columns `a_k × (p − o_k)` of a point `p` fixed to the distal link.
    pub fn point_jacobian(&self, p: &V3<S>) -> [V3<S>; 4] {
        std::array::from_fn(|k| self.axes[k].cross(&p.sub(&self.origins[k])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dips_world::scenes::SceneKind;

    #[test]
    fn generic_fk_matches_world_kinematics() {
        let hand = HandModel::allegro_v4();
        for scene in SceneKind::ALL {
            let base = scene.hand_base();
            let q0 = scene.default_joints();
            for f in Finger::ALL {
                let chain = FingerChain::new(&hand, &base, f);
                let q = q0[f.index()].map(|v| v + 0.1);
                let ours = chain.frames(&q);
                let theirs = hand.finger_frames(&base, f, &q);
                for i in 0..3 {
                    assert!((ours.tip.0[i] - theirs.tip_center[i]).abs() < 1e-12);
                }
                let jt = hand.tip_jacobian(&base, f, &q);
                let jo = ours.point_jacobian(&ours.tip);
                for k in 0..4 {
                    for i in 0..3 {
                        assert!((jo[k].0[i] - jt[(i, k)]).abs() < 1e-12);
                    }
                }
            }
        }
    }
}
