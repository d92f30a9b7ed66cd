//! The one boundary between our nalgebra `f64` types and parry3d's glam `f32` types.
//!
//! parry3d 0.31 exposes glam (`Vec3`, `Pose3`) in single precision. The world keeps every pose
//! in `f64`; queries are run in the shape's *local* frame (small coordinates, so `f32` costs
//! about 1e-8 m), and only vectors cross this module.

use nalgebra::{Point3, Vector3};
use rapier3d::parry::math::Vector as GVec3;

/// nalgebra point (f64) to a glam vector (f32).
pub(crate) fn point_to_glam(p: &Point3<f64>) -> GVec3 {
    GVec3::new(p.x as f32, p.y as f32, p.z as f32)
}

/// nalgebra vector (f64) to a glam vector (f32).
pub(crate) fn vector_to_glam(v: &Vector3<f64>) -> GVec3 {
    GVec3::new(v.x as f32, v.y as f32, v.z as f32)
}

/// glam vector (f32) to a nalgebra point (f64).
pub(crate) fn glam_to_point(v: GVec3) -> Point3<f64> {
    Point3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_f32_exact() {
        let p = Point3::new(0.1, -0.25, 0.0135);
        let back = glam_to_point(point_to_glam(&p));
        assert!((back - p).norm() < 1e-8);
        let v = vector_to_glam(&Vector3::new(1.0, 2.0, 3.0));
        assert_eq!((v.x, v.y, v.z), (1.0, 2.0, 3.0));
    }
}
