//! Fingertip geometry against the object in generic scalars (values or dual numbers), so
//! every Jacobian is exact.

use super::AllegroProblem;
use crate::problems::dual::{Dual, M3, Scalar, V3};
use crate::problems::sdf;
use dips_world::scenes::{self, SceneKind};

/// Object rotation and origin for the object coordinates `o`, given in problem units
/// (`units[k]` metres or radians per unit).
pub(super) fn object_pose<S: Scalar>(
    task: SceneKind,
    units: &[f64; 3],
    o: &[S; 3],
) -> (M3<S>, V3<S>) {
    let o: [S; 3] = std::array::from_fn(|k| o[k] * units[k]);
    match task {
        SceneKind::Screwdriver => (
            M3::rot_x(o[0]).mul(&M3::rot_y(o[1])).mul(&M3::rot_z(o[2])),
            V3::cst(scenes::screwdriver::PIVOT),
        ),
        SceneKind::Card => (
            M3::rot_z(o[2]),
            V3([o[0], o[1], S::cst(scenes::card::INITIAL_CENTER[2])]),
        ),
    }
}

/// Unit tangents `t1, t2` completing the normal `n` to a right-handed frame.
pub(super) fn tangents<S: Scalar>(n: &V3<S>) -> (V3<S>, V3<S>) {
    let helper = if n.z().val().abs() < 0.9 {
        V3::cst([0.0, 0.0, 1.0])
    } else {
        V3::cst([1.0, 0.0, 0.0])
    };
    let t = helper.cross(n);
    let t1 = t.scale(S::cst(1.0) / t.norm());
    let t2 = n.cross(&t1);
    (t1, t2)
}

/// Geometry of one fingertip against the object.
pub(super) struct Contact<S> {
    /// Sphere signed distance (centre distance minus radius).
    pub(super) sdf: S,
    /// Outward object normal (world).
    pub(super) normal: V3<S>,
    /// Closest point on the object surface (world).
    pub(super) surface: V3<S>,
    /// Point of the sphere nearest the object (world).
    pub(super) finger_point: V3<S>,
    pub(super) frames: crate::problems::fk::Frames<S>,
}

/// The parts of a [`Contact`] the step terms need, in the caller's scalar: signed distance,
/// normal, surface point and the Jacobian of the finger's contact point.
pub(super) struct Lifted<S> {
    pub(super) sdf: S,
    pub(super) normal: V3<S>,
    pub(super) surface: V3<S>,
    pub(super) jac: [V3<S>; 4],
}

impl AllegroProblem {
    /// Geometry of finger `i` at joints `q` and object pose `o`.
    pub(super) fn contact<S: Scalar>(&self, i: usize, q: &[S; 4], o: &[S; 3]) -> Contact<S> {
        let frames = self.chains[i].frames(q);
        let (r, origin) = object_pose(self.task, &self.units, o);
        let local = r.tmul_v(&frames.tip.sub(&origin));
        let sd = match self.task {
            SceneKind::Screwdriver => sdf::screwdriver(&local),
            SceneKind::Card => sdf::card(&local),
        };
        let normal = r.mul_v(&sd.normal);
        let surface = frames.tip.sub(&normal.scale(sd.dist));
        let finger_point = frames.tip.sub(&normal.scalef(self.radius));
        Contact {
            sdf: sd.dist - self.radius,
            normal,
            surface,
            finger_point,
            frames,
        }
    }

    /// Geometry of finger `i` at joints `vals[..4]` and object pose `vals[4..]`, computed in
    /// 7-wide dual numbers (the expensive kinematics and distance) and lifted into the
    /// caller's wider dual, whose joints start at column `oq` and object pose at `oo`.
    pub(super) fn lifted_contact<S: Lift>(
        &self,
        i: usize,
        vals: &[f64; 7],
        oq: usize,
        oo: usize,
    ) -> Lifted<S> {
        let d: [Dual<7>; 7] = seed(vals);
        let c = self.contact(i, &[d[0], d[1], d[2], d[3]], &[d[4], d[5], d[6]]);
        let jac = c.frames.point_jacobian(&c.finger_point);
        let l = |x: Dual<7>| S::lift(x, oq, oo);
        let lv = |x: &V3<Dual<7>>| V3(x.0.map(l));
        Lifted {
            sdf: l(c.sdf),
            normal: lv(&c.normal),
            surface: lv(&c.surface),
            jac: jac.each_ref().map(lv),
        }
    }

