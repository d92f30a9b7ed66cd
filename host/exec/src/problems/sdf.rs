//! Analytic signed distances from a fingertip sphere to the task objects, generic over
//! [`Scalar`] so their derivatives come out of the dual numbers exactly.
//!
//! Each function takes the sphere centre in the object frame and returns the distance of the
//! *centre* to the object surface and the outward unit normal (both in the object frame);
//! subtract the sphere radius for the sphere's signed distance.

use super::dual::{Scalar, V3};
use dips_world::scenes::{card, screwdriver};

/// Distance of point `p` (object frame) to the surface and the outward normal.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceDistance<S> {
    /// Signed distance (negative inside).
    pub dist: S,
    /// Outward unit normal at the closest point.
    pub normal: V3<S>,
}

/// A solid cylinder along z with radius `r` spanning `z ∈ [z0, z1]`.
pub fn cylinder<S: Scalar>(p: &V3<S>, r: f64, z0: f64, z1: f64) -> SurfaceDistance<S> {
    let zc = 0.5 * (z0 + z1);
    let hh = 0.5 * (z1 - z0);
    let dzs = p.z() - zc;
    let up = dzs.val() >= 0.0;
    let dz = dzs.abs() - hh;
    let axial = V3::cst([0.0, 0.0, if up { 1.0 } else { -1.0 }]);
    let rho2 = p.x() * p.x() + p.y() * p.y();
    let radial_ok = rho2.val() > 1e-18;
    let rho = if radial_ok { rho2.sqrt() } else { S::cst(0.0) };
    let dr = rho - r;
    let radial = || {
        if radial_ok {
            V3([p.x() / rho, p.y() / rho, S::cst(0.0)])
        } else {
            V3::cst([1.0, 0.0, 0.0])
        }
    };
    let (drv, dzv) = (dr.val(), dz.val());
    if drv <= 0.0 && dzv <= 0.0 {
        if drv > dzv {
            SurfaceDistance {
                dist: dr,
                normal: radial(),
            }
        } else {
            SurfaceDistance {
                dist: dz,
                normal: axial,
            }
        }
    } else if dzv <= 0.0 {
        SurfaceDistance {
            dist: dr,
            normal: radial(),
        }
    } else if drv <= 0.0 {
        SurfaceDistance {
            dist: dz,
            normal: axial,
        }
    } else {
        let d = (dr * dr + dz * dz).sqrt();
        let n = radial().scale(dr / d).add(&axial.scale(dz / d));
        SurfaceDistance { dist: d, normal: n }
    }
}

/// The screwdriver: handle and cap as one cylinder (r 0.02, z 0.1–0.201) united with the
/// shaft (r 0.005, z 0–0.1); object frame at the pivot.
pub fn screwdriver<S: Scalar>(p: &V3<S>) -> SurfaceDistance<S> {
    let body = cylinder(
        p,
        screwdriver::HANDLE_RADIUS,
        screwdriver::HANDLE_Z0,
        screwdriver::CAP_Z1,
    );
    let shaft = cylinder(p, screwdriver::SHAFT_RADIUS, 0.0, screwdriver::HANDLE_Z0);
    if shaft.dist.val() < body.dist.val() {
        shaft
    } else {
        body
    }
}

/// An axis-aligned box with half extents `h` centred at the origin.
pub fn boxed<S: Scalar>(p: &V3<S>, h: &[f64; 3]) -> SurfaceDistance<S> {
    let q: [S; 3] = std::array::from_fn(|i| p.0[i].abs() - h[i]);
    let sign: [f64; 3] = std::array::from_fn(|i| if p.0[i].val() >= 0.0 { 1.0 } else { -1.0 });
    let outside = q.iter().any(|v| v.val() > 0.0);
    if outside {
        let pos: [S; 3] = std::array::from_fn(|i| {
            if q[i].val() > 0.0 {
                q[i] * sign[i]
            } else {
                S::cst(0.0)
            }
        });
        let v = V3(pos);
        let d = v.norm();
        SurfaceDistance {
            dist: d,
            normal: v.scale(S::cst(1.0) / d),
        }
    } else {
        let mut k = 0;
        for i in 1..3 {
            if q[i].val() > q[k].val() {
                k = i;
            }
        }
        let mut n = [0.0; 3];
        n[k] = sign[k];
        SurfaceDistance {
            dist: q[k],
            normal: V3::cst(n),
        }
    }
}

/// The card, in its own frame (centre at the origin, axis-aligned).
pub fn card<S: Scalar>(p: &V3<S>) -> SurfaceDistance<S> {
    boxed(p, &card::HALF_EXTENTS)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fd_check(f: impl Fn(&V3<f64>) -> SurfaceDistance<f64>, p: [f64; 3]) {
        let d0 = f(&V3(p)).dist;
        let n0 = f(&V3(p)).normal.val();
        let eps = 1e-7;
        for i in 0..3 {
            let mut pp = p;
            pp[i] += eps;
            let g = (f(&V3(pp)).dist - d0) / eps;
            assert!(
                (g - n0[i]).abs() < 1e-5,
                "axis {i}: fd {g} vs normal {}",
                n0[i]
            );
        }
    }

    #[test]
    fn normals_are_distance_gradients() {
        let sd = |p: &V3<f64>| screwdriver(p);
        fd_check(sd, [0.03, 0.01, 0.15]); // side of the handle
        fd_check(sd, [0.004, -0.003, 0.22]); // above the cap
        fd_check(sd, [0.03, 0.02, 0.23]); // past the rim
        fd_check(sd, [0.01, 0.0, 0.05]); // beside the shaft
        let cd = |p: &V3<f64>| card(p);
        fd_check(cd, [0.01, -0.02, 0.02]);
        fd_check(cd, [0.09, 0.11, 0.02]);
        fd_check(cd, [0.01, 0.02, 0.003]); // inside, near the top
    }

    #[test]
    fn distances_at_known_points() {
        let d = screwdriver(&V3([0.0, 0.0, 0.216f64]));
        assert!((d.dist - 0.015).abs() < 1e-12);
        let d = screwdriver(&V3([0.035, 0.0, 0.15f64]));
        assert!((d.dist - 0.015).abs() < 1e-12);
        let d = card(&V3([0.0, 0.0, 0.02f64]));
        assert!((d.dist - 0.015).abs() < 1e-12);
    }
}
