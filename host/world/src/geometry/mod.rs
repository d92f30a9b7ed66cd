//! Geometry of the scenes with parry3d: signed distance, closest points and normals between
//! fingertip spheres and the objects (screwdriver shaft, handle and cap; card; table).
//!
//! A [`Body`] is a set of convex [`Part`]s rigidly attached to one frame. A sphere is tested
//! against a part by projecting its centre onto the part's boundary with parry's exact point
//! projection (analytic for cylinders and boxes), which gives the signed distance of the
//! centre, the closest point and the outward normal; subtracting the radius gives the sphere's
//! signed distance φ (negative when penetrating).

mod convert;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rapier3d::parry::query::PointQuery;
use rapier3d::parry::shape::{Cuboid, Cylinder};

use crate::scenes::{card, screwdriver};

/// The convex shape of a part, in the part's own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PartShape {
    /// Solid cylinder with its axis along the body's local +z, spanning `z0..z1`.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Bottom along the axis (body frame).
        z0: f64,
        /// Top along the axis (body frame).
        z1: f64,
    },
    /// Solid box centred at `center` (body frame), axis-aligned in the body frame.
    Box {
        /// Centre in the body frame.
        center: [f64; 3],
        /// Half extents.
        half_extents: [f64; 3],
    },
}

/// One named convex part of a body.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// Name used in contact reports (`shaft`, `handle`, `cap`, `card`, `table`).
    pub name: &'static str,
    /// Its shape.
    pub shape: PartShape,
}

/// A rigid set of parts.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name of the body (`screwdriver`, `card`, `table`).
    pub name: &'static str,
    /// Its parts.
    pub parts: Vec<Part>,
}

/// Result of a sphere–part query, all in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereContact {
    /// Name of the part touched.
    pub part: &'static str,
    /// Signed distance between the sphere surface and the part (m), negative if penetrating.
    pub phi: f64,
    /// Unit normal pointing out of the part, toward the sphere centre.
    pub normal: Vector3<f64>,
    /// Closest point on the part's surface.
    pub point_on_body: Point3<f64>,
    /// Closest point on the sphere's surface (`centre − radius·normal`).
    pub point_on_sphere: Point3<f64>,
}

impl Body {
    /// The screwdriver (object frame at the pivot, +z along the shaft).
    pub fn screwdriver() -> Body {
        use screwdriver::*;
        Body {
            name: "screwdriver",
            parts: vec![
                Part {
                    name: "shaft",
                    shape: PartShape::Cylinder {
                        radius: SHAFT_RADIUS,
                        z0: 0.0,
                        z1: SHAFT_LENGTH,
                    },
                },
                Part {
                    name: "handle",
                    shape: PartShape::Cylinder {
                        radius: HANDLE_RADIUS,
                        z0: HANDLE_Z0,
                        z1: HANDLE_Z1,
                    },
                },
                Part {
                    name: "cap",
                    shape: PartShape::Cylinder {
                        radius: CAP_RADIUS,
                        z0: HANDLE_Z1,
                        z1: CAP_Z1,
                    },
                },
            ],
        }
    }

    /// The card (frame at its centre).
    pub fn card() -> Body {
        Body {
            name: "card",
            parts: vec![Part {
                name: "card",
                shape: PartShape::Box {
                    center: [0.0; 3],
                    half_extents: card::HALF_EXTENTS,
                },
            }],
        }
    }

    /// The card scene's table (frame = world).
    pub fn table() -> Body {
        Body {
            name: "table",
            parts: vec![Part {
                name: "table",
                shape: PartShape::Box {
                    center: card::TABLE_CENTER,
                    half_extents: card::TABLE_HALF_EXTENTS,
                },
            }],
        }
    }

    /// The part with the smallest signed distance to the sphere, if it is at most `max_phi`.
    pub fn sphere_contact(
        &self,
        pose: &Isometry3<f64>,
        center: &Point3<f64>,
        radius: f64,
        max_phi: f64,
    ) -> Option<SphereContact> {
        self.parts
            .iter()
            .map(|part| part.sphere_contact(pose, center, radius))
            .filter(|c| c.phi <= max_phi)
            .min_by(|a, b| a.phi.total_cmp(&b.phi))
    }

    /// Signed distance from the sphere to the body (minimum over parts).
    pub fn sphere_distance(&self, pose: &Isometry3<f64>, center: &Point3<f64>, radius: f64) -> f64 {
        self.parts
            .iter()
            .map(|part| part.sphere_contact(pose, center, radius).phi)
            .fold(f64::INFINITY, f64::min)
    }
}

impl Part {
    /// Pose of the parry shape's own frame in the body frame (parry cylinders are along y).
    fn shape_frame(&self) -> Isometry3<f64> {
        match self.shape {
            PartShape::Cylinder { z0, z1, .. } => Isometry3::from_parts(
                Translation3::new(0.0, 0.0, 0.5 * (z0 + z1)),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
            ),
            PartShape::Box { center, .. } => {
                Isometry3::translation(center[0], center[1], center[2])
            }
        }
    }