    /// Displacement of the object material point at `p` from pose `ot` to `on`.
    pub(super) fn object_motion<S: Scalar>(&self, ot: &[S; 3], on: &[S; 3], p: &V3<S>) -> V3<S> {
        match self.task {
            SceneKind::Screwdriver => {
                let (rt, origin) = object_pose(self.task, &self.units, ot);
                let (rn, _) = object_pose(self.task, &self.units, on);
                let m = rn.mul_t(&rt);
                let half = 0.5;
                let w = V3([
                    (m.0[2][1] - m.0[1][2]) * half,
                    (m.0[0][2] - m.0[2][0]) * half,
                    (m.0[1][0] - m.0[0][1]) * half,
                ]);
                w.cross(&p.sub(&origin))
            }
            SceneKind::Card => {
                let (_, origin) = object_pose(self.task, &self.units, ot);
                let u = &self.units;
                let w = V3([S::cst(0.0), S::cst(0.0), (on[2] - ot[2]) * u[2]]);
                let v = V3([(on[0] - ot[0]) * u[0], (on[1] - ot[1]) * u[1], S::cst(0.0)]);
                v.add(&w.cross(&p.sub(&origin)))
            }
        }
    }

    /// Signed distance of regrasping finger `i` at joints `q` (4) and object pose `o`, with its
    /// derivatives and the step columns they belong to (joints from `qcol`, object from `ocol`).
    pub(super) fn regrasp_sdf(
        &self,
        i: usize,
        q: &[f64],
        o: &[f64; 3],
        qcol: usize,
        ocol: usize,
    ) -> (Dual<7>, [usize; 7]) {
        let v: [Dual<7>; 7] = seed(&[q[0], q[1], q[2], q[3], o[0], o[1], o[2]]);
        let c = self.contact(i, &[v[0], v[1], v[2], v[3]], &[v[4], v[5], v[6]]);
        let map = std::array::from_fn(|k| if k < 4 { qcol + k } else { ocol + k - 4 });
        (c.sdf, map)
    }

    /// Regrasp target cost of finger `i` at `(q, o)`: `‖p^obj − p̄‖²` with the object frame
    /// yaw zeroed (screwdriver) or in the world (card).
    pub(super) fn target_error<S: Scalar>(&self, i: usize, q: &[S; 4], o: &[S; 3]) -> S {
        let c = self.chains[i].tip(q);
        let p = match self.task {
            SceneKind::Screwdriver => {
                let r = M3::rot_x(o[0] * self.units[0]).mul(&M3::rot_y(o[1] * self.units[1]));
                r.tmul_v(&c.sub(&V3::cst(scenes::screwdriver::PIVOT)))
            }
            SceneKind::Card => c,
        };
        let d = p.sub(&V3::cst(self.targets[i]));
        d.dot(&d)
    }

    /// Regrasp target distance (m) of finger `i` at `(q, o)`.
    pub fn target_distance(&self, i: usize, q: &[f64; 4], o: &[f64; 3]) -> f64 {
        self.target_error(i, q, &self.obj_units(o)).sqrt()
    }
}

/// Scalars that can take a 7-wide dual computed on `(q, o)` at column offsets
/// `(oq, oo)` of their own seeding.
pub(super) trait Lift: Scalar {
    fn lift(x: Dual<7>, oq: usize, oo: usize) -> Self;
}

impl<const N: usize> Lift for Dual<N> {
    fn lift(x: Dual<7>, oq: usize, oo: usize) -> Self {
        let mut d = [0.0; N];
        d[oq..oq + 4].copy_from_slice(&x.d[..4]);
        d[oo..oo + 3].copy_from_slice(&x.d[4..]);
        Dual { v: x.v, d }
    }
}

/// Dual numbers seeded with `vals`, one derivative direction each.
pub(super) fn seed<const N: usize>(vals: &[f64]) -> [Dual<N>; N] {
    std::array::from_fn(|i| Dual::var(vals[i], i))
}