    /// Signed distance, closest points and normal between a sphere (world centre) and this part
    /// of a body at `body_pose`.
    pub fn sphere_contact(
        &self,
        body_pose: &Isometry3<f64>,
        center: &Point3<f64>,
        radius: f64,
    ) -> SphereContact {
        let frame = body_pose * self.shape_frame();
        let local = frame.inverse_transform_point(center);
        let pt = convert::point_to_glam(&local);
        let proj = match self.shape {
            PartShape::Cylinder { radius: r, z0, z1 } => {
                Cylinder::new((0.5 * (z1 - z0)) as f32, r as f32).project_local_point(pt, false)
            }
            PartShape::Box { half_extents, .. } => {
                Cuboid::new(convert::vector_to_glam(&Vector3::from(half_extents)))
                    .project_local_point(pt, false)
            }
        };
        let on_surface = convert::glam_to_point(proj.point);
        let diff = local - on_surface;
        let dist = diff.norm();
        let local_normal = if dist > 1e-9 {
            if proj.is_inside {
                -diff / dist
            } else {
                diff / dist
            }
        } else {
            // Centre exactly on the surface: fall back to the direction from the part's centre.
            let from_center = local.coords;
            if from_center.norm() > 1e-12 {
                from_center.normalize()
            } else {
                Vector3::y()
            }
        };
        let signed = if proj.is_inside { -dist } else { dist };
        let normal = frame.rotation * local_normal;
        let point_on_body = frame * on_surface;
        SphereContact {
            part: self.name,
            phi: signed - radius,
            normal,
            point_on_body,
            point_on_sphere: center - normal * radius,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::HandModel;
    use crate::scenes::SceneKind;

    #[test]
    fn sphere_against_handle_side_and_cap_top() {
        let body = Body::screwdriver();
        let pose = Isometry3::translation(0.0, 0.0, 1.205);
        // Beside the handle at height 0.15, 0.05 from the axis: gap 0.05 − 0.02 − 0.015.
        let c = body
            .sphere_contact(&pose, &Point3::new(0.05, 0.0, 1.355), 0.015, 0.1)
            .unwrap();
        assert_eq!(c.part, "handle");
        assert!((c.phi - 0.015).abs() < 1e-6, "{c:?}");
        assert!((c.normal - Vector3::x()).norm() < 1e-6);
        assert!((c.point_on_body - Point3::new(0.02, 0.0, 1.355)).norm() < 1e-6);
        // Above the cap, penetrating by 2 mm.
        let c = body
            .sphere_contact(&pose, &Point3::new(0.0, 0.005, 1.419), 0.015, 0.1)
            .unwrap();
        assert_eq!(c.part, "cap");
        assert!((c.phi + 0.002).abs() < 1e-6, "{c:?}");
        assert!((c.normal - Vector3::z()).norm() < 1e-6);
        // Inside the handle: normal still points out toward the nearest face.
        let c = body.parts[1].sphere_contact(&pose, &Point3::new(0.015, 0.0, 1.355), 0.015);
        assert!(
            (c.phi + 0.02).abs() < 1e-6 && (c.normal - Vector3::x()).norm() < 1e-6,
            "{c:?}"
        );
    }

    #[test]
    fn tilted_body_rotates_normals() {
        let body = Body::card();
        let pose = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.13),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.1),
        );
        let above = pose * Point3::new(0.01, 0.02, 0.005 + 0.015 + 0.003);
        let c = body.sphere_contact(&pose, &above, 0.015, 0.1).unwrap();
        assert!((c.phi - 0.003).abs() < 1e-6);
        assert!((c.normal - pose.rotation * Vector3::z()).norm() < 1e-6);
    }

    /// Spec §2.2 check: at the default grasp the index tip sits on the cap and middle/thumb are
    /// within a few millimetres of the handle; the card tips are 0–2 mm into the card.
    #[test]
    fn default_grasps_are_near_contact() {
        let hand = HandModel::allegro_v4();
        let s = SceneKind::Screwdriver;
        let tips = hand.tip_centers(&s.hand_base(), &s.default_joints());
        let body = Body::screwdriver();
        let pose = Isometry3::translation(0.0, 0.0, 1.205);
        let d: Vec<f64> = tips
            .iter()
            .map(|t| body.sphere_distance(&pose, t, 0.015))
            .collect();
        assert!(
            d[0].abs() < 1.5e-3 && d[1].abs() < 6e-3 && d[3].abs() < 2e-3,
            "{d:?}"
        );
        let c = SceneKind::Card;
        let tips = hand.tip_centers(&c.hand_base(), &c.default_joints());
        let pose = Isometry3::translation(0.0, 0.0, 0.13);
        for t in &tips[..2] {
            let phi = Body::card().sphere_distance(&pose, t, 0.015);
            assert!((-2.5e-3..=0.5e-3).contains(&phi), "{phi}");
        }
    }
}
